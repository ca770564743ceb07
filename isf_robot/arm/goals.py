"""Goal bookkeeping of the nominal controllers (:mod:`isf_robot.arm.nominal`): reach, dwell, time out, advance."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from isf_robot.core.exceptions import ConfigError

__all__ = ["GoalSequence"]


class GoalSequence:
    """Goal bookkeeping shared by the nominal controllers.

    A goal is *reached* the first time the error falls below the tolerance (its time is kept in
    ``arrivals``); after its dwell
    time the sequence moves to the next goal (back to the first when ``loop``; the last goal
    is held otherwise). A goal not reached within ``timeout`` seconds is given up (counted in
    ``missed``) and the sequence moves on, so that an arm held back by a safety filter keeps
    working on its task instead of pushing against an obstacle for the rest of the episode.

    Args:
        n_goals: Number of goals, >= 1.
        dwell: Dwell time per goal [s], shape (n_goals,).
        tolerance: Error below which a goal counts as reached (controller units: [m] or [rad]).
        loop: Restart at the first goal after the last one.
        timeout: Time [s] after which an unreached goal is given up (``inf``: never).

    """

    def __init__(self, n_goals: int, dwell: Sequence[float] | np.ndarray, tolerance: float,
                 loop: bool = True, timeout: float = math.inf) -> None:
        if n_goals < 1:
            raise ConfigError("a goal sequence needs at least one goal")
        self.n_goals = int(n_goals)
        self.dwell = np.asarray(dwell, dtype=float).reshape(-1)
        if self.dwell.shape != (self.n_goals,) or np.any(self.dwell < 0):
            raise ConfigError(f"dwell must be {self.n_goals} non-negative times [s], got {dwell!r}")
        if not tolerance > 0:
            raise ConfigError(f"goal tolerance must be > 0, got {tolerance}")
        self.tolerance = float(tolerance)
        self.loop = bool(loop)
        if not timeout > 0:
            raise ConfigError(f"goal timeout must be > 0 [s], got {timeout}")
        self.timeout = float(timeout)
        self.reset()

    def reset(self) -> None:
        """Start again at the first goal with nothing reached."""
        self.index = 0
        self.reached = 0
        self.missed = 0
        self.arrivals: tuple[float, ...] = ()  # a tuple: snapshots (a dict copy) keep their own
        self._arrived: float | None = None
        self._started: float | None = None
        self._done = False

    def _advance(self) -> None:
        if self.index + 1 < self.n_goals:
            self.index += 1
        elif self.loop:
            self.index = 0
        else:
            self._done = True
        self._arrived = None
        self._started = None

    def steady(self, t_first: float, t_last: float) -> bool:
        """Whether no :meth:`update` at times in ``[t_first, t_last]`` (in order, any errors) can change :attr:`index`.

        Conservative: ``False`` whenever a change is possible. Before an arrival the index changes only by a
        timeout (``t - started >= timeout``) or after an arrival at some ``t_a >= t_first`` and its dwell
        (``t - t_a >= dwell``); after one, when ``t - arrived >= dwell``. A rounded difference grows with
        its first term and falls with its second, so checking ``t_last`` (and ``t_first`` for ``t_a``)
        covers every time in between. The predictive off trigger's rollout uses it to run its points with
        the goal fixed.
        """
        if self._done:
            return True
        dwell = self.dwell[self.index]
        if self._arrived is not None:
            return bool(t_last - self._arrived < dwell)
        started = t_first if self._started is None else self._started
        return bool(t_last - started < self.timeout and t_last - t_first < dwell)

    def update(self, t: float, error: float) -> None:
        """Advance the sequence given the current goal error at time ``t`` [s]."""
        if self._done:
            return
        if self._started is None:
            self._started = t
        if self._arrived is None:
            if error < self.tolerance:
                self._arrived = t
                self.reached += 1
                self.arrivals += (float(t),)
            elif t - self._started >= self.timeout:
                self.missed += 1
                self._advance()
            return
        if t - self._arrived >= self.dwell[self.index]:
            self._advance()
