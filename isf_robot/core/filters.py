"""The standard safety filter (paper, eq. filter) and the intermittent safety filter (Section V).

Both share one interface: ``step(t, x, u_nom)`` (barriers evaluated from the configured
system and barrier objects) or ``step_lie(t, lie, u_nom, x=None)`` for adapters that compute
barrier data in batch (the MuJoCo arm). Both return a :class:`FilterStep` carrying the switch
event of the step (the standard filter's "on" is "a constraint is active").

Infeasibility policy (``on_infeasible``):

* ``"raise"`` (default): :class:`~isf_robot.core.exceptions.InfeasibleFilterError` carrying the
  QP, the state and the barrier values.
* ``"fallback"``: the ``fallback`` callable ``fallback(t, x, lie, qp_result) -> u`` gives the
  command (default: the least-violation command of the slack problem). The step is marked
  ``fallback=True``, the QP status is ``"fallback"``, and an :class:`IsfWarning` is issued. A
  fallback is never presented as a safe answer.

Several barriers in the intermittent filter (paper, Section V): the filter turns on when
any ``Xi_on,i <= 0`` and off when every ``Xi_on,i >= c``. While on, each barrier with
``Xi_on,i < c`` gets the safety-promoting row ``Lf h_i - |dh_i/dx| d_bar >= b`` (eq. filter_inc)
and every other barrier keeps the robust barrier condition (eq. barr_cond), so no barrier is
neglected. If that QP is infeasible, the promotions are relaxed to the robust condition (the
safety condition itself is never relaxed) and the relaxed rows are reported in
``FilterStep.relaxed``; only if the robust problem is infeasible too does the infeasibility
policy apply.

Row screening (``screen``): rows whose ``Xi_on,i`` (the slack of their robust condition under
``u_nom``) is at least ``screen`` are left out of the QP (never fewer than one row), and
checked at its solution; if one is violated or active there the QP is solved again with every
row (``FilterStep.resolved``). So screening saves time on the many far-away rows of a robot
and never changes a command. The threshold is raised to ``c`` for the intermittent filter, so
a screened row is never promoted; the trigger always sees every row's ``Xi_on``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .barrier import Barrier
from .class_k import ClassK
from .exceptions import ConfigError, ShapeError
from .filter_base import _NO_CLOSED, FallbackFn, FilterStep, _FilterBase, _Xi
from .handover import PromotionRamp, blend_weight
from .intermittent import FallRateBound, OffPredictor, Prediction, RolloutFn
from .qp_solver import QPSolver
from .shooting import ManeuverShooter
from .spec import FilterSpec
from .system import ControlAffineSystem, LieData
from .triggers import OnOffTrigger

__all__ = ["FilterStep", "SafetyFilter", "IntermittentSafetyFilter"]

_NONE_B = np.zeros(0, bool)
_NONE_F = np.zeros(0)
_SPEC = FilterSpec()  # (the defaults of the options below: FilterSpec's, stated once)


class SafetyFilter(_FilterBase):
    """The standard safety filter, solved at every step (paper, eq. filter).

    ``u = argmin |u - u_nom|^2  s.t.  Lf h_i(x, u) - |dh_i/dx| d_bar >= -alpha(h_i)`` for all i.
    The step counts as "on" when any constraint is active at the solution (or the fallback
    was applied); mode changes are reported as :class:`SwitchEvent` like the intermittent
    filter's.

    Args:
        alpha: Class-K function (or linear gain).
        d_bar: Disturbance bound ``|d| <= d_bar``, >= 0.
        system: Control-affine system (for :meth:`step`).
        barriers: Barriers (for :meth:`step`).
        u_min: Optional lower input bounds, shape (m,).
        u_max: Optional upper input bounds, shape (m,).
        solver: QP solver (default :class:`QPSolver`).
        on_infeasible: ``"raise"`` or ``"fallback"`` (see module docstring).
        fallback: Optional fallback command function.
        validate: Check shapes of every input (finiteness is always checked).
        screen: Row-screening threshold on ``Xi_on`` (scalar or per row), or ``None``.

    """

    @classmethod
    def from_spec(cls, spec: FilterSpec, **wiring: Any) -> SafetyFilter:
        """The filter with ``spec``'s ``alpha`` and ``d_bar`` (``wiring``: as the class's keyword arguments)."""
        return cls(spec.alpha, spec.d_bar, **wiring)

    def reset(self, t0: float = 0.0) -> None:
        """Forget the mode history."""
        self._switches.reset(False)
        self.qp_solves = 0

    @property
    def on(self) -> bool:
        """Whether a constraint was active at the last step."""
        return self._switches.on

    def step_lie(self, t: float, lie: LieData, u_nom: np.ndarray, x: np.ndarray | None = None, *,
                 screen: float | np.ndarray | None = None) -> FilterStep:
        """Filter ``u_nom`` given precomputed barrier data.

        ``screen`` overrides the constructor's row-screening threshold for this step (scalar or
        one per row of ``lie``).
        """
        screen = self.screen if screen is None else screen
        xs = self._xi(t, lie, u_nom, screen, True)
        u_nom, xi, xi_min, av, _, _, short = xs
        if short is not None and short[1]:  # (the rows' closed form, every other row holding: solved with Xi_on)
            res, fb, resolved, on = short[0], False, False, short[2]
        else:
            res, _, fb, resolved = self._solve_rows(t, x, lie, u_nom, xi, av, None, _NONE_F, 0.0, 0.0, screen, xs)
            on = fb or any(res.active.tolist())
        sw = self._switches
        event = None if on == sw.on else sw.update(t, on, xi_min)
        return FilterStep._of(t, res.u, u_nom, on, lie.h, xi, event, res, (), fb, lie.names, resolved)


class IntermittentSafetyFilter(_FilterBase):
    """The event-triggered intermittent safety filter (paper, Theorem 1).

    Off: the nominal command passes through (projected onto ``u_min``/``u_max`` with the robust
    conditions kept, when it breaks them; the mode stays off); the on trigger monitors
    ``Xi_on(x) = Lf h(x, u_nom) - |dh/dx| d_bar + alpha(h(x))`` and turns the filter on at
    ``Xi_on <= 0`` (eq. trigger:filter_on). On: the safety-promoting filter
    ``Lf h(x, u) - |dh/dx| d_bar >= b`` (eq. filter_inc) pushes h up until ``Xi_on >= c``, when
    the filter turns off. (The paper's eq. trigger:filter_off has a sign slip; see
    :mod:`isf_robot.core.triggers`.) Several barriers and screening: see the module docstring.
    Designed off periods, the predictive off trigger and the smooth hand-over (all optional):
    see :mod:`isf_robot.core.intermittent`.

    Args:
        alpha: Class-K function (or linear gain).
        c: Off-trigger margin, > 0 (with ``min_off``: the smallest margin used).
        b: Promotion rate ``dh/dt >= b`` while on, > 0.
        d_bar: Disturbance bound, >= 0.
        system, barriers, u_min, u_max, solver, on_infeasible, fallback, validate, screen: as
            :class:`SafetyFilter`.
        t0: Start time [s].
        min_off: Asked-for shortest off period [s]: the off margin becomes
            ``clip(min_off R, c, c_max)`` with ``R`` the measured fall rate of ``Xi_on``
            (``None``: the fixed margin ``c``).
        c_max: Largest off margin ``min_off`` may ask for (``inf``: none).
        fall_rate_prior: Fall rate of ``Xi_on`` assumed before the first measurement.
        fall_rate_forget: Time constant [s] of the measured fall rate's memory.
        rollout: Predictive off trigger: the rollout callback
            (:data:`~isf_robot.core.intermittent.RolloutFn`); ``None``: off at ``Xi_on >= c``.
        predict_every: Control steps between rollouts while the off condition holds, >= 1.
        blend: Hand-over time [s] after each switch (0: the command steps at switches).
        c_pred: Off margin when the rollout predicts the nominal safe (``0 < c_pred <= c``; needs
            ``rollout``): the filter turns off as soon as every ``Xi_on >= c_pred`` and the rollout
            predicts every ``Xi_on > 0`` over its horizon, instead of pushing on to ``Xi_on >= c``
            (``None``: the prediction only delays the off switch at ``c``).
        shoot: Maneuvers by shooting: the horizon [s] of ``shoot_rollout`` (0: off; the adapter's rollout
            has it): while on, the promotion level among ``b, 3 b, 10 b`` after which the nominal is
            predicted to re-trigger latest (:class:`~isf_robot.core.shooting.ManeuverShooter`).
        shoot_rollout: The rollout that scores the levels (:data:`~isf_robot.core.intermittent.RolloutFn`
            taking ``first=u``); needed when ``shoot > 0``.
        off_hold: Off only once the off condition has held this long [s] (the trigger's off hold,
            :class:`~isf_robot.core.triggers.OnOffTrigger`; 0 or ``None``: none).

    """

    intermittent = True

    def __init__(
        self,
        alpha: ClassK | float | Callable[[float], float],
        c: float,
        b: float,
        d_bar: float = _SPEC.d_bar,
        *,
        system: ControlAffineSystem | None = None,
        barriers: Sequence[Barrier] | None = None,
        u_min: Sequence[float] | np.ndarray | None = None,
        u_max: Sequence[float] | np.ndarray | None = None,
        solver: QPSolver | None = None,
        on_infeasible: str = "raise",
        fallback: FallbackFn | None = None,
        validate: bool = True,
        screen: float | np.ndarray | None = None,
        t0: float = 0.0,
        min_off: float | None = None,
        c_max: float = _SPEC.c_max,
        fall_rate_prior: float = _SPEC.fall_rate_prior,
        fall_rate_forget: float = _SPEC.fall_rate_forget,
        rollout: RolloutFn | None = None,
        predict_every: int = _SPEC.predict_every,
        blend: float = 0.0,
        c_pred: float | None = None,
        shoot: float = 0.0,
        shoot_rollout: Callable[..., Any] | None = None,
        off_hold: float | None = None,
    ) -> None:
        super().__init__(alpha, d_bar, system=system, barriers=barriers, u_min=u_min, u_max=u_max,
                         solver=solver, on_infeasible=on_infeasible, fallback=fallback, validate=validate,
                         screen=screen)
        self.spec = spec = FilterSpec(
            alpha=self.alpha, d_bar=self.d_bar, c=c, b=b, min_off=0.0 if min_off is None else min_off, c_max=c_max,
            fall_rate_prior=fall_rate_prior, fall_rate_forget=fall_rate_forget, blend=blend,
            predict_every=predict_every, c_pred=0.0 if c_pred is None else c_pred, shoot=shoot,
            off_hold=off_hold or None)
        self.c, self.b, self.c_max, self.blend = spec.c, spec.b, spec.c_max, spec.blend
        self.min_off = spec.min_off or None
        self.c_pred = spec.c_pred or None
        self.fall_rate = FallRateBound(spec.fall_rate_prior, spec.fall_rate_forget)
        self.predictor = None if rollout is None else OffPredictor(rollout, spec.predict_every)
        if self.c_pred is not None and self.predictor is None:
            raise ConfigError("c_pred (predicted-safe off margin) needs a rollout (the predictive off trigger)")
        if spec.shoot and shoot_rollout is None:
            raise ConfigError("shoot (maneuvers by shooting) needs its rollout: shoot_rollout(t, x, first=u)")
        self.shooter = ManeuverShooter(shoot_rollout, spec.predict_every, self.blend) if spec.shoot else None
        self.trigger = OnOffTrigger(self.c if self.c_pred is None else self.c_pred, t0, off_hold=spec.off_hold or 0.0)
        self.reset(t0)

    @classmethod
    def from_spec(cls, spec: FilterSpec, **wiring: Any) -> IntermittentSafetyFilter:
        """The filter with the parameters of ``spec``.

        ``wiring``: ``system``, ``barriers``, ``u_min``, ``u_max``, ``solver``, ``on_infeasible``,
        ``fallback``, ``validate``, ``screen``, ``t0``, ``rollout`` (see the class).
        """
        return cls(spec.alpha, spec.c, spec.b, spec.d_bar, **spec.intermittent_kwargs(), **wiring)

    @property
    def on(self) -> bool:
        """Current mode."""
        return self.trigger.on

    def reset(self, t0: float = 0.0) -> None:
        """Return to the off mode at ``t0``."""
        self.trigger.reset(t0)
        self.qp_solves = 0
        self.fall_rate.reset()
        if self.predictor is not None:
            self.predictor.reset()
        if self.shooter is not None:
            self.shooter.reset()
        self._t_off: float | None = None
        self._u_prev: np.ndarray | None = None
        self._u_handover: np.ndarray | None = None
        self._t_ramp: float | None = None
        self._ramp = PromotionRamp(self._passes.promote_rows)  # the hand-over's per-row weights
        self._fail_of: tuple[Any, Any, np.ndarray] = (None, None, _NONE_B)

    def margin(self) -> float:
        """The off margin now: ``c``, or the one designed for ``min_off``."""
        if self.min_off is None:
            return self.c
        return self.fall_rate.margin(self.min_off, self.c, self.c_max)

    def step_lie(self, t: float, lie: LieData, u_nom: np.ndarray, x: np.ndarray | None = None, *,
                 screen: float | np.ndarray | None = None, promotable: np.ndarray | None = None) -> FilterStep:
        """As :meth:`step`, given precomputed barrier data.

        ``screen`` overrides the constructor's row-screening threshold for this step (scalar or
        one per row of ``lie``). ``promotable`` (bool, one per row; ``None``: every row) limits the
        promotion to those rows: the others keep the robust condition while the filter is on (a team
        of arms leaves its inter-arm rows unpromoted, :mod:`isf_robot.core.team`). The trigger still
        sees every row.
        """
        xs = self._xi(t, lie, u_nom)
        u_nom, xi, xi_min, _, _, _, _ = xs
        trigger = self.trigger
        was_on = trigger.on
        self.fall_rate.observe(t, xi_min, not was_on)
        c = self.c if self.min_off is None else self.margin()
        gate = c if self.c_pred is None else min(c, self.c_pred)  # off needs every Xi_on >= gate
        pred, ran = None, False
        if self.predictor is not None:
            if was_on and xi_min >= gate:
                pred, ran = self.predictor.check(t, x, self.alpha, self.d_bar)
            else:
                self.predictor.idle()
        held = pred is not None and not pred.ok
        if pred is not None and pred.ok:
            c = gate  # predicted safe over the horizon: off at the lower margin
        event = trigger.update(t, xi_min, c, not held)
        bound = None
        if event is not None:
            if event.kind == "off":
                self._t_off, self._u_handover = t, self._u_prev
                self._ramp.clear()
                self._t_ramp = None
                bound = self.fall_rate.bound_s(c)
                if self.predictor is not None:
                    self.predictor.idle()
                if self.shooter is not None:
                    self.shooter.idle()
        if not trigger.on:
            w = 0.0
            if self._u_handover is not None:
                w = blend_weight(t, self._t_off, self.blend)
                if w == 0.0:  # the hand-over is over (time only moves on): no weight until the next off switch
                    self._u_handover = None
            if w == 0.0 and (self.u_min is None and self.u_max is None or self._within_bounds(u_nom)):
                self._u_prev = u_nom
                return FilterStep._of(t, u_nom, u_nom, False, lie.h, xi, event, None, (), False, lie.names, False,
                                      c, bound, ran, held)
            target = u_nom if w == 0.0 else u_nom + w * (self._u_handover - u_nom)
            slack = xi if w == 0.0 else xi + lie.lg @ (target - u_nom)  # robust slack at the target
            if w > 0.0 and float(slack.min()) >= 0.0 and self._within_bounds(target):
                self._u_prev = target
                return FilterStep._of(t, target, u_nom, False, lie.h, xi, event, None, (), False, lie.names, False,
                                      c, bound, ran, held)
            # off, but the target breaks the input bounds or (blending) a robust condition: the
            # command closest to it within them that keeps every robust condition; the mode stays off
            res, relaxed, fb, resolved = self._solve_rows(t, x, lie, target, slack, xs.av, None, _NONE_F, 0.0, 0.0,
                                                          screen, xs if w == 0.0 else None)
            return self._done(FilterStep._of(t, res.u, u_nom, False, lie.h, xi, event, res, relaxed, fb,
                                             lie.names, resolved, c, bound, ran, held))
        failing = self._failing(pred, lie) if held and pred is not None and pred.failing else None
        rate = None
        if self.blend > 0:
            rate = (t - self._t_ramp) / self.blend if self._t_ramp is not None else 0.0
            self._t_ramp = t
        fail = _NONE_B if failing is None else failing
        if promotable is not None:
            if promotable.shape != xi.shape:
                raise ShapeError(f"promotable: one flag per row ({xi.shape[0]}), got shape {promotable.shape}")
            if promotable.dtype != bool or not promotable.flags.c_contiguous:  # (the type the passes take)
                promotable = np.ascontiguousarray(promotable, dtype=bool)
        if self.shooter is None and self._closed:
            res, relaxed, fb, resolved = self._promoted_solve(t, x, lie, xs, c, fail, rate, promotable, screen)
            return self._done(FilterStep._of(t, res.u, u_nom, True, lie.h, xi, event, res, relaxed, fb, lie.names,
                                             resolved, c, bound, ran, held))
        promote, ramp = self._ramp(xi, c, fail, rate, lie.names)
        if promotable is not None:
            promote &= promotable  # (the ramp's own array, rewritten by its next call)
        b, solved = self.b, None
        if self.shooter is not None:
            tried: dict[float, Any] = {}

            def solve(level: float) -> np.ndarray:
                r = tried[level] = self._solve_rows(t, x, lie, u_nom, xi, xs.av, promote, ramp, level, c, screen, xs)
                return r[0].u

            b = self.shooter.level(t, x, b, solve, self.alpha, self.d_bar)
            solved = tried.get(b)  # (a candidate's solve is the step's when its level is the one in use)
        res, relaxed, fb, resolved = solved or self._solve_rows(t, x, lie, u_nom, xi, xs.av, promote, ramp, b, c,
                                                                screen, xs)
        return self._done(FilterStep._of(t, res.u, u_nom, True, lie.h, xi, event, res, relaxed, fb, lie.names,
                                         resolved, c, bound, ran, held))

    def _promoted_solve(self, t: float, x: Any, lie: LieData, xs: _Xi, c: float, failing: np.ndarray,
                        rate: float | None, promotable: np.ndarray | None,
                        screen: float | np.ndarray | None) -> tuple[Any, tuple[str, ...], bool, bool]:
        """The on step's promotion and solve where the closed forms serve (:meth:`_closed_forms`; no maneuvers).

        What :attr:`_ramp` and :meth:`_solve_rows` (the promoted rows, floor ``c``) do one after the other, with their
        passes in one call (:func:`~isf_robot.core.closed_step.promoted_closed_step`): the promoted rows (limited to
        ``promotable``), the rows kept and their closed form; then the QP where that gave no answer.
        """
        xi, u_nom = xs.xi, xs.u_nom
        k = xi.shape[0]
        ids, w, inw, promote, ramp = self._ramp.arrays(k, rate, lie.names)
        if screen is None:
            screen = self.screen
        sa = _NONE_F if screen is None or k < 2 else self._screen_array(screen, k)
        solver, buf, b = self.solver, self._rows_buf, self.b
        if promotable is None:
            promotable = _NONE_B  # (else C-contiguous bool, one per row: step_lie made it so)
        u = np.empty(u_nom.shape[0])
        t0 = time.perf_counter()
        n, code, low, held, bits = xs.passes.promoted_closed_step(
            xi, c, failing, rate is not None, ids, w, inw, 0.0 if rate is None else rate, promote, ramp,
            promotable, sa, xs.argmin, buf, lie.lf, lie.grad_norm, self.d_bar,
            xs.av, b, lie.lg, u_nom, solver.feas_tol, solver.active_tol, solver.few_rows, self._lo, self._hi, u,
            self._res_buf)
        short = self._closed_result(u_nom, u, code, low, held, n, bits, t0) if code >= 0 else _NO_CLOSED
        if short[1]:  # (answered, every other row holding: as _rows_solved returns it)
            return short[0], (), False, False
        return self._rows_solved(t, x, lie, u_nom, xi, xs.av, promote, ramp, b, xs.passes, None if n == k else buf[:n],
                                 short)

    def _failing(self, pred: Prediction, lie: LieData) -> np.ndarray:
        """The rows whose names the prediction found failing (kept while the prediction and names are the same)."""
        if pred is not self._fail_of[0] or lie.names is not self._fail_of[1] or lie.k != self._fail_of[2].shape[0]:
            self._fail_of = (pred, lie.names, np.fromiter(map(pred.failing.__contains__, lie.names), bool, lie.k))
        return self._fail_of[2]

    def _done(self, step: FilterStep) -> FilterStep:
        self._u_prev = step.u
        return step
