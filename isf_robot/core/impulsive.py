"""Event-triggered impulsive control (paper, Sections III and IV).

System (eq. sys:impulse): flow ``x_dot = F(x) + d`` with ``|d| <= d_bar``, jump
``x+ = G(x, v)``. A safeguarding controller ``K`` must give ``h(G(x, K(x))) >= 0``
(eq. jump_positive) and ``Xi(G(x, K(x))) >= c`` (eq. control_jump_cond); this module checks
both at run time and raises :class:`PostJumpConditionError` when they fail.

The integration loop (with event location) belongs to the caller; this module provides the
trigger functions, the jump with its checks, inter-event bookkeeping, a Zeno guard, and the
two-impulse maneuver scheduler.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .barrier import Barrier
from .class_k import ClassK, as_class_k
from .exceptions import ConfigError, PostJumpConditionError
from .miet import ZenoGuard
from .sums import dot, norm
from .triggers import xi_on_scalar, xi_tau
from .validation import as_vector, check_finite_scalar, check_nonnegative, check_positive

__all__ = ["JumpEvent", "EventTriggeredImpulsiveController", "ManeuverScheduler"]

FlowFn = Callable[[float, np.ndarray], np.ndarray]
JumpFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
ControlFn = Callable[[float, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class JumpEvent:
    """One impulse.

    Attributes:
        t: Time [s].
        kind: What fired it: ``"greedy"`` (``Xi <= 0``; first impulse of a maneuver),
            ``"safe"`` (second impulse by ``Xi <= 0``), ``"tau"`` (second impulse by
            ``Xi_tau <= 0``) or ``"manual"``.
        index: 1-based jump count.
        x_before: State before, shape (n,).
        x_after: State after, shape (n,).
        v: Control input of the jump, shape (m,).
        h_before: Barrier before.
        h_after: Barrier after.
        xi_before: Trigger value before.
        xi_after: Trigger value after (>= c by the run-time check).
        interval_s: Time since the previous jump (or since the start for the first) [s].

    """

    t: float
    kind: str
    index: int
    x_before: np.ndarray
    x_after: np.ndarray
    v: np.ndarray
    h_before: float
    h_after: float
    xi_before: float
    xi_after: float
    interval_s: float


class EventTriggeredImpulsiveController:
    """Greedy event-triggered safeguarding impulsive controller (eq. trigger:greedy).

    ``Xi(x) = LF h(x) - |dh/dx| d_bar + alpha(h(x))``; a jump is due at ``Xi <= 0``.

    Args:
        flow_model: ``F(t, x)``, the flow model used by the trigger (e.g. Kepler only), (n,).
        jump_map: ``G(x, v)`` -> (n,).
        barrier: The barrier ``h``.
        controller: Safeguarding controller ``K(t, x)`` -> v.
        alpha: Class-K function or linear gain.
        c: Post-jump margin, > 0.
        d_bar: Flow disturbance bound used in ``Xi``, >= 0.
        tol: Slack allowed in the post-jump checks (round-off), >= 0.
        zeno: Zeno guard (default: stop when 50 jumps fall within 1e-6 s... see ZenoGuard).
        t0: Start time [s].
        extra: Further barriers the jump must keep, each ``(barrier, c_i)``: the same flow model,
            class-K function and ``d_bar``, its own post-jump margin ``c_i > 0``. Every jump is
            checked against all of them as against ``barrier`` (``h_i(x+) >= 0``,
            ``Xi_i(x+) >= c_i``); the controller ``K`` must meet them (e.g. a filter of the
            nominal impulse).

    """

    def __init__(
        self,
        flow_model: FlowFn,
        jump_map: JumpFn,
        barrier: Barrier,
        controller: ControlFn,
        alpha: ClassK | float | Callable[[float], float],
        c: float,
        d_bar: float = 0.0,
        *,
        tol: float = 1e-9,
        zeno: ZenoGuard | None = None,
        t0: float = 0.0,
        extra: Sequence[tuple[Barrier, float]] = (),
    ) -> None:
        for nm, fn in (("flow_model", flow_model), ("jump_map", jump_map), ("controller", controller)):
            if not callable(fn):
                raise ConfigError(f"{nm} must be callable")
        if not isinstance(barrier, Barrier):
            raise ConfigError(f"barrier must be an isf_robot.core.Barrier, got {type(barrier).__name__}")
        self.flow_model = flow_model
        self.jump_map = jump_map
        self.barrier = barrier
        self.controller = controller
        self.alpha = as_class_k(alpha)
        self.c = check_positive(c, "c (post-jump margin)")
        self.d_bar = check_nonnegative(d_bar, "d_bar (disturbance bound)")
        self.tol = check_nonnegative(tol, "tol")
        self.zeno = zeno if zeno is not None else ZenoGuard()
        self.extra: list[tuple[Barrier, float]] = []
        for b, ci in extra:
            if not isinstance(b, Barrier):
                raise ConfigError(f"extra barriers must be isf_robot.core.Barrier, got {type(b).__name__}")
            self.extra.append((b, check_positive(ci, f"c of barrier {getattr(b, 'name', '?')!r}")))
        self.reset(t0)

    def reset(self, t0: float = 0.0) -> None:
        """Forget jump history."""
        self.t_last = check_finite_scalar(t0, "t0")
        self.jumps: list[JumpEvent] = []
        self.zeno.reset()

    # -- trigger values ------------------------------------------------------------------
    def lie_derivative(self, t: float, x: np.ndarray) -> float:
        """``LF h(x) = dh/dx F(x) + dh/dt`` along the flow model."""
        flow = np.asarray(self.flow_model(t, x), dtype=float)
        return dot(self.barrier.gradient(x, t), flow) + float(self.barrier.time_derivative(x, t))

    def xi(self, t: float, x: np.ndarray, barrier: Barrier | None = None) -> float:
        """Greedy trigger value ``Xi(x)`` (eq. greedy_cond) of ``barrier`` (default the main one); due when ``<= 0``."""
        b = self.barrier if barrier is None else barrier
        grad = b.gradient(x, t)
        lfh = dot(grad, np.asarray(self.flow_model(t, x), dtype=float)) + b.time_derivative(x, t)
        return xi_on_scalar(lfh, 0.0, norm(grad), b.value(x, t), self.alpha, self.d_bar)

    # -- the jump ------------------------------------------------------------------------
    def apply_jump(self, t: float, x: np.ndarray, kind: str = "greedy") -> JumpEvent:
        """Apply ``x+ = G(x, K(x))`` at time ``t`` and check the post-jump conditions.

        Raises:
            PostJumpConditionError: ``h(x+) < 0`` or ``Xi(x+) < c`` (beyond ``tol``).
            ZenoError: The Zeno guard fired.

        """
        t = check_finite_scalar(t, "t")
        x = as_vector(x, "state x")
        v = np.atleast_1d(np.asarray(self.controller(t, x), dtype=float))
        if not np.all(np.isfinite(v)):
            raise PostJumpConditionError(
                f"safeguarding controller returned a non-finite input at t={t:.6g}: {v}",
                t=t, x_before=x, x_after=x, h_after=float("nan"), xi_after=float("nan"), c=self.c,
            )
        x_after = np.asarray(self.jump_map(x, v), dtype=float)
        h_before = self.barrier.value(x, t)
        xi_before = self.xi(t, x)
        h_after = self.barrier.value(x_after, t)
        xi_after = self.xi(t, x_after)
        if not (h_after >= -self.tol and xi_after >= self.c - self.tol):
            raise PostJumpConditionError(
                f"safeguarding controller broke the post-jump condition at t={t:.6g}: "
                f"h(G(x,K(x))) = {h_after:.6g} (needs >= 0), Xi(G(x,K(x))) = {xi_after:.6g} "
                f"(needs >= c = {self.c:.6g})",
                t=t, x_before=x, x_after=x_after, h_after=h_after, xi_after=xi_after, c=self.c,
            )
        for b, ci in self.extra:
            hb, xb = b.value(x_after, t), self.xi(t, x_after, b)
            if not (hb >= -self.tol and xb >= ci - self.tol):
                raise PostJumpConditionError(
                    f"safeguarding controller broke the post-jump condition of barrier "
                    f"{getattr(b, 'name', '?')!r} at t={t:.6g}: h = {hb:.6g} (needs >= 0), Xi = {xb:.6g} "
                    f"(needs >= c = {ci:.6g})",
                    t=t, x_before=x, x_after=x_after, h_after=hb, xi_after=xb, c=ci,
                )
        interval = t - self.t_last
        self.zeno.record(t, interval)
        ev = JumpEvent(t, kind, len(self.jumps) + 1, x, x_after, v, h_before, h_after, xi_before, xi_after, interval)
        self.jumps.append(ev)
        self.t_last = t
        return ev

    @property
    def inter_event_times(self) -> np.ndarray:
        """Intervals between successive jumps [s] (the first jump's interval from the start excluded)."""
        return np.array([j.interval_s for j in self.jumps[1:]])


class ManeuverScheduler:
    """Two-impulse safety maneuvers (paper, Section IV, eq. trigger:int_time).

    The first impulse of each maneuver fires by the greedy trigger ``Xi <= 0``. The second
    fires at ``min(t_safe, t_tau)``: ``t_safe`` is the greedy trigger again, ``t_tau`` the first
    ``t >= t_first + tau_p(h(x(t_first)))`` with ``Xi_tau(x) = (1 + tau_p'(h) LF h) / 2 <= 0``.
    Here ``x(t_first)`` is the state right after the first impulse. Then the next first impulse.

    Args:
        controller: The greedy controller (owns the flow model, jump and checks).
        tau_p: Fitted expected inter-event time ``tau_p(h)`` [s].
        dtau_p_dh: Its derivative ``d tau_p / dh`` [s per unit of h].

    """

    def __init__(
        self,
        controller: EventTriggeredImpulsiveController,
        tau_p: Callable[[float], float],
        dtau_p_dh: Callable[[float], float],
    ) -> None:
        if not callable(tau_p) or not callable(dtau_p_dh):
            raise ConfigError("tau_p and dtau_p_dh must be callables of h")
        self.controller = controller
        self.tau_p = tau_p
        self.dtau_p_dh = dtau_p_dh
        self.phase = "first"
        self.gate_time: float | None = None

    def reset(self) -> None:
        """Start again with a first impulse."""
        self.phase = "first"
        self.gate_time = None

    def xi(self, t: float, x: np.ndarray) -> float:
        """Greedy trigger (both phases)."""
        return self.controller.xi(t, x)

    def xi_tau(self, t: float, x: np.ndarray) -> float:
        """Maneuver trigger ``Xi_tau`` (meaningful in the second phase after ``gate_time``)."""
        h = self.controller.barrier.value(x, t)
        return xi_tau(float(self.dtau_p_dh(h)), self.controller.lie_derivative(t, x))

    def apply_jump(self, t: float, x: np.ndarray, kind: str) -> JumpEvent:
        """Apply the jump fired by ``kind`` and advance the phase.

        Args:
            t: Time [s].
            x: State before the jump.
            kind: ``"greedy"`` in the first phase; ``"safe"`` or ``"tau"`` in the second.

        """
        if self.phase == "first" and kind != "greedy":
            raise ConfigError(f"first impulse of a maneuver must be 'greedy', got {kind!r}")
        if self.phase == "second" and kind not in ("safe", "tau"):
            raise ConfigError(f"second impulse of a maneuver must be 'safe' or 'tau', got {kind!r}")
        if kind == "tau" and (self.gate_time is None or t < self.gate_time - 1e-9):
            raise ConfigError(f"tau impulse at t={t} before its gate time {self.gate_time}")
        ev = self.controller.apply_jump(t, x, kind)
        if self.phase == "first":
            tp = float(self.tau_p(ev.h_after))
            if not np.isfinite(tp):
                raise ConfigError(f"tau_p({ev.h_after:.6g}) is not finite")
            self.gate_time = t + max(tp, 0.0)
            self.phase = "second"
        else:
            self.gate_time = None
            self.phase = "first"
        return ev
