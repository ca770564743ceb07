"""Maneuvers by shooting: the promotion level whose maneuver keeps the nominal safe longest.

The arm analogue of the satellite's shooting controller and of the paper's ``tau_p``: while the
intermittent filter is on, it may push with one of a few promotion levels ``b_j = f_j b``
(:data:`LEVELS`: ``f_j = 1, 3, 10``; every level is a promotion above the robust condition, since
``b > 0``). For each level, :class:`ManeuverShooter` takes the filter's command ``u_j`` (the same QP,
level ``b_j``), asks a rollout what happens when ``u_j`` is held over its first step and the nominal
controller takes over from there (``rollout(t, x, first=u_j)``, on the same reduced model as the
predictive off trigger, with its own, longer horizon), and scores the level by the predicted
*re-trigger time* ``tau_j``: the time of the first predicted point with some ``Xi_on <= 0``
(``inf`` when every ``Xi_on > 0`` over the horizon). The level with the
largest ``tau_j`` is chosen; among equal ones the smallest (the least intervention), so the
filter pushes harder than ``b`` only where the prediction says it pays. A choice is made at each
on switch and then every ``every`` control steps while on, so the cost is bounded: ``len(LEVELS)``
QP solves and rollouts per choice. The level in use moves to the chosen one at a bounded rate (the
whole range of levels in ``ramp`` seconds: the filter's hand-over time), so a new choice does not
step the command: a step the arm's low-level controller could not track would break the tracking
bound ``d_bar`` that the robust condition rests on.

Safety does not rest on the choice: every level is a promotion above the robust condition, so
Theorem 1's argument for the safety-promoting filter holds whichever is chosen.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .class_k import ClassK
from .exceptions import ConfigError
from .intermittent import Prediction, predict

__all__ = ["LEVELS", "ManeuverShooter", "release_time"]

LEVELS: tuple[float, ...] = (1.0, 3.0, 10.0)
"""The candidate promotion levels as multiples of ``b``, in order of increasing intervention."""


def release_time(pred: Prediction) -> float:
    """Predicted time [s] until the nominal re-triggers (``inf``: not within the rollout's horizon)."""
    return math.inf if pred.ok else float(pred.first_fail_s)  # type: ignore[arg-type]


class ManeuverShooter:
    """Choice of the promotion level by shooting (see the module docstring).

    Args:
        rollout: The rollout callback, taking ``first=u``: the command over its first step
            (:class:`~isf_robot.arm.rollout.NominalRollout` does).
        every: Control steps between choices while on, >= 1.
        ramp: Time [s] in which the level in use may cross the whole range of levels, >= 0 (0: at once).
        levels: Candidate levels as multiples of ``b``, each > 0, increasing.

    """

    def __init__(self, rollout: Callable[..., Any], every: int = 5, ramp: float = 0.0,
                 levels: tuple[float, ...] = LEVELS) -> None:
        if not callable(rollout):
            raise ConfigError("shooting needs a rollout: rollout(t, x, first=u) -> [(s, lie, u_nom), ...]")
        if int(every) != every or every < 1:
            raise ConfigError(f"shooting needs every >= 1 control steps, got {every}")
        if not levels or any(not f > 0 for f in levels) or list(levels) != sorted(levels):
            raise ConfigError(f"shooting levels must be > 0 and increasing, got {levels}")
        if not (math.isfinite(ramp) and ramp >= 0):
            raise ConfigError(f"shooting ramp must be >= 0 [s], got {ramp}")
        self.rollout, self.every, self.levels = rollout, int(every), tuple(levels)
        self._rate = math.inf if ramp == 0 else (self.levels[-1] - self.levels[0]) / float(ramp)
        self.reset()

    def reset(self) -> None:
        """Forget the current choice and the counts."""
        self.factor = self.applied = self.levels[0]
        self._since = 0
        self._t: float | None = None
        self.choices = 0
        self.raised = 0  # choices of a level above the first
        self.last_tau: tuple[float, ...] = ()

    def idle(self) -> None:
        """The filter is off: the next :meth:`level` chooses afresh, from the first level."""
        self._since = 0
        self.factor = self.applied = self.levels[0]
        self._t = None

    def level(self, t: float, x: Any, b: float, solve: Callable[[float], np.ndarray], alpha: ClassK,
              d_bar: float) -> float:
        """The promotion level to use at ``t``; ``solve(level)`` is the filter's command with that level."""
        if self._since and self._since < self.every:
            self._since += 1
        else:
            self._choose(t, x, b, solve, alpha, d_bar)
        step = math.inf if self._t is None else self._rate * (t - self._t)
        self._t = t
        self.applied += max(-step, min(step, self.factor - self.applied))
        return self.applied * b

    def _choose(self, t: float, x: Any, b: float, solve: Callable[[float], np.ndarray], alpha: ClassK,
                d_bar: float) -> None:
        taus = []
        best, best_tau = self.levels[0], -math.inf
        for f in self.levels:
            u = solve(f * b)
            tau = release_time(predict(self.rollout(t, x, first=u), alpha, d_bar))
            taus.append(tau)
            if tau > best_tau:
                best, best_tau = f, tau
        self.factor, self._since, self.last_tau = best, 1, tuple(taus)
        self.choices += 1
        self.raised += best != self.levels[0]
