"""Buffered column logging: per-step values go into preallocated numpy arrays, sent in chunks.

One ``rr.log`` call costs tens of microseconds, more than a physics step; one
``send_columns`` call for a few thousand rows costs about as much as a few ``rr.log`` calls.
So each logged quantity is a :class:`Channel` holding a fixed number of rows; when a channel
is full (and when the run ends) its rows go to the recording stream in one ``send_columns``
call on the simulation-time timeline, and the arrays are reused. Memory is therefore bounded
by ``capacity`` rows per channel, whatever the length of the run.

Rows of a channel are indexed by simulation time [s] (a Rerun *duration* timeline, stored in
nanoseconds). Values are kept as given (float64 stays float64), so what is read back from a
saved recording equals what was pushed.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import rerun as rr

from .errors import RecordError

__all__ = ["TIMELINE", "Channel", "RaggedChannel", "ColumnBuffer"]

TIMELINE = "sim_time"
"""Name of the simulation-time timeline [s] every recorder logs on."""

Builder = Callable[..., Any]
"""``build(**arrays) -> ComponentColumnList``: turns the buffered arrays into Rerun columns."""

Derived = Callable[[np.ndarray, dict[str, np.ndarray]], "tuple[np.ndarray, Any] | None"]
"""``fn(t, arrays) -> (t_selected, columns) | None``: another entity built from a channel's rows."""


class Channel:
    """A fixed-shape per-row quantity of one entity, buffered for ``send_columns``.

    Args:
        buffer: The owning buffer (gives the stream, timeline and capacity).
        path: Entity path.
        fields: Field name -> ``(shape, dtype)`` of one row's value of that field.
        build: ``build(**arrays)`` with each array of shape ``(n, *shape)``, returning the
            component columns (e.g. ``rr.Scalars.columns``); ``None`` sends nothing at ``path``.
        derived: Further entities sent from the same rows at each flush, as
            ``(path, fn)`` with ``fn(t, arrays) -> (t_selected, columns)`` or ``None`` to
            skip; one push then feeds several entities.

    """

    __slots__ = ("_buffer", "path", "_names", "_arrays", "_t", "_n", "_build", "_derived", "rows_sent")

    def __init__(
        self,
        buffer: ColumnBuffer,
        path: str,
        fields: Mapping[str, tuple[tuple[int, ...], Any]],
        build: Builder | None,
        derived: Sequence[tuple[str, Derived]] = (),
    ) -> None:
        if not fields:
            raise RecordError(f"channel {path!r} needs at least one field")
        cap = buffer.capacity
        self._buffer = buffer
        self.path = path
        self._names = tuple(fields)
        self._arrays = tuple(np.zeros((cap, *shape), dtype=dtype) for shape, dtype in fields.values())
        self._t = np.zeros(cap, dtype=np.float64)
        self._n = 0
        self._build = build
        self._derived = tuple(derived)
        self.rows_sent = 0

    def __len__(self) -> int:
        return self._n

    def push(self, t: float, *values: Any) -> None:
        """Append one row at simulation time ``t`` [s]: one value per field, in field order."""
        n = self._n
        self._t[n] = t
        for arr, v in zip(self._arrays, values):
            arr[n] = v
        self._n = n + 1
        if self._n == self._t.shape[0]:
            self.flush()

    def flush(self) -> None:
        """Send the buffered rows (if any) in one ``send_columns`` call and empty the buffer."""
        n = self._n
        if n == 0:
            return
        # copies: the stream may encode the columns after this call returns (a background thread), while the
        # buffers fill again; views sent here were overwritten under load (rows of later blocks read back)
        arrays = {k: a[:n].copy() for k, a in zip(self._names, self._arrays)}
        stream, timeline, t = self._buffer.stream, self._buffer.timeline, self._t[:n].copy()
        if self._build is not None:
            stream.send_columns(self.path, indexes=[rr.TimeColumn(timeline, duration=t)],
                                columns=self._build(**arrays))
        for path, fn in self._derived:
            out = fn(t, arrays)
            if out is not None and len(out[0]):
                stream.send_columns(path, indexes=[rr.TimeColumn(timeline, duration=out[0])], columns=out[1])
        self.rows_sent += n
        self._n = 0


