"""Column builders of the arm recorder: line strips, witness segments, goals, command correction.

Each turns a block of step values into Rerun columns in one go (Arrow arrays built here, as
Rerun's own conversion loops over strips in Python).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.components import LineStrip3DBatch

__all__ = ["strip_array", "witness_columns", "closest_witness", "goal_columns", "norm_columns"]


def strip_array(points: np.ndarray, lengths: np.ndarray) -> Any:
    """Arrow array of line strips (float32 points) from the points of every strip, concatenated."""
    dtype = LineStrip3DBatch._ARROW_DATATYPE
    inner = pa.FixedSizeListArray.from_arrays(pa.array(np.asarray(points, dtype=np.float32).reshape(-1)),
                                              type=dtype.value_type)
    offsets = np.concatenate(([0], np.cumsum(lengths))).astype(np.int32)
    return pa.ListArray.from_arrays(pa.array(offsets), inner, type=dtype)


def witness_columns(segs: np.ndarray, lengths: np.ndarray) -> Any:
    """Line-strip columns of witness segments: row ``i`` holds ``lengths[i]`` consecutive segments.

    ``segs``: (on geom 1, on geom 2) points [m], shape (s, 2, 3), rows one after another; segments
    with NaN points are dropped. The Arrow array is built here in one go (Rerun's own conversion
    loops over strips in Python).
    """
    segs = np.asarray(segs, dtype=np.float64).reshape(-1, 2, 3)
    lengths = np.asarray(lengths, dtype=np.int64)
    ok = np.all(np.isfinite(segs), axis=(1, 2))
    if not ok.all():
        row_of = np.repeat(np.arange(len(lengths)), lengths)
        lengths = np.bincount(row_of[ok], minlength=len(lengths))
        segs = segs[ok]
    strips = strip_array(segs.reshape(-1, 3), np.full(len(segs), 2))
    return rr.LineStrips3D.columns(strips=strips).partition(lengths.tolist())


def closest_witness(block: Any, n: int, closest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The witness segments of each row's pairs among ``closest[i]``, for :func:`witness_columns`.

    ``block`` holds each row's pairs within the cut-off and their witness points (``pairs``,
    ``witness``, row ``i``'s from ``pair_start[i]`` to ``pair_start[i + 1]``:
    :class:`~isf_robot.arm.step_columns.StepColumns`); ``closest`` holds each row's pairs to draw,
    shape (n, m) (the smallest ``h`` first, as the step record's ``closest``).

    Returns:
        ``(segments, lengths)``: shape (s, 2, 3) and (n,), row after row.

    """
    nc = block.n_collision
    if closest.size == 0 or nc == 0 or n == 0:
        return np.zeros((0, 2, 3)), np.zeros(n, dtype=np.int64)
    start = block.pair_start[: n + 1]
    counts = np.diff(start)
    pair, segs = block.pairs[start[0]: start[-1]], block.witness[start[0]: start[-1]]
    row = np.repeat(np.arange(n), counts)
    member = np.zeros((n, nc), dtype=bool)
    member[np.arange(n)[:, None], closest] = True
    keep = member[row, pair]
    kept = np.flatnonzero(keep)  # (take: a boolean mask over the segments is 5x slower)
    return np.take(segs, kept, axis=0), np.bincount(row[kept], minlength=n)


def goal_columns(t: np.ndarray, a: dict[str, np.ndarray]) -> tuple[np.ndarray, Any] | None:
    """The goal pursued at each step with a finite goal (``None`` when there is none)."""
    ok = np.all(np.isfinite(a["goal"]), axis=1)
    if not ok.any():
        return None
    return t[ok], rr.Points3D.columns(positions=a["goal"][ok])


def norm_columns(t: np.ndarray, a: dict[str, np.ndarray]) -> tuple[np.ndarray, Any]:
    """``|u - u_nom|`` per step, the square root of the replay column ``intervention_rate``."""
    return t, rr.Scalars.columns(scalars=np.sqrt(a["intervention_rate"]))
