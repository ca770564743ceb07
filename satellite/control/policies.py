"""Trigger policies (paper, eqs. trigger:greedy and trigger:int_time): what each trigger does in a run.

One policy per :class:`satellite.control.triggers.Trigger`: which events each arc of the integration
watches and which impulse a fired event applies. The integration of one arc is
:class:`satellite.orbit.arcs.ArcIntegrator`; the loop that calls :meth:`TriggerPolicy.step` until the
end time is :func:`satellite.orbit.simulate.simulate`.

* ``none``: no control; one arc that stops when the satellite first leaves the band (``h = 0``
  falling), whose time is reported (the series gravity model is not meant for deep inside).
* ``greedy``: event ``Xi = 0`` (falling), then ``x+ = G(x, K(x))``; with the surface barrier
  (:mod:`satellite.control.surface_barrier`) also ``Xi_s = 0`` (falling), a ``surface`` impulse.
* ``periodic`` (the baseline of traditional station keeping): an impulse ``x+ = G(x, K(x))``
  every ``period_s`` whatever ``Xi``; each arc stops at the first band exit (``h = 0`` falling),
  which ends the run and is reported (an impulse cannot bring a satellite outside the band back:
  it changes the velocity only, so ``h(x+) = h(x) < 0`` would break the post-jump condition).
* ``maneuver``: first impulse by ``Xi``; then integrate to the gate ``t_first + tau_p(h(x+))``
  with the ``Xi`` event only (a ``safe`` second impulse if it fires first), then enable
  ``Xi_tau = (1 + tau_p'(h) LF h) / 2`` (a ``tau`` second impulse at the gate itself when
  ``Xi_tau <= 0`` there).

Every arc also watches the apsis event (``r . v = 0``, non-terminal), so the reported radius
range is that of the trajectory, not of the step points.

**Practical minimum inter-impulse interval** (time regularisation; issue 14, item 4): an impulse
fired by ``Xi`` (``greedy``, a maneuver's first or ``safe`` impulse) less than ``min_interval_s``
after the previous impulse is **held**: the flow goes on, watched for ``h`` falling to the band's
edge, until the interval has passed; then the impulse fires if ``Xi <= 0`` still (otherwise the
run goes on watching ``Xi``). A hold that would let the satellite leave the band is cut short:
the impulse fires when ``h`` falls to ``1e-6 h_max`` (inside the band, where the controller meets
both post-jump conditions), or the surface barrier's ``h_s`` to 1 mm, an **override** of the
interval. Holds and overrides are counted (:attr:`TriggerPolicy.holds`,
:attr:`TriggerPolicy.hold_overrides`). The default,
:data:`MIN_INTERVAL_S` = 60 s, never binds in the paper's setting (the shortest interval measured
in default 2400 h runs is minutes: REPRODUCTION.md) and lies above the sampled MIET estimate
(~10 s), so it is what keeps a run from crowding impulses when the estimate's assumptions fail,
long before the core's Zeno guard (20 impulses within 1 us) would stop it; a minute is also the
order of a small spacecraft's thruster cycle.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from isf_robot.core import ConfigError, EventTriggeredImpulsiveController, JumpEvent, ManeuverScheduler
from isf_robot.core.class_k import Linear
from satellite.control.triggers import RDOT, XI, XITAU, BandTriggers, H, Trigger
from satellite.orbit.arcs import ArcIntegrator
from satellite.orbit.events import event

__all__ = [
    "TriggerPolicy", "NoControl", "Greedy", "Maneuver", "Periodic", "make_policy", "MIN_INTERVAL_S",
]

MIN_INTERVAL_S = 60.0
"""Default practical minimum interval between impulses [s] (see the module docstring)."""

_EDGE = 1e-6
"""A hold ends when ``h`` falls to this fraction of ``h_max`` (inside the band)."""

_EDGE_S = 1e-3
"""... or when the surface barrier's ``h_s`` falls to this many metres."""

Step = tuple[float, NDArray[np.float64], bool]
"""``(t, y, finished)`` after one policy step."""


