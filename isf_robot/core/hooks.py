"""Observer hooks: the numerics never log; whoever watches subscribes.

Simulation loops (the arm's, the satellite's, the core demo's) call ``on_start`` once,
``on_step`` per control step with their step record, ``on_event`` per switch or jump event,
and ``on_finish`` with the summary. A run that stops early (an error, Ctrl-C) calls
``on_abort`` instead of ``on_finish``, so an observer writing a file can leave it marked as
partial. :class:`Observer` is a no-op base to subclass.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["Observer", "Observers"]


class Observer:
    """Base observer with no-op hooks."""

    def on_start(self, info: Mapping[str, Any]) -> None:
        """Called once before the first step with run metadata."""

    def on_step(self, record: Any) -> None:
        """Called after every control step with the loop's step record."""

    def on_event(self, event: Any) -> None:
        """Called for each switch / jump event."""

    def on_finish(self, summary: Mapping[str, Any]) -> None:
        """Called once at the end with the run summary."""

    def on_abort(self, reason: BaseException) -> None:
        """Called instead of :meth:`on_finish` when the run stops early (error or interrupt)."""


class Observers(Observer):
    """Fan-out to several observers, in order."""

    def __init__(self, observers: Iterable[Observer] = ()) -> None:
        self.items = [o for o in observers if o is not None]

    def __bool__(self) -> bool:
        return bool(self.items)

    def on_start(self, info: Mapping[str, Any]) -> None:
        for o in self.items:
            o.on_start(info)

    def on_step(self, record: Any) -> None:
        for o in self.items:
            o.on_step(record)

    def on_event(self, event: Any) -> None:
        for o in self.items:
            o.on_event(event)

    def on_finish(self, summary: Mapping[str, Any]) -> None:
        for o in self.items:
            o.on_finish(summary)

    def on_abort(self, reason: BaseException) -> None:
        """Tell every observer, even when one of them fails (the run's own error is re-raised)."""
        for o in self.items:
            try:
                o.on_abort(reason)
            except Exception:  # noqa: BLE001, S112 - the run's error matters more than the observer's
                continue
