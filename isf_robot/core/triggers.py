"""Trigger logic (paper, eqs. trigger:filter_on, trigger:filter_off, trigger:greedy, trigger:int_time).

The trigger values themselves are plain functions of Lie data; the stateful parts are small
state machines driven by the caller's clock, so they can be tested with a fake clock.

**The off trigger's sign.** The paper writes the off trigger as ``Xi_off = Xi_on - c <= 0``.
Read literally this holds the instant the filter turns on (``Xi_on <= 0 < c``), so the filter
would switch off at once. The text and the proof of Theorem 1 need every off period to start
with ``Xi_on >= c``; we implement exactly that: the filter turns OFF at the first time after
an on-time with ``Xi_on >= c``. On at ``Xi_on <= 0``, off at ``Xi_on >= c``: hysteresis.
"""

from __future__ import annotations

import math

import numpy as np

from .class_k import ClassK
from .exceptions import ConfigError
from .jit import formula
from .robust import robust_slack
from .switches import SwitchCounter, SwitchEvent
from .system import LieData
from .validation import check_finite_scalar, check_nonnegative, check_positive

__all__ = ["SwitchEvent", "OnOffTrigger", "xi_on", "xi_on_scalar", "xi_tau"]


def xi_on(lie: LieData, u_nom: np.ndarray, alpha: ClassK, d_bar: float,
          alpha_h: np.ndarray | None = None) -> np.ndarray:
    """Per-barrier on-trigger values ``Xi_on = Lf h(x, u_nom) - |dh/dx| d_bar + alpha(h)``.

    :func:`~isf_robot.core.robust.robust_slack` of every row under ``u_nom``; also the greedy
    impulsive trigger ``Xi`` (eq. greedy_cond) when ``lg`` is empty / ``u_nom`` is the flow's.

    Args:
        lie: Lie data at the current state, k barriers.
        u_nom: Nominal command, shape (m,).
        alpha: Class-K function.
        d_bar: Disturbance bound.
        alpha_h: ``alpha.vector(lie.h)`` when the caller has it already.

    Returns:
        Shape (k,).

    """
    if alpha_h is None:
        alpha_h = alpha.vector(lie.h)
    lg = lie.lg
    lg_u = lg @ u_nom if lg.shape[1] else np.zeros(lg.shape[0])
    return robust_slack(lie.lf, lg_u, lie.grad_norm, d_bar, alpha_h)


def xi_on_scalar(lf: float, lg_u: float, grad_norm: float, h: float, alpha: ClassK, d_bar: float) -> float:
    """One barrier's ``Xi_on`` in plain floats (:func:`~isf_robot.core.robust.robust_slack` of one row).

    For callers that evaluate it inside an integrator's event function (about 0.3 us instead of
    ~20 us of array work). With ``lg_u = 0`` it is the greedy impulsive trigger ``Xi``.

    Args:
        lf: Drift term ``dh/dx f0(x) + dh/dt`` [units of h per s].
        lg_u: Input term ``dh/dx g(x) u_nom`` [units of h per s] (0 for an impulsive flow).
        grad_norm: ``|dh/dx|``.
        h: Barrier value.
        alpha: Class-K function, called on the float ``h``.
        d_bar: Disturbance bound.

    Returns:
        The trigger value [units of h per s].

    """
    return robust_slack(lf, lg_u, grad_norm, d_bar, alpha(h))


@formula
def xi_tau(dtau_dh: float, lf_h: float) -> float:
    """Maneuver trigger value ``Xi_tau = (1 + tau_p_dot) / 2`` with ``tau_p_dot = tau_p'(h) LF h``.

    Args:
        dtau_dh: Derivative of the fitted inter-event time with respect to h at h(x).
        lf_h: Lie derivative of h along the flow at x.

    """
    return 0.5 * (1.0 + dtau_dh * lf_h)


class OnOffTrigger:
    """Hysteresis between the on trigger (``Xi_on <= 0``) and the off trigger (``Xi_on >= c``).

    With several barriers, pass ``min_i Xi_on,i``: the filter turns on when any barrier's
    value reaches 0 and off when every barrier's value is at least ``c``.

    *Off hold* (``off_hold > 0``): the off trigger asks its condition (``xi_min`` at least the margin) to
    have held at every update of the last ``off_hold`` seconds while on, the update that switched on
    included (where it failed). Where ``Xi_on`` can flip sign between control steps (the closest points of
    two links jumping between features; a torque-level barrier's curvature term) the filter would switch
    off and on within milliseconds; the hold keeps it on instead. It only ever keeps the filter on (the
    filter's constraints enforced), never off, so the safety argument is unchanged.

    Args:
        c: Margin ``c > 0`` required before the filter may turn off.
        t0: Start time [s].
        start_on: Start in the on mode.
        off_hold: Seconds the off condition must have held before the filter turns off (0: none).

    """

    def __init__(self, c: float, t0: float = 0.0, start_on: bool = False, off_hold: float = 0.0) -> None:
        self.c = check_positive(c, "c (off-trigger margin)")
        self.off_hold = check_nonnegative(off_hold, "off_hold (off hold [s])")
        self.reset(t0, start_on)

    def reset(self, t0: float = 0.0, start_on: bool = False) -> None:
        """Forget history; start at ``t0`` in the given mode.

        Starting on counts as the off condition failing at ``t0``: the off hold runs from there.
        """
        self._t_last = check_finite_scalar(t0, "t0")
        self._t_fail = t0 if start_on else -math.inf  # the last update at which the off condition failed while on
        self._switches = SwitchCounter(start_on)

    @property
    def on(self) -> bool:
        """Current mode."""
        return self._switches.on

    @property
    def n_on(self) -> int:
        """On-switches so far."""
        return self._switches.n_on

    @property
    def n_off(self) -> int:
        """Off-switches so far."""
        return self._switches.n_off

    def update(self, t: float, xi_min: float, margin: float | None = None,
               allow_off: bool = True) -> SwitchEvent | None:
        """Advance to time ``t`` given the current ``min_i Xi_on,i``.

        Args:
            t: Time [s], non-decreasing.
            xi_min: ``min_i Xi_on,i`` at ``t``.
            margin: Off margin for this step (default ``c``; a designed margin, >= ``c``).
            allow_off: ``False`` keeps the filter on although ``xi_min >= margin`` (a predictive
                off trigger delays switching off; the on trigger is never delayed).

        Returns:
            The switch event if the mode changed at ``t``, else ``None``.

        """
        if t < self._t_last:
            raise ConfigError(f"trigger time went backwards: {t} < {self._t_last}")
        if xi_min != xi_min:  # NaN
            raise ConfigError(f"trigger value is NaN at t={t}")
        self._t_last = t
        if not self._switches.on:
            if xi_min <= 0.0:
                self._t_fail = t
                return self._switches.update(t, True, xi_min)
            return None
        if xi_min < (self.c if margin is None else max(margin, self.c)):
            self._t_fail = t
        elif allow_off and t - self._t_fail >= self.off_hold:
            return self._switches.update(t, False, xi_min)
        return None
