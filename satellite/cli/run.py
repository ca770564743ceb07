"""``isf-satellite run``: one orbit run with a chosen trigger, summary as text or JSON."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Mapping
from typing import Any, TextIO

from isf_robot.core import ConfigError, Observer, UnknownNameError
from isf_robot.record.options import add_recording_args, make_observer
from isf_robot.support.report import with_schema
from satellite.control.contact import CONTACT_MODES
from satellite.control.controller import CONTROLLERS, ControlParams, resolve_control
from satellite.control.shooting import ShootingParams
from satellite.control.tau import load_tau
from satellite.control.triggers import TRIGGERS, Trigger
from satellite.gravity.fields import DEFAULT_GRAVITY, GRAVITY_MODELS, load_field
from satellite.orbit.arcs import IntegratorSettings
from satellite.orbit.model import InitialOrbit, OrbitModel
from satellite.orbit.simulate import MIN_INTERVAL_S, SURFACE_STEP_S, RunResult, SatelliteSample, simulate
from satellite.shape.mesh_surface import load_surface

__all__ = ["register", "run", "ProgressObserver", "format_text", "add_controller_args", "control_from_args"]


def add_controller_args(p: argparse.ArgumentParser) -> None:
    """``--controller`` and the shooting controller's ``--shoot-*`` options (``run``, ``tau``)."""
    p.add_argument("--controller", default="kepler", metavar="{" + ",".join(CONTROLLERS) + "}",
                   help="safeguarding controller: kepler (the paper's: a Kepler target orbit, default) or shooting "
                        "(the impulse whose predicted time to the next trigger in the truth field is longest)")
    d = ShootingParams()
    p.add_argument("--shoot-horizon-h", type=float, default=None, metavar="HOURS",
                   help=f"shooting: prediction horizon (default {d.horizon_h:g})")
    p.add_argument("--shoot-grid", type=int, default=None, metavar="N",
                   help=f"shooting: odd number of lattice points per velocity axis (default {d.grid})")
    p.add_argument("--shoot-dv-max", type=float, default=None, metavar="M_PER_S",
                   help="shooting: largest impulse in m/s (default: no limit beyond the lattice)")


def control_from_args(args: argparse.Namespace) -> ControlParams:
    """The run's :class:`ControlParams` from the parsed options (one-line errors for bad ones)."""
    shoot = {k: getattr(args, f"shoot_{k}") for k in ("horizon_h", "grid", "dv_max")}
    given = [f"--shoot-{k.replace('_', '-')}" for k, v in shoot.items() if v is not None]
    if args.controller not in CONTROLLERS:
        raise UnknownNameError("controller", args.controller, CONTROLLERS)
    if given and args.controller != "shooting":
        raise ConfigError(f"{', '.join(given)} need(s) --controller shooting")
    params = ShootingParams(**{k: v for k, v in shoot.items() if v is not None})
    return ControlParams(alpha_gain=args.alpha_gain, d_bar=args.d_bar, c=getattr(args, "c", None),
                         controller=args.controller, shooting=params)


class ProgressObserver(Observer):
    """Writes a line to a stream at every ``step`` fraction of the simulated time.

    Args:
        stream: Where to write (stderr in the CLI).
        step: Fraction of the run between lines, in (0, 1].

    """

    def __init__(self, stream: TextIO, step: float = 0.1) -> None:
        self.stream = stream
        self.step = step
        self.total_s = 0.0
        self.next_frac = step
        self.jumps = 0
        self.wall0 = time.perf_counter()

    def on_start(self, info: Mapping[str, Any]) -> None:
        self.total_s = float(info["hours"]) * 3600.0
        self.wall0 = time.perf_counter()

    def on_step(self, record: SatelliteSample) -> None:
        if self.total_s <= 0.0:
            return
        frac = record.t / self.total_s
        if frac + 1e-12 >= self.next_frac:
            while self.next_frac <= frac + 1e-12:
                self.next_frac += self.step
            self.stream.write(
                f"isf-satellite run: {100 * min(frac, 1.0):3.0f}% ({record.t / 3600:.0f} h), "
                f"{self.jumps} impulses, {time.perf_counter() - self.wall0:.1f} s\n"
            )
            self.stream.flush()

    def on_event(self, event: Any) -> None:
        self.jumps += 1


