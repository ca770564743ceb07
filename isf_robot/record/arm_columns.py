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
    inner = pa.FixedSizeListArray.from_arrays(pa.array(points.astype(np.float32).reshape(-1)),
                                              type=dtype.value_type)
    offsets = np.concatenate(([0], np.cumsum(lengths))).astype(np.int32)
    return pa.ListArray.from_arrays(pa.array(offsets), inner, type=dtype)


def witness_columns(rows: list[np.ndarray]) -> Any:
    """Segments (on geom 1, on geom 2) of each row; segments with NaN points are dropped.

    The Arrow array is built here in one go (Rerun's own conversion loops over strips in Python).
    """
    segs = np.concatenate([np.asarray(w, dtype=np.float64).reshape(-1, 2, 3) for w in rows])
    ok = np.all(np.isfinite(segs), axis=(1, 2))
    lengths = np.fromiter((len(w) for w in rows), dtype=np.int64, count=len(rows))
    if not ok.all():
        row_of = np.repeat(np.arange(len(rows)), lengths)
        lengths = np.bincount(row_of[ok], minlength=len(rows))
        segs = segs[ok]
    strips = strip_array(segs.reshape(-1, 3), np.full(len(segs), 2))
    return rr.LineStrips3D.columns(strips=strips).partition(lengths.tolist())


def closest_witness(record: Any, m: int) -> np.ndarray:
    """Witness segments of the record's pairs that are among its ``m`` closest."""
    w = record.witness
    if not len(w) or m <= 0:
        return np.zeros((0, 2, 3))
    keep = set(record.closest[:m])
    mask = [n in keep for n in record.witness_names]
    return w[np.asarray(mask, dtype=bool)] if not all(mask) else w


def goal_columns(t: np.ndarray, a: dict[str, np.ndarray]) -> tuple[np.ndarray, Any] | None:
    """The goal pursued at each step with a finite goal (``None`` when there is none)."""
    ok = np.all(np.isfinite(a["goal"]), axis=1)
    if not ok.any():
        return None
    return t[ok], rr.Points3D.columns(positions=a["goal"][ok])


def norm_columns(t: np.ndarray, a: dict[str, np.ndarray]) -> tuple[np.ndarray, Any]:
    """``|u - u_nom|`` per step, the square root of the replay column ``intervention_rate``."""
    return t, rr.Scalars.columns(scalars=np.sqrt(a["intervention_rate"]))
