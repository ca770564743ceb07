"""Closed-loop orbit runs: no control, the greedy trigger, or two-impulse maneuvers.

:func:`simulate` sets a run up (model with the initial body phase, resolved controller settings,
the sampled MIET figures, observers, the optional surface check), calls its trigger's policy
(:mod:`satellite.control.policies`) arc by arc until the end time, and sums the run up in a
:class:`RunResult`. The arcs themselves are integrated by :class:`satellite.orbit.arcs.ArcIntegrator`.

Observers get, in ``on_start(info)``, the run's settings plus what a viewer needs to draw it
(see :func:`start_info`): band limits, body spin, and the body's triangles (``body_mesh``: the
surface check's mesh, else the shipped shape).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Mapping
from typing import Any

from isf_robot.core import ConfigError, Observer, Observers
from isf_robot.core.sums import norm
from satellite.control.contact import CONTACT_MODES, make_contact
from satellite.control.controller import ControlParams, make_controller, resolve_control
from satellite.control.policies import MIN_INTERVAL_S, make_policy
from satellite.control.shooting import shooting_report
from satellite.control.surface_barrier import add_surface_barrier
from satellite.control.tau import check_tau_controller
from satellite.control.triggers import TRIGGERS, BandTriggers, Trigger
from satellite.control.triggers import H as EV_H
from satellite.orbit.arcs import ArcIntegrator, IntegratorSettings, SatelliteSample, SimulationError, Tracker
from satellite.orbit.events import event
from satellite.orbit.model import BAND_INNER, BAND_OUTER, InitialOrbit, OrbitModel
from satellite.orbit.result import (
    MietReport,
    RunResult,
    contact_report,
    miet_estimate,
    run_settings,
    surface_barrier_report,
)
from satellite.shape.mesh_surface import body_mesh_info, load_surface
from satellite.shape.surface_check import SurfaceCheck
from satellite.shape.surfaces import SurfaceModel

__all__ = [
    "TRIGGERS",
    "Trigger",
    "IntegratorSettings",
    "SatelliteSample",
    "RunResult",
    "SimulationError",
    "simulate",
    "start_info",
    "miet_estimate",
    "MietReport",
    "MIN_INTERVAL_S",
    "SURFACE_STEP_S",
]

SURFACE_STEP_S = 10.0
"""Default sampling interval of the surface check [s] (``surface_step_s``)."""


def start_info(
    trigger: Trigger,
    hours: float,
    initial: InitialOrbit,
    model: OrbitModel,
    x0: Any,
    settings: Mapping[str, Any],
    body_mesh: Mapping[str, Any] | None,
) -> dict[str, Any]:
    """The ``on_start`` information of a run.

    Args:
        trigger: The run's trigger.
        hours: Requested duration [h].
        initial: Initial orbit (its seed is reported).
        model: The run's model (body phase and spin rate).
        x0: Initial state, shape (6,).
        settings: Resolved settings (as in :attr:`RunResult.settings`; includes ``R_m``,
            ``spin_period_h`` and ``mu``).
        body_mesh: The body's triangles (:func:`satellite.shape.mesh_surface.body_mesh_info`), or
            ``None`` (left out).

    Returns:
        ``trigger``, ``hours``, ``seed``, ``x0``, the settings, ``band_over_R`` (inner and outer
        edge [R]), ``body_phase_rad`` (body angle at ``t = 0``), ``omega_rad_s`` (spin rate),
        ``body_shape`` (``"mesh:<name>"`` or ``"ellipsoid"``) and, when given, ``body_mesh``
        (``vertices`` (N, 3) [m] about the centre of mass, ``faces`` (M, 3) int, ``name``).

    """
    info: dict[str, Any] = {"trigger": trigger, "hours": hours, "seed": initial.seed, "x0": list(x0), **settings}
    info["band_over_R"] = [BAND_INNER, BAND_OUTER]
    info["body_phase_rad"] = model.body_phase
    info["omega_rad_s"] = model.omega
    info["body_shape"] = f"mesh:{body_mesh['name']}" if body_mesh is not None else "ellipsoid"
    if body_mesh is not None:
        info["body_mesh"] = dict(body_mesh)
    return info


def simulate(
    trigger: Trigger | str,
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
    surface_step_s: float = SURFACE_STEP_S,
    body_mesh: bool | None = None,
    contact: str = "off",
    contact_surface: SurfaceModel | None = None,
    period_h: float | None = None,
    period_at_start: bool = False,
    min_interval_s: float = MIN_INTERVAL_S,
    surface_barrier: bool = False,
    surface_clearance_m: float = 0.0,
    surface_c: float | None = None,
) -> RunResult:
    """Simulate ``hours`` of orbit with the given trigger.

    Args:
        trigger: A :class:`~satellite.control.triggers.Trigger` or its name (``"none"``, ``"greedy"``,
            ``"maneuver"``, ``"periodic"`` with ``period_h``).
        hours: Duration [h], >= 0.
        initial: Initial orbit (default :class:`InitialOrbit` with seed 0).
        model: Orbit model; default the Itokawa degree-8 field with spin. Its body phase is
            replaced by the initial orbit's.
        control: Trigger settings (defaults in :class:`ControlParams`).
        tau: Fitted ``tau_p`` (a :class:`satellite.control.tau.TauFit`), needed for ``maneuver``.
        integrator: ``solve_ivp`` settings.
        observers: Core observers: ``on_start(info)`` (see :func:`start_info`),
            ``on_step(SatelliteSample)`` every ``sample_interval_s``, ``on_event(JumpEvent)``,
            ``on_finish(summary)``.
        sample_interval_s: Spacing of the samples sent to observers [s], > 0.
        miet_samples: Samples for the MIET bound.
        surface: Shape model for the optional surface check (off when ``None``, as in the paper,
            which ignores impact). When given, each arc keeps the integrator's dense output
            (same steps, so the same trajectory), which is sampled every ``surface_step_s`` and
            at every located event, turned into the body frame and checked against the shape
            (:class:`satellite.shape.surface_check.SurfaceCheck`); the report lands in ``RunResult.surface``.
        surface_step_s: Sampling interval of the surface check [s], > 0.
        body_mesh: Put the body's triangles in the start info (the surface check's mesh, else
            the shipped shape, read once per process); default (``None``) only when observers
            are attached. Never changes the trajectory.
        contact: Surface contact in the dynamics (:mod:`satellite.control.contact`): ``"off"`` (the
            paper), ``"count"`` (contacts counted, the trajectory unchanged) or ``"stop"`` (the run
            ends at the first contact); reported in ``RunResult.contact``.
        contact_surface: The shape for ``contact`` (default: ``surface``, else
            :func:`satellite.shape.mesh_surface.load_surface`).
        period_h: Impulse period [h] of the ``periodic`` trigger.
        period_at_start: ``periodic`` also fires at ``t = 0`` (an insertion impulse), then every ``period_h``.
        min_interval_s: Practical minimum interval between impulses [s], >= 0 (0: none): an
            impulse due by ``Xi`` sooner after the previous one is held until the interval has
            passed, or until ``h`` reaches the band's edge (:mod:`satellite.control.policies`); the result
            counts both. Not applied to the ``periodic`` clock nor to ``tau`` impulses (gated by
            ``tau_p``).
        surface_barrier: Add the surface-clearance barrier (:mod:`satellite.control.surface_barrier`;
            ``greedy`` and ``maneuver``): ``h_s`` = distance outside a smooth envelope of the shape (the
            contact shape, else ``surface``, else the shipped shape) minus
            ``surface_clearance_m``; its trigger ``Xi_s`` fires impulses (``surface`` ones for
            ``greedy``) and every impulse keeps both post-jump conditions. Reported in ``RunResult.surface_barrier``.
        surface_clearance_m: Clearance above the envelope [m], >= 0.
        surface_c: Post-jump margin of ``Xi_s`` [m/s], > 0; default
            :data:`satellite.control.surface_barrier.DEFAULT_SURFACE_C` (0.01 m/s).

    Returns:
        The :class:`RunResult`.

    Raises:
        UnknownNameError: Unknown trigger.
        ConfigError: Bad duration, missing ``tau`` for maneuvers, initial state outside the band.
        PostJumpConditionError: The controller broke ``h(x+) >= 0`` or ``Xi(x+) >= c``.
        SimulationError: The integrator failed.

    """
    wall0 = time.perf_counter()
    trigger = Trigger.parse(trigger)
    if isinstance(hours, bool) or not isinstance(hours, (int, float)) or not math.isfinite(hours) or hours < 0:
        raise ConfigError(f"hours must be a finite number >= 0, got {hours!r}")
    if not (math.isfinite(sample_interval_s) and sample_interval_s > 0):
        raise ConfigError(f"sample_interval_s must be positive, got {sample_interval_s}")
    if isinstance(min_interval_s, bool) or not (
            isinstance(min_interval_s, (int, float)) and math.isfinite(min_interval_s) and min_interval_s >= 0):
        raise ConfigError(f"min_interval_s must be a finite number of seconds >= 0, got {min_interval_s!r}")
    if contact not in CONTACT_MODES:
        raise ConfigError(f"contact must be one of {', '.join(CONTACT_MODES)}; got {contact!r}")
    if trigger.needs_tau and tau is None:
        raise ConfigError(f"the {trigger} trigger needs a fitted tau_p (make one with `isf-satellite tau`)")
    initial = initial or InitialOrbit()
    base = model or OrbitModel()
    model = base.with_phase(initial.body_phase())
    resolved = resolve_control(model, control)
    check_tau_controller(tau if trigger.needs_tau else None, resolved.controller)
    integ = integrator or IntegratorSettings()
    ctrl = make_controller(model, resolved)
    bound = model.accel_bound() if integ.event_scan else None
    trig = BandTriggers(model, ctrl.alpha, resolved.d_bar, accel_bound=bound)
    obs = Observers(observers)
    track = Tracker(model, trig, obs, sample_interval_s)
    miet: MietReport = miet_estimate(model, resolved, samples=miet_samples)
    check = SurfaceCheck(surface, model.body_phase, model.omega, surface_step_s) if surface is not None else None
    exit_watch = event(trig.h, False, -1.0, trig.rates()["h"], trig.h_batch, (EV_H, 0.0, None))
    watch = None
    if contact != "off":
        watch = make_contact(model, contact_surface or surface or load_surface())
    arcs = ArcIntegrator(model, integ, track, check, exit_watch, watch, contact == "stop")
    policy = make_policy(trigger, trig, ctrl, arcs, obs.on_event, tau,
                         period_h * 3600.0 if period_h is not None else None, float(min_interval_s),
                         period_at_start)
    sfilter = None
    if surface_barrier:
        shape = contact_surface or surface or load_surface()
        sfilter = add_surface_barrier(model, resolved, ctrl, trig, policy, shape, surface_clearance_m, surface_c)
        track.surface_h = sfilter.strig.h_batch

    y = initial.state(model)
    t = 0.0
    t_end = hours * 3600.0
    h0 = trig.h(0.0, y)
    if h0 < 0.0:
        raise ConfigError(f"initial state is outside the band (h = {h0:.4g})")
    if sfilter is not None and sfilter.strig.h(0.0, y) < 0.0:
        raise ConfigError(f"initial state is inside the surface envelope (h_s = {sfilter.strig.h(0.0, y):.4g} m)")
    settings = run_settings(resolved, model, initial, integ)
    settings["accel_bound"] = bound
    settings.update(resolved.describe())
    if tau is not None:
        settings["tau"] = tau.describe()
    if period_h is not None:
        settings["period_h"] = float(period_h)
    if period_at_start:
        settings["period_at_start"] = True
    if obs:
        send_mesh = body_mesh if body_mesh is not None else True
        mesh = body_mesh_info(surface) if send_mesh else None
        obs.on_start(start_info(trigger, hours, initial, model, y.tolist(), settings, mesh))
    track.radius(y)
    if obs:
        track.emit(0.0, y, policy.first_phase, None)

    try:
        while t < t_end:
            t, y, finished = policy.step(t, y, t_end)
            if finished or arcs.stopped is not None:
                break
    except BaseException as exc:  # an error or Ctrl-C: observers keep what they have, marked partial
        if obs:
            obs.on_abort(exc)
        raise

    jumps = tuple(ctrl.jumps)
    iet = ctrl.inter_event_times / 3600.0
    kinds: dict[str, int] = {}
    for j in jumps:
        kinds[j.kind] = kinds.get(j.kind, 0) + 1
    h_lo = min(model.h_of_r(track.r_min), model.h_of_r(track.r_max))
    exits = sorted(track.band_exits)
    left_band = policy.left_band_s if policy.left_band_s is not None else (exits[0] if exits else None)
    result = RunResult(
        trigger=trigger,
        hours=float(hours),
        simulated_h=t / 3600.0,
        triggers=len(jumps),
        kinds=kinds,
        min_h=h_lo,
        r_min_over_R=track.r_min / model.R,
        r_max_over_R=track.r_max / model.R,
        total_dv=float(sum(norm(j.v) for j in jumps)),
        min_inter_event_h=float(iet.min()) if iet.size else None,
        mean_inter_event_h=float(iet.mean()) if iet.size else None,
        miet_bound_h=miet.bound_s / 3600.0,
        miet_estimate_h=miet.estimate_s / 3600.0,
        min_interval_s=float(min_interval_s),
        min_interval_binds=policy.holds,
        min_interval_overrides=policy.hold_overrides,
        left_band_h=left_band / 3600.0 if left_band is not None else None,
        wall_s=time.perf_counter() - wall0,
        seed=int(initial.seed),
        settings=settings,
        events=jumps,
        nfev=track.nfev,
        surface=check.report() if check is not None else None,
        band_exits=len(exits),
        contact=contact_report(contact, watch, track, arcs.stopped, jumps, t),
        shooting=shooting_report(sfilter.nominal if sfilter is not None else ctrl.controller),
        surface_barrier=surface_barrier_report(sfilter, track, policy.surface_fires),
        min_xi_tau=track.xi_tau_min if math.isfinite(track.xi_tau_min) else None,
    )
    obs.on_finish(result.summary())
    return result


def summary_line(result: RunResult) -> Mapping[str, Any]:
    """Short mapping for logs (trigger, triggers, min_h, wall time)."""
    return {"trigger": result.trigger, "triggers": result.triggers, "min_h": result.min_h, "wall_s": result.wall_s}