class TriggerPolicy:
    """What one trigger does between impulses; :meth:`step` advances the run by one arc.

    Args:
        trig: The band trigger values.
        ctrl: The core impulsive controller (post-jump checks, jump history).
        arc: Integrates one arc (:class:`satellite.orbit.arcs.ArcIntegrator`).
        on_jump: Called with every applied impulse (the observers' ``on_event``).
        tau: Fitted ``tau_p`` (used by ``maneuver`` only).

    Attributes:
        trigger: The trigger this policy implements.
        first_phase: Phase label of the run's first sample.
        left_band_s: First time outside the band [s] (``none`` only; ``None`` otherwise).
        min_interval_s: Practical minimum interval between impulses [s] (0: none).
        holds: Impulses due by ``Xi`` sooner than ``min_interval_s`` after the previous one.
        hold_overrides: Holds ended early at the band's edge.

    """

    trigger: Trigger
    first_phase: str

    def __init__(
        self,
        trig: BandTriggers,
        ctrl: EventTriggeredImpulsiveController,
        arc: ArcIntegrator,
        on_jump: Callable[[JumpEvent], None],
        tau: Any = None,
    ) -> None:
        self.trig = trig
        self.ctrl = ctrl
        self.arc = arc
        self.on_jump = on_jump
        self.left_band_s: float | None = None
        self.min_interval_s = 0.0
        self.holds = 0
        self.hold_overrides = 0
        self.rates = trig.rates()
        self.xi_ev = event(trig.xi, True, -1.0, self.rates["xi"], trig.xi_batch, _xi_code(trig))
        self.apsis_ev = event(trig.r_dot, False, 0.0, self.rates["apsis"], trig.r_dot_batch, (RDOT, 0.0, None))
        self.fire_evs = [self.xi_ev]  # + the surface barrier's Xi_s (set_surface)
        self.surface_fires = 0
        edge = trig.h_max * _EDGE

        def near_edge(s: float, x: NDArray[np.float64]) -> float:
            return trig.h(s, x) - edge

        def near_edge_batch(s: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
            return trig.h_batch(s, x) - edge

        self.edge_evs = [event(near_edge, True, -1.0, self.rates["h"], near_edge_batch, (H, edge, None))]  # ends a hold

    def set_surface(self, strig: Any) -> None:
        """Watch the surface barrier's ``Xi_s`` too (:class:`satellite.control.surface_barrier.SurfaceTriggers`).

        Its falling zero fires an impulse (the run's controller keeps both barriers): of kind
        ``surface`` for ``greedy``; for ``maneuver`` wherever ``Xi`` would fire one (a first
        ``greedy`` or a ``safe`` second impulse), counted in :attr:`surface_fires`.

        Raises:
            ConfigError: The trigger is neither ``greedy`` nor ``maneuver``.

        """
        if self.trigger not in (Trigger.GREEDY, Trigger.MANEUVER):
            raise ConfigError(f"the surface barrier works with the greedy and maneuver triggers, not {self.trigger}")
        scan = self.trig.accel_bound is not None
        self.fire_evs = [self.xi_ev, event(strig.xi, True, -1.0, strig.xi_rate if scan else None, strig.xi_batch)]

        def near(s: float, x: NDArray[np.float64]) -> float:
            return strig.h(s, x) - _EDGE_S

        def near_batch(s: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
            return strig.h_batch(s, x) - _EDGE_S

        self.edge_evs = [self.edge_evs[0], event(near, True, -1.0, strig.h_rate if scan else None, near_batch)]

    def step(self, t: float, y: NDArray[np.float64], t_end: float) -> Step:
        """Integrate from ``(t, y)`` to the next impulse (applied) or to ``t_end`` [s]."""
        raise NotImplementedError

    def _jump(self, t: float, y: NDArray[np.float64], kind: str) -> NDArray[np.float64]:
        ev = self.ctrl.apply_jump(t, y, kind)
        self.on_jump(ev)
        return ev.x_after

    def _hold(self, t: float, y: NDArray[np.float64], t_end: float, phase: str) -> Step:
        """Hold an impulse due by ``Xi`` at ``(t, y)`` until ``min_interval_s`` has passed (module docstring).

        Returns:
            ``(t, y, fire)``: where the hold ended and whether the impulse fires there.

        """
        if not self.ctrl.jumps or t >= self.ctrl.t_last + self.min_interval_s:
            return t, y, True
        self.holds += 1
        edges = self.edge_evs
        sol = self.arc(t, min(self.ctrl.t_last + self.min_interval_s, t_end), y, [*edges, self.apsis_ev], phase, None)
        if sol.status == 1:
            self.hold_overrides += 1
            i = _first(sol, range(len(edges)))
            return float(sol.t_events[i][0]), sol.y_events[i][0], True
        t, y = float(sol.t[-1]), sol.y[:, -1]
        return t, y, t < t_end and min(float(e.fn(t, y)) for e in self.fire_evs) <= 0.0

    def _fire_arc(self, t: float, arc_end: float, y: NDArray[np.float64], t_end: float, phase: str,
                  kinds: tuple[str, str]) -> tuple[float, NDArray[np.float64], bool]:
        """One arc to the first falling zero of ``Xi`` (or ``Xi_s``) before ``arc_end``, held and fired.

        ``kinds`` names the impulse fired by ``Xi`` and by ``Xi_s``. Returns ``(t, y, stopped)``:
        ``stopped`` when an event ended the arc (whether or not the hold let the impulse fire).
        """
        fire = self.fire_evs
        sol = self.arc(t, arc_end, y, [*fire, self.apsis_ev], phase, None)
        t, y = float(sol.t[-1]), sol.y[:, -1]
        if sol.status != 1:
            return t, y, False
        i = _first(sol, range(len(fire)))
        t, y, due = self._hold(float(sol.t_events[i][0]), sol.y_events[i][0], t_end, phase)
        if due:
            self.surface_fires += i
            y = self._jump(t, y, kinds[i])
        return t, y, True


class NoControl(TriggerPolicy):
    """``none``: one arc, stopped when ``h`` falls through 0."""

    trigger = Trigger.NONE
    first_phase = "none"

    def step(self, t: float, y: NDArray[np.float64], t_end: float) -> Step:
        """One arc to ``t_end`` or to the band exit; the run then ends."""
        exit_ev = event(self.trig.h, True, -1.0, self.rates["h"], self.trig.h_batch, (H, 0.0, None))
        sol = self.arc(t, t_end, y, [exit_ev, self.apsis_ev], "none", None)
        if sol.status == 1:
            self.left_band_s = float(sol.t_events[0][0])
        return float(sol.t[-1]), y, True


class Greedy(TriggerPolicy):
    """``greedy``: an impulse at every falling zero of ``Xi``."""

    trigger = Trigger.GREEDY
    first_phase = "greedy"

    def step(self, t: float, y: NDArray[np.float64], t_end: float) -> Step:
        """One arc to the next ``Xi = 0`` (impulse applied) or to ``t_end``."""
        t, y, _ = self._fire_arc(t, t_end, y, t_end, "greedy", ("greedy", "surface"))
        return t, y, False


class Maneuver(TriggerPolicy):
    """``maneuver``: first impulse by ``Xi``, second by ``Xi`` (``safe``) or, after the gate, ``Xi_tau``."""

    trigger = Trigger.MANEUVER
    first_phase = "first"

    def __init__(
        self,
        trig: BandTriggers,
        ctrl: EventTriggeredImpulsiveController,
        arc: ArcIntegrator,
        on_jump: Callable[[JumpEvent], None],
        tau: Any = None,
    ) -> None:
        super().__init__(trig, ctrl, arc, on_jump, tau)
        if tau is None:
            raise ConfigError("the maneuver trigger needs a fitted tau_p (make one with `isf-satellite tau`)")
        self.sched = ManeuverScheduler(self.ctrl, tau.tau_p, tau.dtau_dh)
        self.xi_tau = self.trig.xi_tau_fn(tau.dtau_dh)
        self.xi_tau_ev = event(self.xi_tau, True, -1.0, _xi_tau_rate(trig, tau), code=(XITAU, 0.0, tau))

    def _jump(self, t: float, y: NDArray[np.float64], kind: str) -> NDArray[np.float64]:
        ev = self.sched.apply_jump(t, y, kind)
        self.on_jump(ev)
        return ev.x_after

    def step(self, t: float, y: NDArray[np.float64], t_end: float) -> Step:
        """One arc of the current phase; at most one impulse."""
        sched = self.sched
        fire = self.fire_evs  # Xi (and Xi_s with the surface barrier)
        if sched.phase == "first":
            t, y, _ = self._fire_arc(t, t_end, y, t_end, "first", ("greedy", "greedy"))
            return t, y, False
        gate = float(sched.gate_time)  # type: ignore[arg-type]
        if t < gate:
            t, y, stopped = self._fire_arc(t, min(gate, t_end), y, t_end, "second", ("safe", "safe"))
            if stopped:
                return t, y, False
            if t >= t_end:
                return t, y, True
            t = gate
        at_gate = self.xi_tau(t, y)
        self.arc.track.note_xi_tau(at_gate)
        if at_gate <= 0.0:
            return t, self._jump(t, y, "tau"), False
        evs = [self.xi_ev, self.xi_tau_ev, *fire[1:], self.apsis_ev]  # Xi, Xi_tau, (Xi_s)
        sol = self.arc(t, t_end, y, evs, "second-gated", self.xi_tau)
        t, y = float(sol.t[-1]), sol.y[:, -1]
        if sol.status == 1:
            i = _first(sol, range(len(evs) - 1))
            t, y = float(sol.t_events[i][0]), sol.y_events[i][0]
            due = True
            if i != 1:
                t, y, due = self._hold(t, y, t_end, "second-gated")
            if due:
                self.surface_fires += i == 2
                y = self._jump(t, y, "tau" if i == 1 else "safe")
        return t, y, False


def _xi_code(trig: BandTriggers) -> tuple[int, float, Any] | None:
    """The compiled form of ``Xi`` (:mod:`satellite.orbit.fast_arcs`): for a linear class-K function only."""
    return (XI, 0.0, None) if isinstance(trig.alpha, Linear) else None


def _first(sol: Any, indices: Any) -> int:
    """The index among ``indices`` of the event that stopped the arc (the earliest located)."""
    return min((k for k in indices if len(sol.t_events[k])), key=lambda k: float(sol.t_events[k][0]))


def _xi_tau_rate(trig: BandTriggers, tau: Any) -> Any:
    """Rate bound of ``Xi_tau`` for a polynomial fit ``tau_p(h) = sum_k a_k s^k``, ``s = h / h_max``.

    On ``s`` in [0, 1] (``tau_p'`` is held constant outside), ``|tau_p'| <= sum_k k |a_k| / h_max``
    and ``|tau_p''| <= sum_k k (k - 1) |a_k| / h_max^2``. ``None`` (step points only) without
    acceleration bound or for a fit that is not such a polynomial.
    """
    bounds = getattr(tau, "slope_bounds", None)
    if trig.accel_bound is None or bounds is None:
        return None
    d1, d2 = bounds
    return trig.xi_tau_rate(d1, d2)


class Periodic(TriggerPolicy):
    """``periodic``: an impulse every ``period_s`` (set by :func:`make_policy`), stopped at a band exit.

    With ``at_start`` the first impulse comes at the run's start (an insertion impulse, as station
    keeping starts on a designed orbit), else after the first period.
    """

    trigger = Trigger.PERIODIC
    first_phase = "periodic"
    period_s = float("nan")
    at_start = False

    def step(self, t: float, y: NDArray[np.float64], t_end: float) -> Step:
        """One arc to the next impulse time (impulse applied), to ``t_end`` or to the band exit (run ends)."""
        if self.at_start and not self.ctrl.jumps and t < t_end:
            y = self._jump(t, y, "periodic")
        exit_ev = event(self.trig.h, True, -1.0, self.rates["h"], self.trig.h_batch, (H, 0.0, None))
        t_next = min(t + self.period_s, t_end)
        sol = self.arc(t, t_next, y, [exit_ev, self.apsis_ev], "periodic", None)
        if sol.status == 1:
            self.left_band_s = float(sol.t_events[0][0])
            return self.left_band_s, sol.y_events[0][0], True
        t, y = float(sol.t[-1]), sol.y[:, -1]
        if t < t_end:
            y = self._jump(t, y, "periodic")
        return t, y, False


_POLICIES: dict[Trigger, type[TriggerPolicy]] = {p.trigger: p for p in (NoControl, Greedy, Maneuver, Periodic)}


def make_policy(
    trigger: Trigger,
    trig: BandTriggers,
    ctrl: EventTriggeredImpulsiveController,
    arc: ArcIntegrator,
    on_jump: Callable[[JumpEvent], None],
    tau: Any = None,
    period_s: float | None = None,
    min_interval_s: float = MIN_INTERVAL_S,
    at_start: bool = False,
) -> TriggerPolicy:
    """The policy of ``trigger`` (arguments as for :class:`TriggerPolicy`; ``period_s`` for ``periodic``).

    ``min_interval_s`` is the practical minimum interval between impulses [s] (module docstring);
    ``at_start``: the periodic trigger's first impulse at the start (:class:`Periodic`).
    """
    policy = _POLICIES[trigger](trig, ctrl, arc, on_jump, tau)
    policy.min_interval_s = float(min_interval_s)
    if isinstance(policy, Periodic):
        if period_s is None or not (np.isfinite(period_s) and period_s > 0):
            raise ConfigError(f"the periodic trigger needs a period > 0 (hours), got {period_s}")
        policy.period_s = float(period_s)
        policy.at_start = bool(at_start)
    elif at_start:
        raise ConfigError(f"an impulse at the start goes with the periodic trigger only, not {trigger}")
    return policy
