"""Closed-loop orbit runs: no control, the greedy trigger, or two-impulse maneuvers.

The truth flow (spherical harmonics, spinning body) is integrated by ``scipy.integrate.solve_ivp``
(DOP853) once per inter-event arc, with terminal events for the triggers, so every impulse is
applied at a located event and no integration step straddles an impulse:

* ``greedy`` (paper, eq. trigger:greedy): event ``Xi = 0`` (falling), then ``x+ = G(x, K(x))``.
* ``maneuver`` (paper, eq. trigger:int_time): first impulse by ``Xi``; then integrate to the
  gate ``t_first + tau_p(h(x+))`` with the ``Xi`` event only (a ``safe`` second impulse if it
  fires first), then enable ``Xi_tau = (1 + tau_p'(h) LF h) / 2`` (a ``tau`` second impulse at
  the gate itself when ``Xi_tau <= 0`` there).
* ``none``: no control; the run stops when the satellite first leaves the band (``h = 0``
  falling), whose time is reported (the series gravity model is not meant for deep inside).

A non-terminal event at ``r . v = 0`` locates every apsis, so the reported radius range and
``min_h`` are the extremes of the trajectory, not of the step points.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from isf_robot.core import (
    ConfigError,
    IsfError,
    JumpEvent,
    Linear,
    ManeuverScheduler,
    Observer,
    Observers,
    UnknownNameError,
    estimate_miet_constants,
)
from satellite.controller import ControlParams, FastTriggers, ResolvedControl, make_controller, resolve_control
from satellite.model import BAND_INNER, BAND_OUTER, InitialOrbit, OrbitModel
from satellite.surface import SurfaceCheck, SurfaceModel

__all__ = [
    "TRIGGERS",
    "IntegratorSettings",
    "SatelliteSample",
    "RunResult",
    "SimulationError",
    "simulate",
    "miet_estimate",
]

TRIGGERS = ("none", "greedy", "maneuver")
"""Trigger names accepted by :func:`simulate`."""


class SimulationError(IsfError):
    """The integrator failed (e.g. step size underflow)."""


@dataclass(frozen=True)
class IntegratorSettings:
    """``solve_ivp`` settings (SI units).

    Attributes:
        rtol: Relative tolerance.
        atol: Absolute tolerance.
        max_step_s: Largest step [s] (default 1200 s, about 1/20 of the 6.65 h period at 2R).

    """

    rtol: float = 1e-10
    atol: float = 1e-12
    max_step_s: float = 1200.0


@dataclass(frozen=True)
class SatelliteSample:
    """One output sample of a run, passed to ``Observer.on_step``.

    Samples are taken at integrator step points, at most one per ``sample_interval_s``.

    Attributes:
        t: Time [s].
        position: Inertial position [m], length 3.
        velocity: Inertial velocity [m/s], length 3.
        r: Radius [m].
        h: Barrier value [m^2].
        xi: Greedy trigger value ``Xi`` [m^2/s].
        xi_tau: Maneuver trigger value (``nan`` unless in the second phase after the gate).
        phase: ``"none"``, ``"greedy"``, or for maneuvers ``"first"``, ``"second"`` (before the
            gate), ``"second-gated"`` (after it).
        body_angle: Body rotation angle [rad].

    """

    t: float
    position: tuple[float, float, float]
    velocity: tuple[float, float, float]
    r: float
    h: float
    xi: float
    xi_tau: float
    phase: str
    body_angle: float


@dataclass(frozen=True)
class RunResult:
    """Outcome of :func:`simulate`.

    Attributes:
        trigger: ``none``, ``greedy`` or ``maneuver``.
        hours: Requested duration [h].
        simulated_h: Duration actually simulated [h] (shorter for ``none`` leaving the band).
        triggers: Number of impulses.
        kinds: Impulse counts by kind (``greedy``, ``safe``, ``tau``).
        min_h: Smallest barrier value over the trajectory [m^2].
        r_min_over_R: Smallest radius [R].
        r_max_over_R: Largest radius [R].
        total_dv: Sum of impulse magnitudes [m/s].
        min_inter_event_h: Shortest interval between impulses [h] (``None`` for < 2 impulses).
        mean_inter_event_h: Mean interval between impulses [h] (``None`` for < 2 impulses).
        miet_bound_h: Sampled MIET bound ``c / (L_Xi (B + d_bar))`` [h].
        left_band_h: First time outside the band [h] (``None`` if it stayed in).
        wall_s: Wall time of the run [s].
        seed: Seed of the initial orbit.
        settings: Resolved settings (JSON-ready).
        events: The impulses.
        nfev: Right-hand-side evaluations.
        surface: Report of the optional surface check (:meth:`satellite.surface.SurfaceCheck.report`),
            ``None`` when the check was off; merged into :meth:`summary` when present.

    """

    trigger: str
    hours: float
    simulated_h: float
    triggers: int
    kinds: dict[str, int]
    min_h: float
    r_min_over_R: float
    r_max_over_R: float
    total_dv: float
    min_inter_event_h: float | None
    mean_inter_event_h: float | None
    miet_bound_h: float
    left_band_h: float | None
    wall_s: float
    seed: int
    settings: dict[str, Any]
    events: tuple[JumpEvent, ...] = field(repr=False)
    nfev: int = 0
    surface: dict[str, Any] | None = None

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary (everything but the event list; the surface keys when checked)."""
        keys = (
            "trigger", "hours", "simulated_h", "triggers", "kinds", "min_h", "r_min_over_R",
            "r_max_over_R", "total_dv", "min_inter_event_h", "mean_inter_event_h", "miet_bound_h",
            "left_band_h", "wall_s", "seed", "nfev", "settings",
        )
        out = {k: getattr(self, k) for k in keys}
        if self.surface is not None:
            out.update(self.surface)
        return out


