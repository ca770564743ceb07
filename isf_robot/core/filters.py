"""The standard safety filter (paper, eq. filter) and the intermittent safety filter (Section V).

Both share one interface: ``step(t, x, u_nom)`` (barriers evaluated from the configured
system and barrier objects) or ``step_lie(t, lie, u_nom, x=None)`` for adapters that compute
barrier data in batch (the MuJoCo arm). Both return a :class:`FilterStep`.

Infeasibility policy (``on_infeasible``):

* ``"raise"`` (default): :class:`~isf_robot.core.exceptions.InfeasibleFilterError` carrying the
  QP, the state and the barrier values.
* ``"fallback"``: the ``fallback`` callable ``fallback(t, x, lie, qp_result) -> u`` gives the
  command (default: the least-violation command of the slack problem). The step is marked
  ``fallback=True``, the QP status is ``"fallback"``, and an :class:`IsfWarning` is issued. A
  fallback is never presented as a safe answer.

Several barriers in the intermittent filter (DESIGN.md, section 2): the filter turns on when
any ``Xi_on,i <= 0`` and off when every ``Xi_on,i >= c``. While on, each barrier with
``Xi_on,i < c`` gets the safety-promoting row ``Lf h_i - |dh_i/dx| d_bar >= b`` (eq. filter_inc)
and every other barrier keeps the robust barrier condition (eq. barr_cond), so no barrier is
neglected. If that QP is infeasible, the promotions are relaxed to the robust condition (the
safety condition itself is never relaxed) and the relaxed rows are reported in
``FilterStep.relaxed``; only if the robust problem is infeasible too does the infeasibility
policy apply.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .barrier import Barrier, evaluate_barriers
from .class_k import ClassK, as_class_k
from .exceptions import ConfigError, InfeasibleFilterError, IsfWarning, ShapeError
from .qp import FilterQP, QPResult, QPSolver, build_filter_qp
from .system import ControlAffineSystem, LieData, lie_data
from .triggers import OnOffTrigger, SwitchEvent, xi_on
from .validation import as_vector, check_finite_scalar, check_nonnegative, check_positive

__all__ = ["FilterStep", "SafetyFilter", "IntermittentSafetyFilter"]

FallbackFn = Callable[[float, "np.ndarray | None", LieData, QPResult], np.ndarray]


@dataclass(frozen=True)
class FilterStep:
    """One control step of a filter.

    Attributes:
        t: Time [s].
        u: The command to apply, shape (m,).
        u_nom: The nominal command, shape (m,).
        on: Whether the filter acted in this step (intermittent: its mode; standard: a
            constraint was active).
        h: Barrier values, shape (k,).
        xi: ``Xi_on`` per barrier under the nominal command, shape (k,).
        event: The on/off switch at this step, if any.
        qp: The QP result when a QP was solved, else ``None``.
        relaxed: Names of barriers whose promotion was relaxed in this step.
        fallback: Whether the command came from the infeasibility fallback.
        names: Barrier labels.

    """

    t: float
    u: np.ndarray
    u_nom: np.ndarray
    on: bool
    h: np.ndarray
    xi: np.ndarray
    event: SwitchEvent | None = None
    qp: QPResult | None = None
    relaxed: tuple[str, ...] = ()
    fallback: bool = False
    names: tuple[str, ...] = field(default_factory=tuple)

    @property
    def h_min(self) -> float:
        """Smallest barrier value."""
        return float(np.min(self.h)) if self.h.size else float("inf")

    @property
    def xi_min(self) -> float:
        """Smallest ``Xi_on``."""
        return float(np.min(self.xi)) if self.xi.size else float("inf")

    @property
    def solved_qp(self) -> bool:
        """Whether a QP (or its closed form) was solved in this step."""
        return self.qp is not None


class _FilterBase:
    def __init__(
        self,
        alpha: ClassK | float | Callable[[float], float],
        d_bar: float = 0.0,
        *,
        system: ControlAffineSystem | None = None,
        barriers: Sequence[Barrier] | None = None,
        u_min: Sequence[float] | np.ndarray | None = None,
        u_max: Sequence[float] | np.ndarray | None = None,
        solver: QPSolver | None = None,
        on_infeasible: str = "raise",
        fallback: FallbackFn | None = None,
        validate: bool = True,
    ) -> None:
        self.validate = bool(validate)
        self.alpha = as_class_k(alpha)
        self.d_bar = check_nonnegative(d_bar, "d_bar (disturbance bound)")
        self.system = system
        self.barriers = list(barriers) if barriers is not None else None
        if self.barriers is not None and len(self.barriers) == 0:
            raise ConfigError("barriers must hold at least one barrier (or be None for step_lie)")
        self.u_min = None if u_min is None else as_vector(u_min, "u_min")
        self.u_max = None if u_max is None else as_vector(u_max, "u_max")
        if self.u_min is not None and self.u_max is not None:
            if self.u_min.shape != self.u_max.shape:
                raise ShapeError(f"u_min {self.u_min.shape} and u_max {self.u_max.shape} differ in shape")
            if np.any(self.u_min > self.u_max):
                raise ConfigError(f"u_min must be <= u_max elementwise, got {self.u_min} and {self.u_max}")
        if system is not None:
            for name, b in (("u_min", self.u_min), ("u_max", self.u_max)):
                if b is not None and b.shape != (system.m,):
                    raise ShapeError(f"{name} must have shape ({system.m},), got {b.shape}")
        self.solver = solver if solver is not None else QPSolver()
        if on_infeasible not in ("raise", "fallback"):
            raise ConfigError(f"on_infeasible must be 'raise' or 'fallback', got {on_infeasible!r}")
        self.on_infeasible = on_infeasible
        if fallback is not None and not callable(fallback):
            raise ConfigError("fallback must be callable fallback(t, x, lie, qp_result) -> u")
        self.fallback = fallback
        self.qp_solves = 0

    # -- inputs --------------------------------------------------------------------------
    def lie(self, t: float, x: np.ndarray) -> LieData:
        """Evaluate the configured barriers and system at ``(t, x)``."""
        if self.system is None or self.barriers is None:
            raise ConfigError("step(t, x, u_nom) needs system= and barriers=; otherwise call step_lie()")
        x = as_vector(x, "state x", self.system.n)
        ev = evaluate_barriers(self.barriers, x, t)
        return lie_data(ev, self.system.f0(x, t), self.system.g(x, t))

    def _check_inputs(self, u_nom: np.ndarray, lie: LieData) -> np.ndarray:
        if not self.validate:
            return u_nom
        lie.validate()
        return as_vector(u_nom, "nominal command u_nom", lie.m)

    def build_qp(
        self, lie: LieData, u_nom: np.ndarray, promote: np.ndarray | None = None, b: float = 0.0
    ) -> FilterQP:
        """Build the filter QP: robust rows, or promoting rows where ``promote`` is True."""
        rhs = -self.alpha.vector(lie.h)
        kinds: tuple[str, ...]
        if promote is not None and np.any(promote):
            rhs = np.where(promote, b, rhs)
            kinds = tuple("promote" if p else "robust" for p in promote)
        else:
            kinds = ("robust",) * lie.k
        return build_filter_qp(u_nom, lie.lf, lie.lg, lie.grad_norm, rhs, self.d_bar,
                               u_min=self.u_min, u_max=self.u_max, kinds=kinds, names=lie.names)

    def _solve(self, qp: FilterQP) -> QPResult:
        self.qp_solves += 1
        return self.solver.solve(qp)

    def _infeasible(
        self, t: float, x: np.ndarray | None, lie: LieData, qp: FilterQP, res: QPResult
    ) -> tuple[np.ndarray, QPResult]:
        if self.on_infeasible == "raise":
            raise InfeasibleFilterError(
                f"safety filter infeasible at t={t:.6g}: no command satisfies the robust barrier "
                f"condition{' and the input bounds' if qp.has_bounds else ''} "
                f"(least violation {res.max_violation:.3g}; min h = {float(np.min(lie.h)):.4g})",
                qp=qp, state=x, barrier_values=lie.h.copy(), t=t,
            )
        u = res.u if self.fallback is None else as_vector(self.fallback(t, x, lie, res), "fallback command", lie.m)
        warnings.warn(
            f"safety filter infeasible at t={t:.6g}; applied the fallback command "
            f"(violation {qp.max_violation(u):.3g})", IsfWarning, stacklevel=3,
        )
        return u, QPResult(u, "fallback", res.active, res.solve_time_s, res.iterations,
                           qp.max_violation(u), res.relaxed)


class SafetyFilter(_FilterBase):
    """The standard safety filter, solved at every step (paper, eq. filter).

    ``u = argmin |u - u_nom|^2  s.t.  Lf h_i(x, u) - |dh_i/dx| d_bar >= -alpha(h_i)`` for all i.
    The step counts as "on" when any constraint is active at the solution.

    Args:
        alpha: Class-K function (or linear gain).
        d_bar: Disturbance bound ``|d| <= d_bar``, >= 0.
        system: Control-affine system (for :meth:`step`).
        barriers: Barriers (for :meth:`step`).
        u_min: Optional lower input bounds, shape (m,).
        u_max: Optional upper input bounds, shape (m,).
        solver: QP solver (default :class:`QPSolver` with eps_abs 1e-9).
        on_infeasible: ``"raise"`` or ``"fallback"`` (see module docstring).
        fallback: Optional fallback command function.

    """

    def step(self, t: float, x: np.ndarray, u_nom: np.ndarray) -> FilterStep:
        """Filter ``u_nom`` at state ``x`` and time ``t`` [s]."""
        t = check_finite_scalar(t, "t")
        x = as_vector(x, "state x", self.system.n if self.system else None)
        return self.step_lie(t, self.lie(t, x), u_nom, x=x)

    def step_lie(self, t: float, lie: LieData, u_nom: np.ndarray, x: np.ndarray | None = None) -> FilterStep:
        """Filter ``u_nom`` given precomputed barrier data."""
        u_nom = self._check_inputs(u_nom, lie)
        xi = xi_on(lie, u_nom, self.alpha, self.d_bar)
        qp = self.build_qp(lie, u_nom)
        res = self._solve(qp)
        fb = False
        if not res.ok:
            _, res = self._infeasible(t, x, lie, qp, res)
            fb = True
        on = bool(np.any(res.active)) or fb
        return FilterStep(t, res.u, u_nom, on, lie.h, xi, None, res, (), fb, lie.names)


class IntermittentSafetyFilter(_FilterBase):
    """The event-triggered intermittent safety filter (paper, Theorem 1).

    Off: the nominal command passes through; the on trigger monitors
    ``Xi_on(x) = Lf h(x, u_nom) - |dh/dx| d_bar + alpha(h(x))`` and turns the filter on at
    ``Xi_on <= 0`` (eq. trigger:filter_on). On: the safety-promoting filter
    ``Lf h(x, u) - |dh/dx| d_bar >= b`` (eq. filter_inc) pushes h up until ``Xi_on >= c``, when
    the filter turns off. (The paper's eq. trigger:filter_off has a sign slip; see
    :mod:`isf_robot.core.triggers`.) Several barriers: see the module docstring.

    Args:
        alpha: Class-K function (or linear gain).
        c: Off-trigger margin, > 0.
        b: Promotion rate ``dh/dt >= b`` while on, > 0.
        d_bar: Disturbance bound, >= 0.
        system, barriers, u_min, u_max, solver, on_infeasible, fallback, validate: as
            :class:`SafetyFilter`.
        t0: Start time [s].

    """

    def __init__(
        self,
        alpha: ClassK | float | Callable[[float], float],
        c: float,
        b: float,
        d_bar: float = 0.0,
        *,
        system: ControlAffineSystem | None = None,
        barriers: Sequence[Barrier] | None = None,
        u_min: Sequence[float] | np.ndarray | None = None,
        u_max: Sequence[float] | np.ndarray | None = None,
        solver: QPSolver | None = None,
        on_infeasible: str = "raise",
        fallback: FallbackFn | None = None,
        validate: bool = True,
        t0: float = 0.0,
    ) -> None:
        super().__init__(alpha, d_bar, system=system, barriers=barriers, u_min=u_min, u_max=u_max,
                         solver=solver, on_infeasible=on_infeasible, fallback=fallback, validate=validate)
        self.c = check_positive(c, "c (off-trigger margin)")
        self.b = check_positive(b, "b (promotion rate)")
        self.trigger = OnOffTrigger(self.c, t0)

    @property
    def on(self) -> bool:
        """Current mode."""
        return self.trigger.on

    def reset(self, t0: float = 0.0) -> None:
        """Return to the off mode at ``t0``."""
        self.trigger.reset(t0)
        self.qp_solves = 0

    def step(self, t: float, x: np.ndarray, u_nom: np.ndarray) -> FilterStep:
        """Advance the trigger to ``t`` and return the command for state ``x``."""
        t = check_finite_scalar(t, "t")
        x = as_vector(x, "state x", self.system.n if self.system else None)
        return self.step_lie(t, self.lie(t, x), u_nom, x=x)

    def step_lie(self, t: float, lie: LieData, u_nom: np.ndarray, x: np.ndarray | None = None) -> FilterStep:
        """As :meth:`step`, given precomputed barrier data."""
        u_nom = self._check_inputs(u_nom, lie)
        xi = xi_on(lie, u_nom, self.alpha, self.d_bar)
        event = self.trigger.update(t, float(np.min(xi)))
        if not self.trigger.on:
            return FilterStep(t, u_nom, u_nom, False, lie.h, xi, event, None, (), False, lie.names)
        promote = xi < self.c
        qp = self.build_qp(lie, u_nom, promote, self.b)
        res = self._solve(qp)
        relaxed: tuple[str, ...] = ()
        if not res.ok and np.any(promote):
            relaxed_idx = tuple(int(i) for i in np.flatnonzero(promote))
            relaxed = tuple(lie.names[i] if i < len(lie.names) else str(i) for i in relaxed_idx)
            qp = self.build_qp(lie, u_nom)
            res = self._solve(qp)
            res = QPResult(res.u, res.status, res.active, res.solve_time_s, res.iterations,
                           res.max_violation, relaxed_idx)
        fb = False
        if not res.ok:
            _, res = self._infeasible(t, x, lie, qp, res)
            fb = True
        return FilterStep(t, res.u, u_nom, True, lie.h, xi, event, res, relaxed, fb, lie.names)