def register(subparsers: Any) -> None:
    """Add the ``run`` subcommand."""
    p = subparsers.add_parser(
        "run",
        help="simulate the orbit with no control, the greedy trigger or two-impulse maneuvers",
        description=(
            "Integrates the satellite about Itokawa (exact polyhedron gravity, tabulated; spinning body) "
            "and applies the safeguarding impulsive controller when the trigger fires. "
            "Band [1.6R, 2.4R], h = (0.4R)^2 - (r - 2R)^2."
        ),
    )
    p.add_argument("--trigger", default=Trigger.GREEDY.value, metavar="{" + ",".join(TRIGGERS) + "}",
                   help="; ".join(f"{t}: {t.description}" for t in Trigger) + f" (default {Trigger.GREEDY})")
    p.add_argument("--hours", type=float, default=2400.0, help="simulated time in hours (default 2400)")
    p.add_argument("--seed", type=int, default=0, help="seed of the initial orbit's node, latitude and body phase")
    p.add_argument("--tau", metavar="FILE", help="tau_p fit written by `isf-satellite tau` (maneuver trigger)")
    p.add_argument("--period-h", type=float, default=None, metavar="HOURS",
                   help="impulse period of the periodic trigger (baseline station keeping), hours")
    p.add_argument("--period-at-start", action="store_true",
                   help="periodic: the first impulse at t = 0 (insertion), then every --period-h (default: at t = T)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout (nothing else)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--disturbance-scale", type=float, default=1.0, metavar="K",
                   help="experiment: scale the non-Kepler gravity by K (default 1, the full field)")
    p.add_argument("--no-spin", action="store_true", help="freeze the body (default: 12.1324 h spin)")
    p.add_argument("--inclination", type=float, default=45.0, metavar="DEG",
                   help="inclination to the body's equator (default 45)")
    p.add_argument("--radius", type=float, default=2.0, metavar="R_OVER_R",
                   help="initial radius in units of R, inside [1.6, 2.4] (default 2.0, circular speed)")
    p.add_argument("--alpha-gain", type=float, default=None, metavar="PER_S",
                   help="alpha(h) = gain * h (default: mean motion at 2R, 2.63e-4 1/s)")
    p.add_argument("--d-bar", type=float, default=0.0, help="disturbance bound used in Xi (default 0)")
    p.add_argument("--c", type=float, default=None, help="post-jump margin (default: half the smallest post-jump Xi)")
    add_controller_args(p)
    p.add_argument("--gravity", default=DEFAULT_GRAVITY,
                   metavar="{" + ",".join(GRAVITY_MODELS) + "}|FILE.json|FILE.npz",
                   help="truth gravity: table (default: the exact polyhedron field, tabulated), sh8 (the paper's "
                        "degree-8 series, invalid inside 1.925R), polyhedron (exact at every step, slow), or a "
                        "file written by `isf-satellite gravity` (.json series, .npz --table)")
    p.add_argument("--events", action="store_true", help="with --json, include the impulse list")
    p.add_argument("--surface-check", action="store_true",
                   help="also check the trajectory against the body's shape (off by default: like the paper, "
                        "the dynamics ignore impact); adds surface_* keys and min_clearance_m")
    p.add_argument("--contact", choices=CONTACT_MODES, default="count",
                   help="surface contact in the dynamics: count (default: contacts counted, the orbit goes on "
                        "through the body as in the paper), stop (the run ends at the first contact), off")
    p.add_argument("--min-interval", type=float, default=MIN_INTERVAL_S, metavar="S",
                   help="practical minimum interval between impulses in seconds: an impulse due by Xi sooner after "
                        "the previous one waits, unless the satellite would leave the band; 0 turns it off "
                        f"(default {MIN_INTERVAL_S:g}; reported as min_interval_binds/overrides)")
    p.add_argument("--surface-barrier", action="store_true",
                   help="greedy and maneuver: a second barrier keeps the satellite outside a smooth envelope of "
                        "the shape (h_s = distance outside the envelope - --surface-clearance); its trigger fires "
                        "impulses too and every impulse keeps both post-jump conditions")
    p.add_argument("--surface-clearance", type=float, default=0.0, metavar="M",
                   help="clearance above the envelope for --surface-barrier, metres (default 0)")
    p.add_argument("--surface-c", type=float, default=None, metavar="M_PER_S",
                   help="post-jump margin of the surface trigger, m/s "
                        "(default 0.01: fewer, larger surface impulses than a smaller margin)")
    p.add_argument("--no-event-scan", action="store_true",
                   help="see events at integrator step points only (solve_ivp's rule; can miss crossings)")
    p.add_argument("--shape", metavar="PATH.obj",
                   help="shape file for --contact, --surface-check, --surface-barrier and --gravity polyhedron "
                        "(default: the shipped Gaskell Itokawa mesh, itokawa_low.obj)")
    p.add_argument("--shape-units", choices=("km", "m"), default="km", help="length unit of --shape (default km)")
    p.add_argument("--surface-step", type=float, default=None, metavar="S",
                   help=f"sampling interval of --surface-check in seconds (default {SURFACE_STEP_S:g})")
    add_recording_args(p)
    p.set_defaults(func=run)


