"""Observer hooks: the numerics never log; whoever watches subscribes.

Simulation loops (the arm's, the satellite's, the core demo's) call ``on_start`` once,
``on_step`` per control step with their step record, ``on_event`` per switch or jump event,
and ``on_finish`` with the summary. A loop that keeps its steps in columns (the arm's) hands an
observer that overrides :meth:`Observer.on_steps` whole blocks of steps instead of per-step
records (:func:`takes_blocks`); every other observer still gets ``on_step`` at every step. A run
that stops early (an error, Ctrl-C) calls ``on_abort`` instead of ``on_finish`` (after handing
over the steps done), so an observer writing a file can leave it marked as partial.
:class:`Observer` is a no-op base to subclass.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["Observer", "Observers", "takes_blocks"]


class Observer:
    """Base observer with no-op hooks."""

    def on_start(self, info: Mapping[str, Any]) -> None:
        """Called once before the first step with run metadata."""

    def on_step(self, record: Any) -> None:
        """Called after every control step with the loop's step record."""

    def on_steps(self, block: Any) -> None:
        """Called with a block of consecutive steps in columns, by loops that keep columns.

        ``len(block)`` rows; ``block.record(i)`` is row ``i`` as the loop's step record. The block's
        arrays are reused after the call: keep copies, not views. Default: :meth:`on_step` per row.
        """
        for i in range(len(block)):
            self.on_step(block.record(i))

    def on_event(self, event: Any) -> None:
        """Called for each switch / jump event."""

    def on_finish(self, summary: Mapping[str, Any]) -> None:
        """Called once at the end with the run summary."""

    def on_abort(self, reason: BaseException) -> None:
        """Called instead of :meth:`on_finish` when the run stops early (error or interrupt)."""


def takes_blocks(observer: Observer) -> bool:
    """Whether ``observer`` overrides :meth:`Observer.on_steps` (it then gets blocks, not per-step records)."""
    return getattr(type(observer), "on_steps", Observer.on_steps) is not Observer.on_steps


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

    def on_steps(self, block: Any) -> None:
        for o in self.items:
            o.on_steps(block)

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
