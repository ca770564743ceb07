"""A long run's progress on a terminal: one line, rewritten in place, gone when the run ends.

``isf-robot run`` hands :class:`TerminalProgress` to the simulation (``ArmSimulation.progress``), whose loop
calls it every few hundred control steps with the simulated time; it writes at most every ``every``
seconds of wall time, and only after ``after`` seconds, so a short run prints nothing. It writes only to a
terminal (:meth:`TerminalProgress.for_stream` gives ``None`` for a pipe or a file: logs and ``--json``
output stay clean), and :meth:`~TerminalProgress.close` erases the line before the summary is printed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TextIO

__all__ = ["TerminalProgress"]


class TerminalProgress:
    """``progress(t, total)``: ``label  12.0 / 30.0 s simulated (40 %), 8 s`` on one rewritten line.

    Args:
        stream: Where to write (a terminal).
        label: What runs (the scene and the strategy).
        after: Wall time [s] before the first line.
        every: Least wall time [s] between lines.
        clock: The wall clock (tests pass a fake one).

    """

    def __init__(self, stream: TextIO, label: str = "", after: float = 1.0, every: float = 0.5,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        self.stream, self.label, self.every, self.clock = stream, label, float(every), clock
        self.start = clock()
        self.next = self.start + float(after)
        self.shown = False

    @classmethod
    def for_stream(cls, stream: TextIO, label: str = "", **kwargs: float) -> TerminalProgress | None:
        """A reporter when ``stream`` is a terminal, else ``None`` (nothing to report to)."""
        isatty = getattr(stream, "isatty", None)
        return cls(stream, label, **kwargs) if isatty is not None and isatty() else None

    def __call__(self, t: float, total: float) -> None:
        """The run has simulated ``t`` of ``total`` seconds."""
        now = self.clock()
        if now < self.next:
            return
        self.next = now + self.every
        share = f" ({100.0 * t / total:.0f} %)" if total > 0 else ""
        head = f"{self.label}  " if self.label else ""
        self.stream.write(f"\r\x1b[K{head}{t:.1f} / {total:.1f} s simulated{share}, {now - self.start:.0f} s")
        self.stream.flush()
        self.shown = True

    def close(self) -> None:
        """Erase the line (if one was written)."""
        if self.shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self.shown = False
