"""What the intermittent filter adds to its on/off trigger: designed off periods and a smooth hand-over.

Three optional parts of :class:`~isf_robot.core.filters.IntermittentSafetyFilter` (each off by
default, so a filter built without them behaves exactly as before):

* **A minimum off time by design** (:class:`FallRateBound`). An off period starts with every
  ``Xi_on >= c`` and ends when some ``Xi_on`` reaches 0, so if ``min_i Xi_on`` falls no faster
  than ``R`` while the filter is off, every off period lasts at least ``c / R`` -- the paper's
  MIET ``tau = c / (L_Xi (B + d_bar))`` (Proposition 1) with the product ``L_Xi (B + d_bar)``,
  the largest rate of change of ``Xi`` along the flow, replaced by ``R``. ``R`` is *measured*:
  the fall rate of ``min_i Xi_on`` between consecutive off-mode steps (the state then moves under
  the nominal command), a running maximum that forgets with time constant ``forget_s``. Asked
  for ``min_off`` seconds, the filter uses the off margin ``c_eff = clip(min_off R, c, c_max)``
  and reports the bound ``c_eff / R`` at every off switch beside the measured off periods. A
  measured rate is not a proof: the measured minimum off period is always reported too.
* **A predictive off trigger** (:class:`OffPredictor`). When the off condition holds, the filter
  asks a rollout callback for the nominal controller rolled forward on the reduced model
  ``q_dot = u_nom(q)`` over a horizon, computes ``Xi_on`` at the predicted points with its own
  ``alpha`` and ``d_bar`` (:func:`~isf_robot.core.triggers.xi_on`: the formula lives once), and
  turns off only if every predicted ``Xi_on > 0``. Rows predicted to fail are promoted while the
  filter stays on, steering toward states with a longer off time. The prediction only *delays*
  switching off at ``c``; with ``c_pred < c`` (the filter's option) it may also switch off *early*, at
  every ``Xi_on >= c_pred``, when the rollout predicts every ``Xi_on > 0`` over the horizon, so the
  promotion stops as soon as the nominal is predicted safe instead of pushing on to ``c``. Either way
  the on trigger is monitored exactly as before and the robust condition is enforced whenever it
  binds, so Theorem 1 is untouched (``c_pred > 0`` keeps the hysteresis; the off period's length now
  rests on the prediction, and the measured off periods are reported). The
  rollout runs at most once every ``every`` control steps (its cost per step is bounded).
* **A smooth hand-over** (:func:`blend_weight`). For ``blend`` seconds after an off switch the
  command moves linearly from the last filtered command to the nominal one, projected onto the
  robust barrier conditions (the standard filter's QP with the blended target), so the only step
  in the command is the one safety requires; for ``blend`` seconds after an on switch the
  promotion level ramps from the robust condition ``-alpha(h)`` to ``b`` (never below the robust
  condition).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .class_k import ClassK
from .exceptions import ConfigError, NonFiniteError
from .fast import NO_SCREEN, xi_kernel, xi_pass
from .miet import miet_bound
from .system import LieData
from .triggers import xi_on
from .validation import check_nonnegative

__all__ = ["FallRateBound", "OffPredictor", "Prediction", "RolloutFn", "blend_weight"]

RolloutFn = Callable[[float, Any], Sequence[tuple[float, LieData, np.ndarray]]]
"""``rollout(t, x) -> [(s, lie, u_nom), ...]``: predicted barrier data and nominal command at times
``t + s`` (``0 < s <= horizon``) of the nominal controller rolled forward on the reduced model from
the state ``x`` the adapter passed to ``step_lie`` (``None`` if it passed none)."""


class FallRateBound:
    """Measured bound ``R`` on how fast ``min_i Xi_on`` falls while the filter is off.

    Args:
        prior: Rate assumed before any measurement [units of Xi per s] (0: none).
        forget_s: Time constant [s] with which the running maximum decays (``inf``: a plain
            running maximum over the run).

    """

    def __init__(self, prior: float = 0.0, forget_s: float = 2.0) -> None:
        self.prior = check_nonnegative(prior, "prior fall rate")
        if not forget_s > 0:
            raise ConfigError(f"forget_s (fall-rate memory) must be > 0 [s] (inf: never forget), got {forget_s}")
        self.forget_s = float(forget_s)
        self.reset()

    def reset(self) -> None:
        """Forget every measurement."""
        self.rate = self.prior
        self._t: float | None = None
        self._xi = 0.0
        self.samples = 0

    def observe(self, t: float, xi_min: float, off: bool) -> None:
        """Record ``min_i Xi_on`` at time ``t``; ``off``: the filter was off since the previous sample.

        Only intervals spent off (the state moving under the nominal command) measure the rate.
        """
        finite = math.isfinite(xi_min)
        if off and finite and self._t is not None and t > self._t:
            dt = t - self._t
            fall = (self._xi - xi_min) / dt
            decayed = self.rate * math.exp(-dt / self.forget_s)
            self.rate = max(fall, decayed, 0.0)
            self.samples += 1
        self._t, self._xi = (t, xi_min) if finite else (None, 0.0)

    def margin(self, min_off: float, c_min: float, c_max: float) -> float:
        """Off margin ``clip(min_off R, c_min, c_max)`` that makes off periods last ``min_off`` at rate ``R``."""
        return min(c_max, max(c_min, min_off * self.rate))

    def bound_s(self, c: float) -> float:
        """Shortest off period the margin ``c`` guarantees at fall rate ``R`` [s] (``inf`` at ``R = 0``)."""
        return miet_bound(c, self.rate, 1.0) if self.rate > 0 else math.inf


@dataclass(frozen=True)
class Prediction:
    """The outcome of one rollout.

    Attributes:
        ok: Every predicted ``Xi_on`` is > 0 over the horizon.
        xi_min: Smallest predicted ``Xi_on`` (``inf`` without points).
        first_fail_s: Time from now of the first predicted point with some ``Xi_on <= 0``
            (``None`` when ok).
        failing: Names of the rows predicted to reach ``Xi_on <= 0``.
        points: Predicted points evaluated.

    """

    ok: bool
    xi_min: float
    first_fail_s: float | None
    failing: frozenset[str]
    points: int


def predict(points: Sequence[tuple[float, LieData, np.ndarray]], alpha: ClassK, d_bar: float) -> Prediction:
    """Evaluate ``Xi_on`` at every predicted point; see :class:`Prediction`.

    Each point's ``Xi_on`` is :func:`~isf_robot.core.triggers.xi_on`, made in one compiled pass
    where the kernel is available (:func:`~isf_robot.core.fast.xi_pass`: the same numbers, as in
    the filter's own step).
    """
    kernel = xi_kernel()
    xi_lo = math.inf
    first: float | None = None
    failing: set[str] = set()
    for s, lie, u in points:
        u = np.asarray(u, dtype=float)
        got = None if kernel is None else xi_pass(kernel, lie, u, alpha, d_bar, NO_SCREEN)
        if got is not None:
            xi, total, lo = got[0], got[1], got[2]
        else:
            xi = xi_on(lie, u, alpha, d_bar)
            xl = xi.tolist()
            total, lo = sum(xl), min(xl, default=math.inf)
        if xi.size == 0:
            continue
        if not math.isfinite(total):
            raise NonFiniteError(f"predicted Xi_on not finite {s:.3g} s ahead: {xi}")
        xi_lo = min(xi_lo, lo)
        if lo <= 0.0:
            first = s if first is None else min(first, s)
            names, nn = lie.names, len(lie.names)
            failing.update([names[i] if i < nn else str(i) for i, v in enumerate(xi.tolist()) if v <= 0.0])
    return Prediction(first is None, xi_lo, first, frozenset(failing), len(points))


class OffPredictor:
    """Gate of the off switch by a rollout, run at most once every ``every`` control steps.

    :meth:`check` is called at each step where the off condition holds; it runs the rollout on
    the first such step and then every ``every``-th step while the condition keeps holding,
    returning the last outcome in between. :meth:`idle` (the condition does not hold, or the
    filter switched) restarts the count.

    Args:
        rollout: The rollout callback (:data:`RolloutFn`).
        every: Steps between rollouts, >= 1.

    """

    def __init__(self, rollout: RolloutFn, every: int = 5) -> None:
        if not callable(rollout):
            raise ConfigError("rollout must be callable rollout(t, x) -> [(s, lie, u_nom), ...]")
        if int(every) != every or int(every) < 1:
            raise ConfigError(f"predict_every must be a whole number of control steps >= 1, got {every}")
        self.rollout = rollout
        self.every = int(every)
        self.reset()

    def reset(self) -> None:
        """Forget the last prediction and the counts."""
        self.last: Prediction | None = None
        self._since = 0
        self.rollouts = 0

    def idle(self) -> None:
        """The off condition does not hold: the next :meth:`check` runs a rollout."""
        self.last = None
        self._since = 0

    def check(self, t: float, x: Any, alpha: ClassK, d_bar: float) -> tuple[Prediction, bool]:
        """The prediction for switching off at ``t`` from state ``x`` and whether a rollout ran for it."""
        if self.last is not None and self._since < self.every:
            self._since += 1
            return self.last, False
        self.last = predict(self.rollout(t, x), alpha, d_bar)
        self._since = 1
        self.rollouts += 1
        return self.last, True


def blend_weight(t: float, t_switch: float | None, blend: float) -> float:
    """Weight of the pre-switch command ``1 - (t - t_switch) / blend`` in [0, 1] (0 without a blend)."""
    if blend <= 0.0 or t_switch is None:
        return 0.0
    return min(1.0, max(0.0, 1.0 - (t - t_switch) / blend))
