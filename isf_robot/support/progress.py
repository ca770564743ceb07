"""A long run's progress on a terminal: one line, rewritten in place, gone when the run ends.

``isf-robot run`` hands :class:`TerminalProgress` to the simulation (``ArmSimulation.progress``), whose loop
calls it every few hundred control steps with the simulated time; it writes at most every ``every``
seconds of wall time, and only after ``after`` seconds, so a short run prints nothing. It writes only to a
terminal (:meth:`TerminalProgress.for_stream` gives ``None`` for a pipe or a file: logs and ``--json``
output stay clean), and :meth:`~TerminalProgress.close` erases the line before the summary is printed.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import TextIO

__all__ = ["TerminalProgress", "AFTER_ENV"]

AFTER_ENV = "ISF_ROBOT_PROGRESS_AFTER"
"""Environment variable: seconds of wall time before a run's first progress line (default 1)."""


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
        self.after = float(after)
        self.start = clock()
        self.next = self.start + self.after
        self.shown = False
        self.broken = False

    @classmethod
    def for_stream(cls, stream: TextIO, label: str = "", **kwargs: float) -> TerminalProgress | None:
        """A reporter when ``stream`` is a terminal, else ``None`` (nothing to report to).

        ``after`` defaults to :data:`AFTER_ENV` when that is set to a number of seconds (else 1 s).
        """
        isatty = getattr(stream, "isatty", None)
        if isatty is None or not isatty():
            return None
        if "after" not in kwargs:
            try:
                kwargs["after"] = max(0.0, float(os.environ.get(AFTER_ENV, "1")))
            except ValueError:
                kwargs["after"] = 1.0
        return cls(stream, label, **kwargs)

    def __call__(self, t: float, total: float) -> None:
        """The run has simulated ``t`` of ``total`` seconds (``t = 0``: a run starts; its clock starts too)."""
        now = self.clock()
        if t == 0.0:
            self.start, self.next = now, now + self.after
        if now < self.next or self.broken:
            return
        self.next = now + self.every
        share = f" ({100.0 * t / total:.0f} %)" if total > 0 else ""
        head = f"{self.label}  " if self.label else ""
        self._write(f"\r\x1b[K{head}{t:.1f} / {total:.1f} s simulated{share}, {now - self.start:.0f} s")
        self.shown = not self.broken

    def close(self) -> None:
        """Erase the line (if one was written)."""
        if self.shown:
            self._write("\r\x1b[K")
            self.shown = False

    def _write(self, text: str) -> None:
        """Write and flush; a terminal that went away ends the reporting, not the run."""
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # (a closed terminal or stream: nothing more to show)
            self.broken = True
