"""Reading one entity's time-indexed columns back from a ``.rrd`` file (for tests and tools).

Re-exported by :mod:`isf_robot.record.replay`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader

from .errors import RecordingReadError

__all__ = ["read_columns"]


def _check_file(p: Path) -> None:
    """Raise :class:`RecordingReadError` unless ``p`` is a readable file starting like an RRD."""
    if not p.exists():
        raise RecordingReadError(p, "no such file")
    if p.is_dir():
        raise RecordingReadError(p, "is a directory (pass the .rrd files in it)")
    try:
        with open(p, "rb") as fh:
            head = fh.read(4)
    except OSError as exc:
        raise RecordingReadError(p, f"cannot open it: {exc.strerror or exc}") from exc
    if len(head) < 4:
        raise RecordingReadError(p, "the file is empty or too short to be a Rerun recording")
    if not head.startswith(b"RRF"):
        raise RecordingReadError(p, f"not a Rerun .rrd file (starts with {head!r}, expected b'RRF2')")


def _damaged(p: Path, exc: Exception) -> RecordingReadError:
    msg = " ".join(str(exc).split())
    return RecordingReadError(p, f"truncated or corrupt Rerun file ({msg})")


def read_columns(path: str | Path, entity: str, names: Sequence[str] | None = None,
                 recording: int = 0) -> dict[str, np.ndarray]:
    """Read the time-indexed columns of one entity back, in time order.

    Single-instance columns come back as shape (N,), multi-instance ones (e.g. a ``Scalars``
    entity with one series per joint, or 3-D points) as shape (N, k) or (N, k, d) when every
    row has the same count, else as an object array of per-row arrays. ``sim_time`` [s] is
    added (from the timeline, nanosecond resolution). Rows that only clear the entity (a gap
    in a series) are left out unless a ``Clear:`` column is asked for, which returns them alone.

    Args:
        path: The ``.rrd`` file.
        entity: Entity path, e.g. ``"/plots/mode"``.
        names: Column names to return (default: every component column), e.g.
            ``"Scalars:scalars"`` or an ``AnyValues`` field name.
        recording: Index of the recording in the file.

    Raises:
        RecordingReadError: Unreadable file, or no such entity / column.

    """
    p = Path(path)
    _check_file(p)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            reader = RrdReader(p)
            entries = reader.recordings()
            if not 0 <= recording < len(entries):
                raise RecordingReadError(p, f"no recording #{recording} (the file holds {len(entries)})")
            batches = [c.to_record_batch() for c in reader.stream(store=entries[recording])
                       if c.entity_path == entity and not c.is_static]
    except RecordingReadError:
        raise
    except Exception as exc:
        raise _damaged(p, exc) from exc
    if not batches:
        raise RecordingReadError(p, f"no time-indexed entity {entity!r} in the recording")
    def data_columns(b: pa.RecordBatch) -> list[str]:
        return [f.name for f in b.schema if (f.metadata or {}).get(b"rerun:kind") == b"data"]

    # rows holding only a Clear (gaps in a series) are returned only when asked for by name
    clears = names is not None and any(str(n).startswith("Clear:") for n in names)
    batches = [b for b in batches if clears == all(n.startswith("Clear:") for n in data_columns(b))]
    if not batches:
        raise RecordingReadError(p, f"no time-indexed entity {entity!r} in the recording")
    available = data_columns(batches[0])
    wanted = list(names) if names is not None else available
    out: dict[str, list[Any]] = {n: [] for n in wanted}
    times: list[np.ndarray] = []
    for b in batches:
        times.append(b.column("sim_time").cast(pa.int64()).to_numpy(zero_copy_only=False))
        for n in wanted:
            if n not in b.schema.names:
                raise RecordingReadError(p, f"entity {entity!r} has no column {n!r} (has: {', '.join(available)})")
            out[n].extend(_row_values(b.column(n)))
    t_ns = np.concatenate(times)
    order = np.argsort(t_ns, kind="stable")
    result: dict[str, np.ndarray] = {"sim_time": t_ns[order] * 1e-9}
    for n, rows in out.items():
        rows = [rows[i] for i in order]
        lens = {len(r) for r in rows}
        try:
            if lens == {1}:
                result[n] = np.asarray([r[0] for r in rows])
                continue
            if len(lens) == 1:
                result[n] = np.asarray(rows)
                continue
        except ValueError:  # rows of one item each, items of different lengths (e.g. line strips)
            rows = [r[0] for r in rows]
        arr = np.empty(len(rows), dtype=object)
        arr[:] = [np.asarray(r) for r in rows]
        result[n] = arr
    return result


def _row_values(col: pa.ChunkedArray | pa.Array) -> list[Any]:
    arr = col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col
    return [v if v is not None else [] for v in arr.to_pylist()]