def format_text(res: RunResult) -> str:
    """Human-readable summary."""

    def f(v: Any, fmt: str) -> str:
        return "-" if v is None else format(v, fmt)

    lines = [
        f"trigger            {res.trigger}",
        f"hours              {res.hours:g} (simulated {res.simulated_h:.4g})",
        f"triggers           {res.triggers} {res.kinds if res.kinds else ''}".rstrip(),
        f"min Xi_tau         {f(res.min_xi_tau, '.4g')} "
        + ("(a tau impulse needs Xi_tau <= 0, i.e. dtau_p/dt <= -1)" if res.trigger is Trigger.MANEUVER
           else "(evaluated by the maneuver trigger only)"),
        f"min_h              {res.min_h:.6g} m^2",
        f"r range            [{res.r_min_over_R:.4f}, {res.r_max_over_R:.4f}] R",
        f"total_dv           {res.total_dv:.6g} m/s",
        f"inter-event        min {f(res.min_inter_event_h, '.4g')} h, mean {f(res.mean_inter_event_h, '.4g')} h",
        f"miet               estimate {f(res.miet_estimate_h, '.3g')} h (c / sup|dXi/dt|), Proposition 1's "
        f"product {res.miet_bound_h:.3g} h",
    ]
    if res.min_interval_binds:
        lines.append(f"min interval       {res.min_interval_s:g} s bound {res.min_interval_binds} time(s), "
                     f"{res.min_interval_overrides} cut short at the band's edge")
    if res.trigger in (Trigger.NONE, Trigger.PERIODIC) or res.band_exits:
        lines.append(f"left_band          {f(res.left_band_h, '.4g')} h ({res.band_exits} exit(s))")
    if res.surface is not None:
        s = res.surface
        lines += [
            f"surface model      {s['surface_model']}",
            f"surface hits       {s['surface_hits']} samples in {s['surface_passes']} passes "
            f"(first {f(s['first_surface_hit_h'], '.4g')} h; every {s['surface_step_s']:g} s + events)",
            f"min clearance      {f(s['min_clearance_m'], '.4g')} m (radial) at {f(s['min_clearance_h'], '.4g')} h",
        ]
    if res.contact is not None:
        c = res.contact
        lines += [
            f"contact            {c['surface_contacts']} contact(s) ({c['contact_mode']}; first "
            f"{f(c['first_contact_h'], '.4g')} h; {c['envelope_passes']} pass(es) near the surface, "
            f"min clearance {f(c['min_pass_clearance_m'], '.3g')} m){' - run stopped' if c['contact_stopped'] else ''}",
            f"contact model      {c['contact_model']}",
            f"before contact     {c['triggers_physical']} impulse(s), {c['total_dv_physical']:.6g} m/s in "
            f"{c['physical_h']:.4g} h (the physical flight: a run that touched the surface goes on through it)",
        ]
    if res.surface_barrier is not None:
        b = res.surface_barrier
        lines.append(f"surface barrier    {b['surface_impulses']} surface impulse(s), min h_s "
                     f"{f(b['surface_min_h_m'], '.4g')} m, {b['surface_filtered']} impulse(s) filtered; "
                     f"{b['surface_barrier']['name']}")
    lines.append(f"wall               {res.wall_s:.2f} s")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Execute ``isf-satellite run``; return the exit status."""
    trigger = Trigger.parse(args.trigger)
    if not math.isfinite(args.hours) or args.hours <= 0:
        raise ConfigError(f"--hours must be a finite number > 0, got {args.hours:g}")
    surface = shape = None
    if (args.shape and not args.surface_check and args.contact == "off" and not args.surface_barrier
            and args.gravity != "polyhedron"):
        raise ConfigError("--shape needs --surface-check, --contact count|stop, --surface-barrier or "
                          "--gravity polyhedron")
    if args.surface_step is not None and not args.surface_check:
        raise ConfigError("--surface-step goes with --surface-check")
    surface_step = SURFACE_STEP_S if args.surface_step is None else args.surface_step
    if not (math.isfinite(surface_step) and surface_step > 0):
        raise ConfigError(f"--surface-step must be a positive number of seconds, got {surface_step:g}")
    if not args.surface_barrier and (args.surface_clearance != 0.0 or args.surface_c is not None):
        raise ConfigError("--surface-clearance and --surface-c go with --surface-barrier")
    if args.surface_barrier and trigger not in (Trigger.GREEDY, Trigger.MANEUVER):
        raise ConfigError(f"--surface-barrier works with --trigger greedy or maneuver, not {trigger}")
    if args.surface_barrier and not (math.isfinite(args.surface_clearance) and args.surface_clearance >= 0):
        raise ConfigError(f"--surface-clearance must be a number of metres >= 0, got {args.surface_clearance:g}")
    if args.surface_c is not None and not (math.isfinite(args.surface_c) and args.surface_c > 0):
        raise ConfigError(f"--surface-c must be a positive speed in m/s, got {args.surface_c:g}")
    if args.surface_check or args.contact != "off" or args.surface_barrier:

        shape = load_surface(args.shape, units=args.shape_units)
        surface = shape if args.surface_check else None
    tau = None
    if trigger.needs_tau:
        if not args.tau:
            raise ConfigError(f"--trigger {trigger} needs --tau FILE (make one with `isf-satellite tau --out FILE`)")

        tau = load_tau(args.tau)
    if args.period_at_start and trigger is not Trigger.PERIODIC:
        raise ConfigError("--period-at-start goes with --trigger periodic (and only with it)")
    if (trigger is Trigger.PERIODIC) != (args.period_h is not None):
        raise ConfigError("--period-h HOURS goes with --trigger periodic (and only with it)")
    if not (math.isfinite(args.min_interval) and args.min_interval >= 0):
        raise ConfigError(f"--min-interval must be a number of seconds >= 0, got {args.min_interval:g}")
    if args.period_h is not None and not (math.isfinite(args.period_h) and args.period_h > 0):
        raise ConfigError(f"--period-h must be a positive number of hours, got {args.period_h:g}")
    model = OrbitModel(load_field(args.gravity, args.shape, args.shape_units), spin=not args.no_spin,
                       disturbance_scale=args.disturbance_scale)
    initial = InitialOrbit(radius_over_R=args.radius, inclination_deg=args.inclination, seed=args.seed)
    control = control_from_args(args)

    resolve_control(model, control)  # every parameter checked before a recording is opened
    observers: list[Observer] = [] if args.quiet else [ProgressObserver(sys.stderr)]
    recorder = make_observer(args, "satellite", name=f"{trigger}-seed{args.seed}")
    if recorder is not None:
        observers.append(recorder)
    res = simulate(trigger, args.hours, initial=initial, model=model, control=control, tau=tau,
                   observers=observers, surface=surface, surface_step_s=surface_step,
                   body_mesh=recorder is not None, contact=args.contact, contact_surface=shape,
                   integrator=IntegratorSettings(event_scan=not args.no_event_scan), period_h=args.period_h,
                   min_interval_s=args.min_interval, surface_barrier=args.surface_barrier,
                   surface_clearance_m=args.surface_clearance, surface_c=args.surface_c,
                   period_at_start=args.period_at_start)
    if args.json:
        out = res.summary()
        if args.events:
            out["events"] = [
                {"t_h": e.t / 3600.0, "kind": e.kind, "dv": e.v.tolist(), "h_before": e.h_before,
                 "xi_after": e.xi_after} for e in res.events
            ]
        sys.stdout.write(json.dumps(with_schema("isf-satellite-run", out)) + "\n")
    else:
        sys.stdout.write(format_text(res) + "\n")
    return 0