class RaggedChannel:
    """A per-row quantity with a varying number of instances (e.g. witness segments).

    Rows are kept as small arrays in a list until the channel holds ``capacity`` rows.

    Args:
        buffer: The owning buffer.
        path: Entity path.
        build: ``build(rows) -> ComponentColumnList`` given the list of buffered row values.

    """

    __slots__ = ("_buffer", "path", "_rows", "_t", "_build", "rows_sent")

    def __init__(self, buffer: ColumnBuffer, path: str, build: Callable[[list[Any]], Any]) -> None:
        self._buffer = buffer
        self.path = path
        self._rows: list[Any] = []
        self._t: list[float] = []
        self._build = build
        self.rows_sent = 0

    def __len__(self) -> int:
        return len(self._t)

    def push(self, t: float, value: Any) -> None:
        """Append one row (any number of instances) at time ``t`` [s]."""
        self._t.append(t)
        self._rows.append(value)
        if len(self._t) >= self._buffer.capacity:
            self.flush()

    def flush(self) -> None:
        """Send the buffered rows (if any) and empty the buffer."""
        if not self._t:
            return
        cols = self._build(self._rows)
        self._buffer.stream.send_columns(
            self.path,
            indexes=[rr.TimeColumn(self._buffer.timeline, duration=np.asarray(self._t, dtype=np.float64))],
            columns=cols,
        )
        self.rows_sent += len(self._t)
        self._rows = []
        self._t = []


class ColumnBuffer:
    """The set of channels of one recording stream.

    Args:
        stream: The explicit recording stream to send to (no global state).
        capacity: Rows buffered per channel before it is sent, >= 1.
        timeline: Timeline name (simulation seconds).

    """

    def __init__(self, stream: rr.RecordingStream, capacity: int = 2048, timeline: str = TIMELINE) -> None:
        if int(capacity) < 1:
            raise RecordError(f"capacity must be >= 1 rows, got {capacity}")
        self.stream = stream
        self.capacity = int(capacity)
        self.timeline = timeline
        self._channels: dict[str, Any] = {}

    def channel(self, path: str, fields: Mapping[str, tuple[tuple[int, ...], Any]], build: Builder | None,
                derived: Sequence[tuple[str, Derived]] = ()) -> Channel:
        """Create (or return the existing) fixed-shape channel at ``path`` (see :class:`Channel`)."""
        ch = self._channels.get(path)
        if ch is None:
            ch = Channel(self, path, fields, build, derived)
            self._channels[path] = ch
        if not isinstance(ch, Channel):
            raise RecordError(f"entity {path!r} already has a ragged channel")
        return ch

    def scalars(self, path: str, width: int = 1) -> Channel:
        """A ``Scalars`` channel with ``width`` float64 series per row."""
        shape: tuple[int, ...] = () if width == 1 else (int(width),)
        return self.channel(path, {"scalars": (shape, np.float64)},
                            lambda scalars: rr.Scalars.columns(scalars=scalars))

    def ragged(self, path: str, build: Callable[[list[Any]], Any]) -> RaggedChannel:
        """Create (or return the existing) ragged channel at ``path``."""
        ch = self._channels.get(path)
        if ch is None:
            ch = RaggedChannel(self, path, build)
            self._channels[path] = ch
        if not isinstance(ch, RaggedChannel):
            raise RecordError(f"entity {path!r} already has a fixed-shape channel")
        return ch

    def add(self, path: str, channel: Any) -> Any:
        """Register a custom channel (any object with ``flush()`` and ``__len__``) under ``path``."""
        if path in self._channels:
            raise RecordError(f"entity {path!r} already has a channel")
        self._channels[path] = channel
        return channel

    def flush(self) -> None:
        """Send every channel's buffered rows."""
        for ch in self._channels.values():
            ch.flush()

    @property
    def buffered_rows(self) -> int:
        """Rows currently held in memory over all channels."""
        return sum(len(ch) for ch in self._channels.values())