def miet_estimate(
    model: OrbitModel, resolved: ResolvedControl, samples: int = 2000, seed: int = 0
) -> tuple[float, float, float]:
    """Sampled MIET bound (paper, Proposition 1) on the band with bounded-orbit speeds.

    States are drawn with radius uniform in the band, uniform directions, and speeds up to the
    escape speed at 1.6R; ``L_Xi`` and ``B`` come from :func:`isf_robot.core.estimate_miet_constants`
    (Kepler flow), ``d_bar`` from the largest sampled disturbance over the band.

    Returns:
        ``(bound_s, L_Xi, d_bar_flow)``.

    """
    rng = np.random.default_rng(seed)
    trig = FastTriggers(model, Linear(resolved.alpha_gain), resolved.d_bar)
    v_max = math.sqrt(2.0 * model.mu / (BAND_INNER * model.R))
    u = rng.normal(size=(samples, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    w = rng.normal(size=(samples, 3))
    w /= np.linalg.norm(w, axis=1)[:, None]
    rad = rng.uniform(BAND_INNER, BAND_OUTER, samples) * model.R
    spd = rng.uniform(0.0, v_max, samples)
    states = np.hstack([u * rad[:, None], w * spd[:, None]])
    d_flow = model.disturbance_bound(samples=samples, seed=seed)
    consts = estimate_miet_constants(
        lambda x: trig.xi(0.0, x), lambda x: model.kepler_rhs(0.0, x), states, resolved.c, d_flow
    )
    return consts.bound_s, consts.lipschitz_xi, d_flow


class _Tracker:
    """Running extremes, samples for observers, and progress bookkeeping of one run."""

    def __init__(self, model: OrbitModel, trig: FastTriggers, obs: Observers, interval: float) -> None:
        self.model = model
        self.trig = trig
        self.obs = obs
        self.interval = interval
        self.r_min = math.inf
        self.r_max = -math.inf
        self.t_next = 0.0
        self.nfev = 0

    def radius(self, y: NDArray[np.float64]) -> None:
        r = math.sqrt(float(y[0] ** 2 + y[1] ** 2 + y[2] ** 2))
        self.r_min = min(self.r_min, r)
        self.r_max = max(self.r_max, r)

    def arc(self, sol: Any, phase: str, xi_tau: Callable[[float, NDArray[np.float64]], float] | None) -> None:
        self.nfev += int(sol.nfev)
        ys = sol.y
        r = np.sqrt(ys[0] ** 2 + ys[1] ** 2 + ys[2] ** 2)
        self.r_min = min(self.r_min, float(r.min()))
        self.r_max = max(self.r_max, float(r.max()))
        for evs in sol.y_events:
            for y in evs:
                self.radius(y)
        if not self.obs:
            return
        for k, t in enumerate(sol.t):
            if t + 1e-9 < self.t_next:
                continue
            self.t_next = t + self.interval
            self.emit(float(t), ys[:, k], phase, xi_tau)

    def emit(self, t: float, y: NDArray[np.float64], phase: str, xi_tau: Any) -> None:
        r, h, _ = self.trig.parts(y)
        xt = float(xi_tau(t, y)) if xi_tau is not None else math.nan
        self.obs.on_step(
            SatelliteSample(
                t=t,
                position=(float(y[0]), float(y[1]), float(y[2])),
                velocity=(float(y[3]), float(y[4]), float(y[5])),
                r=r,
                h=h,
                xi=self.trig.xi(t, y),
                xi_tau=xt,
                phase=phase,
                body_angle=self.model.body_phase + self.model.omega * t,
            )
        )


def _event(fn: Callable[[float, NDArray[np.float64]], float], terminal: bool, direction: float) -> Any:
    def ev(t: float, y: NDArray[np.float64]) -> float:
        return fn(t, y)

    ev.terminal = terminal  # type: ignore[attr-defined]
    ev.direction = direction  # type: ignore[attr-defined]
    return ev


def _surface_samples(check: SurfaceCheck, sol: Any, t0: float) -> None:
    """Feed one arc to the surface check: grid multiples of its step, events and both ends."""
    t1 = float(sol.t[-1])
    step = check.step_s
    grid = np.arange(math.ceil(t0 / step), math.floor(t1 / step) + 1) * step
    extra = [t0, t1] + [float(x) for ev in sol.t_events for x in ev]
    times = np.unique(np.concatenate([grid, np.asarray(extra)]))
    times = times[(times >= t0) & (times <= t1)]
    check.add(times, sol.sol(times)[:3].T)


def simulate(
    trigger: str,
    hours: float,
    *,
    initial: InitialOrbit | None = None,
    model: OrbitModel | None = None,
    control: ControlParams | None = None,
    tau: Any = None,
    integrator: IntegratorSettings | None = None,
    observers: Iterable[Observer] = (),
    sample_interval_s: float = 600.0,
    miet_samples: int = 2000,
    surface: SurfaceModel | None = None,
    surface_step_s: float = 10.0,
) -> RunResult:
    """Simulate ``hours`` of orbit with the given trigger.

    Args:
        trigger: ``"none"``, ``"greedy"`` or ``"maneuver"``.
        hours: Duration [h], >= 0.
        initial: Initial orbit (default :class:`InitialOrbit` with seed 0).
        model: Orbit model; default the Itokawa degree-8 field with spin. Its body phase is
            replaced by the initial orbit's.
        control: Trigger settings (defaults in :class:`ControlParams`).
        tau: Fitted ``tau_p`` (a :class:`satellite.tau.TauFit`), needed for ``maneuver``.
        integrator: ``solve_ivp`` settings.
        observers: Core observers: ``on_start(info)``, ``on_step(SatelliteSample)`` every
            ``sample_interval_s``, ``on_event(JumpEvent)``, ``on_finish(summary)``.
        sample_interval_s: Spacing of the samples sent to observers [s], > 0.
        miet_samples: Samples for the MIET bound.
        surface: Shape model for the optional surface check (off when ``None``, as in the paper,
            which ignores impact). When given, each arc keeps the integrator's dense output
            (same steps, so the same trajectory), which is sampled every ``surface_step_s`` and
            at every located event, turned into the body frame and checked against the shape
            (:class:`satellite.surface.SurfaceCheck`); the report lands in ``RunResult.surface``.
        surface_step_s: Sampling interval of the surface check [s], > 0.

    Returns:
        The :class:`RunResult`.

    Raises:
        UnknownNameError: Unknown trigger.
        ConfigError: Bad duration, missing ``tau`` for maneuvers, initial state outside the band.
        PostJumpConditionError: The controller broke ``h(x+) >= 0`` or ``Xi(x+) >= c``.
        SimulationError: The integrator failed.

    """
    wall0 = time.perf_counter()
    if trigger not in TRIGGERS:
        raise UnknownNameError("trigger", trigger, TRIGGERS)
    if isinstance(hours, bool) or not isinstance(hours, (int, float)) or not math.isfinite(hours) or hours < 0:
        raise ConfigError(f"hours must be a finite number >= 0, got {hours!r}")
    if not (math.isfinite(sample_interval_s) and sample_interval_s > 0):
        raise ConfigError(f"sample_interval_s must be positive, got {sample_interval_s}")
    if trigger == "maneuver" and tau is None:
        raise ConfigError("the maneuver trigger needs a fitted tau_p (make one with `isf-satellite tau`)")
    initial = initial or InitialOrbit()
    base = model or OrbitModel()
    model = base.with_phase(initial.body_phase())
    resolved = resolve_control(model, control)
    integ = integrator or IntegratorSettings()
    ctrl = make_controller(model, resolved)
    trig = FastTriggers(model, ctrl.alpha, resolved.d_bar)
    obs = Observers(observers)
    track = _Tracker(model, trig, obs, sample_interval_s)
    miet_s, _, _ = miet_estimate(model, resolved, samples=miet_samples)
    check = SurfaceCheck(surface, model.body_phase, model.omega, surface_step_s) if surface is not None else None

    y = initial.state(model)
    t = 0.0
    t_end = hours * 3600.0
    h0 = trig.h(0.0, y)
    if h0 < 0.0:
        raise ConfigError(f"initial state is outside the band (h = {h0:.4g})")
    settings = {
        "alpha_gain": resolved.alpha_gain,
        "c": resolved.c,
        "d_bar": resolved.d_bar,
        "min_post_jump_xi": resolved.min_post_jump_xi,
        "spin": model.spin,
        "spin_period_h": model.spin_period_h,
        "gravity_degree": model.field.degree,
        "disturbance_scale": model.disturbance_scale,
        "R_m": model.R,
        "mu": model.mu,
        "inclination_deg": initial.inclination_deg,
        "radius_over_R": initial.radius_over_R,
        "speed_factor": initial.speed_factor,
        "rtol": integ.rtol,
        "atol": integ.atol,
        "max_step_s": integ.max_step_s,
    }
    if tau is not None:
        settings["tau"] = tau.describe()
    obs.on_start({"trigger": trigger, "hours": hours, "seed": initial.seed, "x0": y.tolist(), **settings})
    track.radius(y)
    if obs:
        track.emit(0.0, y, "first" if trigger == "maneuver" else trigger, None)

    xi_ev = _event(trig.xi, True, -1.0)
    apsis_ev = _event(trig.r_dot, False, 0.0)
    left_band: float | None = None
    sched = ManeuverScheduler(ctrl, tau.tau_p, tau.dtau_dh) if trigger == "maneuver" else None
    xi_tau_fn = trig.xi_tau_fn(tau.dtau_dh) if tau is not None else None
    xi_tau_ev = _event(xi_tau_fn, True, -1.0) if xi_tau_fn is not None else None

    def arc(t0: float, t1: float, y0: NDArray[np.float64], events: list[Any], phase: str, xt: Any) -> Any:
        sol = solve_ivp(
            model.truth_rhs, (t0, t1), y0, method="DOP853", rtol=integ.rtol, atol=integ.atol,
            max_step=integ.max_step_s, events=events, dense_output=check is not None,
        )
        if sol.status == -1:
            raise SimulationError(f"integration failed at t = {sol.t[-1] / 3600:.4g} h: {sol.message}")
        track.arc(sol, phase, xt)
        if check is not None:
            _surface_samples(check, sol, t0)
        return sol

    def jump(t_j: float, y_j: NDArray[np.float64], kind: str) -> NDArray[np.float64]:
        ev = sched.apply_jump(t_j, y_j, kind) if sched is not None else ctrl.apply_jump(t_j, y_j, kind)
        obs.on_event(ev)
        return ev.x_after

    while t < t_end:
        if trigger == "none":
            h_ev = _event(trig.h, True, -1.0)
            sol = arc(t, t_end, y, [h_ev, apsis_ev], "none", None)
            if sol.status == 1:
                left_band = float(sol.t_events[0][0]) / 3600.0
            t = float(sol.t[-1])
            break
        if sched is None or sched.phase == "first":
            sol = arc(t, t_end, y, [xi_ev, apsis_ev], "greedy" if sched is None else "first", None)
            t, y = float(sol.t[-1]), sol.y[:, -1]
            if sol.status == 1:
                t, y = float(sol.t_events[0][0]), sol.y_events[0][0]
                y = jump(t, y, "greedy")
            continue
        gate = float(sched.gate_time)  # type: ignore[arg-type]
        if t < gate:
            sol = arc(t, min(gate, t_end), y, [xi_ev, apsis_ev], "second", None)
            t, y = float(sol.t[-1]), sol.y[:, -1]
            if sol.status == 1:
                t, y = float(sol.t_events[0][0]), sol.y_events[0][0]
                y = jump(t, y, "safe")
                continue
            if t >= t_end:
                break
            t = gate
        if xi_tau_fn(t, y) <= 0.0:  # type: ignore[misc]
            y = jump(t, y, "tau")
            continue
        sol = arc(t, t_end, y, [xi_ev, xi_tau_ev, apsis_ev], "second-gated", xi_tau_fn)
        t, y = float(sol.t[-1]), sol.y[:, -1]
        if sol.status == 1:
            fired = [i for i in (0, 1) if len(sol.t_events[i])]
            i = min(fired, key=lambda k: float(sol.t_events[k][0]))
            t, y = float(sol.t_events[i][0]), sol.y_events[i][0]
            y = jump(t, y, "safe" if i == 0 else "tau")

    jumps = tuple(ctrl.jumps)
    iet = ctrl.inter_event_times / 3600.0
    kinds: dict[str, int] = {}
    for j in jumps:
        kinds[j.kind] = kinds.get(j.kind, 0) + 1
    h_lo = min(model.h_of_r(track.r_min), model.h_of_r(track.r_max))
    result = RunResult(
        trigger=trigger,
        hours=float(hours),
        simulated_h=t / 3600.0,
        triggers=len(jumps),
        kinds=kinds,
        min_h=h_lo,
        r_min_over_R=track.r_min / model.R,
        r_max_over_R=track.r_max / model.R,
        total_dv=float(sum(float(np.linalg.norm(j.v)) for j in jumps)),
        min_inter_event_h=float(iet.min()) if iet.size else None,
        mean_inter_event_h=float(iet.mean()) if iet.size else None,
        miet_bound_h=miet_s / 3600.0,
        left_band_h=left_band,
        wall_s=time.perf_counter() - wall0,
        seed=int(initial.seed),
        settings=settings,
        events=jumps,
        nfev=track.nfev,
        surface=check.report() if check is not None else None,
    )
    obs.on_finish(result.summary())
    return result


def summary_line(result: RunResult) -> Mapping[str, Any]:
    """Short mapping for logs (trigger, triggers, min_h, wall time)."""
    return {"trigger": result.trigger, "triggers": result.triggers, "min_h": result.min_h, "wall_s": result.wall_s}
