"""Counting filter switches: one definition of a :class:`SwitchEvent` for every strategy.

The intermittent filter's mode is decided by its trigger (:class:`~isf_robot.core.triggers.OnOffTrigger`);
the standard filter's "mode" is whether a constraint is active. Both report their mode changes
through :class:`SwitchCounter`, so events carry the same numbering and period lengths.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SwitchEvent", "SwitchCounter"]


@dataclass(frozen=True)
class SwitchEvent:
    """A filter switch.

    Attributes:
        t: Time of the switch [s].
        kind: ``"on"`` or ``"off"``.
        xi_min: Smallest ``Xi_on`` over the barriers at the switch.
        index: 1-based count of switches of this kind so far.
        duration_s: Length of the period that just ended [s] (the off period before an
            "on", the on period before an "off"), or ``None`` for the first on after start.

    """

    t: float
    kind: str
    xi_min: float
    index: int
    duration_s: float | None = None


class SwitchCounter:
    """Turns a sequence of modes into :class:`SwitchEvent` objects.

    Args:
        on: The mode at the start.

    """

    __slots__ = ("on", "n_on", "n_off", "_t_switch")

    def __init__(self, on: bool = False) -> None:
        self.reset(on)

    def reset(self, on: bool = False) -> None:
        """Forget history; start in mode ``on``."""
        self.on = bool(on)
        self.n_on = 0
        self.n_off = 0
        self._t_switch: float | None = None

    def update(self, t: float, on: bool, xi_min: float) -> SwitchEvent | None:
        """Record the mode at time ``t`` [s]; return the event if it changed."""
        if on == self.on:
            return None
        self.on = on
        if on:
            self.n_on += 1
        else:
            self.n_off += 1
        dur = None if self._t_switch is None else t - self._t_switch
        self._t_switch = t
        return SwitchEvent(t, "on" if on else "off", float(xi_min), self.n_on if on else self.n_off, dur)
