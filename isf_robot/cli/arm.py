"""``isf-robot`` subcommands of the arm layer: ``scenes``, ``run``, ``compare``, ``demo``.

Registered by :mod:`isf_robot.cli` through :func:`register`. Handlers import MuJoCo lazily;
errors reach :func:`isf_robot.cli.errors.run_handler` (one line on stderr, exit status 2).
The filter parameters are resolved once per command (:func:`isf_robot.arm.resolve_params`:
flags, then the scene's ``[filter]``, then the tracking calibration for an unknown ``d_bar``).
With ``--json`` stdout holds exactly one JSON object; progress goes to stderr.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import os
import sys
from pathlib import Path
from typing import Any

from isf_robot.arm.config_schema import LEVELS  # (no MuJoCo: the handlers import it lazily)
from isf_robot.core.exceptions import ConfigError
from isf_robot.core.hooks import Observers
from isf_robot.core.jit import CACHED_ONLY, JIT_ENV
from isf_robot.core.spec import PARAMETERS, Parameter
from isf_robot.core.strategies import strategy_info, strategy_names
from isf_robot.record.options import add_recording_args, make_observer
from isf_robot.support.parallel import Interrupted
from isf_robot.support.progress import TerminalProgress
from isf_robot.support.report import format_value, to_jsonable, with_schema

from .arm_team import COORDINATION_HELP, check_coordination, team_compare, team_report, team_simulation

__all__ = ["register", "DEMO_SCENE"]

DEMO_SCENE = "panda_pole"


def _strategy_help() -> str:
    return "; ".join(f"{n}: {strategy_info(n).summary}" for n in strategy_names())


def _add_scene_args(p: argparse.ArgumentParser, files: bool = True) -> None:
    p.add_argument("--scene", metavar="NAME", help="a shipped scene (see `isf-robot scenes`)")
    if files:
        p.add_argument("--model", metavar="PATH.xml", help="an MJCF file (with --config)")
        p.add_argument("--config", metavar="PATH.toml", help="its scene config (with --model)")


def _add_filter_args(p: argparse.ArgumentParser, several_levels: bool = False) -> None:
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="simulated time per episode [s] (default: the scene's)")
    p.add_argument("--level", choices=LEVELS, default=None, nargs="+" if several_levels else None,
                   help="what the filter commands: joint velocities on q_dot = u + d, or joint torques on the full "
                        "dynamics (second-order barriers; d_bar [rad/s^2] calibrated for it); default: the scene's "
                        "[filter] level, else velocity" + ("; two levels (--level velocity torque): both on the "
                                                           "same seeds, side by side in one table"
                                                           if several_levels else ""))
    p.add_argument("--control-period", type=float, default=None, metavar="S",
                   help="control period [s], a whole multiple of the physics timestep "
                        "(default: the scene's)")
    main = {q.name: q for q in PARAMETERS if q.name in _MAIN}
    for name in _MAIN:
        _add_parameter(p, main[name])
    _add_intermittent_args(p)


_MAIN = ("alpha", "c", "b", "d_bar")  # (the paper's four; the intermittent options in their own group)
_HELP = {"d_bar": "disturbance bound: tracking error [rad/s] at the velocity level (default: the scene's, else "
                  "calibrated), model error [rad/s^2] at the torque level (default: calibrated)",
         "predict_every": "control steps between rollouts of the predictive off trigger (default 5)"}


def _add_parameter(p: Any, q: Parameter) -> None:
    """``--name`` for one field of :class:`~isf_robot.core.FilterSpec` (default: the scene's)."""
    p.add_argument("--" + q.name.replace("_", "-"), type=int if q.name == "predict_every" else float, default=None,
                   metavar=q.metavar, help=_HELP.get(q.name, q.help))


def _add_intermittent_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("intermittent filter options (isf; off by default)")
    for q in PARAMETERS:
        if q.flag and q.name not in _MAIN:
            _add_parameter(g, q)


def _intermittent_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    return {q.name: getattr(args, q.name, None) for q in PARAMETERS if q.flag and q.name not in _MAIN}


def _level(args: argparse.Namespace, scene: Any) -> str:
    """``--level``, else the scene's ``[filter] level`` (the torque level: one arm only)."""
    level = str(getattr(args, "level", None) or scene.config.level)
    if level == "torque" and scene.arms:
        raise ConfigError(f"the torque level runs a scene with one arm; {scene.name} has {len(scene.arms)} "
                          "([[arm]] tables): use the velocity level")
    return level


def _simulation(args: argparse.Namespace, scene: Any, **kwargs: Any) -> Any:
    """The simulation of ``--filter`` at the run's level (keyword arguments: :func:`_params` and more).

    A scene with several arms: the team's (``--coordination``).
    """
    from isf_robot.arm.compare import simulation_type

    level = _level(args, scene)
    if scene.arms:
        return team_simulation(args, scene, kwargs)
    return simulation_type(level)(scene, args.filter, seed=args.seed, **kwargs)


def _params(args: argparse.Namespace, scene: Any) -> dict[str, Any]:
    """ArmSimulation keyword arguments from the flags, the filter parameters resolved once (at the run's level)."""
    from isf_robot.arm.calibration_loop import loop_params
    from isf_robot.arm.compare import level_params
    from isf_robot.arm.diagnostics import run_findings

    scene = _with_period(scene, getattr(args, "control_period", None))  # (the calibration's period: the run's)
    level = _level(args, scene)
    if level == "torque" and getattr(args, "d_bar_in_loop", False):
        raise ConfigError("--d-bar-in-loop raises the velocity level's d_bar; the torque level's is calibrated "
                          "(give --d-bar to set it)")
    params = level_params(scene, level, args.alpha, args.c, args.b, args.d_bar, **_intermittent_kwargs(args))
    if getattr(args, "d_bar_in_loop", False):
        params = loop_params(scene, args.filter, params)
    out: dict[str, Any] = {"params": params}
    for f in run_findings(scene, out["params"]) if level == "velocity" else ():  # what `isf-robot check` reports
        print(f"warning [{f.code}]: {f.message}", file=sys.stderr)
    if getattr(args, "control_period", None) is not None:
        out["control_period"] = args.control_period
    return out


def _with_period(scene: Any, period: float | None) -> Any:
    """``scene`` with ``--control-period`` in its config (``[control] period``), checked against the physics timestep.

    The calibration of ``d_bar`` reads it there (its hold and tracking errors grow with the period).
    """
    if period is None:
        return scene
    from isf_robot.arm.episode import check_control_period

    check_control_period(period, float(scene.model.opt.timestep))
    control = dataclasses.replace(scene.config.control, period=float(period))
    return dataclasses.replace(scene, config=dataclasses.replace(scene.config, control=control))


def _check_seed(args: argparse.Namespace) -> None:
    if args.seed < 0:
        raise ConfigError(f"--seed must be a non-negative integer, got {args.seed}")


def _spec(args: argparse.Namespace) -> Any:
    from isf_robot.arm.compare import SceneSpec

    return SceneSpec(name=args.scene, model=getattr(args, "model", None),
                     config=getattr(args, "config", None))


def register(subparsers: Any) -> None:
    """Add ``scenes``, ``run``, ``compare`` and ``demo`` to the CLI's subparsers."""
    p = subparsers.add_parser("scenes", help="list the shipped arm scenes",
                              description="List the shipped arm scenes, one line each.")
    p.set_defaults(handler=_cmd_scenes)

    p = subparsers.add_parser(
        "run", help="simulate one episode of an arm scene",
        description="Simulate one episode: nominal task, safety filter, MuJoCo physics. Safety "
                    "is checked on the true geometry at every physics step.")
    _add_scene_args(p)
    p.add_argument("--filter", choices=strategy_names(), default="isf",
                   help=f"strategy (default isf) -- {_strategy_help()}")
    p.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    p.add_argument("--coordination", choices=("central", "decentral"), default=None,
                   help=COORDINATION_HELP + " (default central)")
    _add_filter_args(p)
    p.add_argument("--d-bar-in-loop", action="store_true",
                   help="raise d_bar until the tracking error this filter produces is covered (runs it on seeds "
                        "0-5 for 6 s a round, a few rounds; cached per process)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--quiet", action="store_true",
                   help="no progress line (shown on a terminal only, for runs longer than a second)")
    p.add_argument("--view", action="store_true",
                   help="watch the run in MuJoCo's viewer in real time (Space pauses, Ctrl + mouse drag perturbs "
                        "a body, closing the window stops the run; needs a display)")
    p.add_argument("--view-speed", type=float, default=1.0, metavar="X",
                   help="with --view: simulated seconds per wall-clock second (default 1)")
    p.add_argument("--view-collision", action="store_true",
                   help="with --view: also draw the collision geoms of bodies that have visual geoms (hidden by "
                        "default, as in `isf-robot render`)")
    p.add_argument("--video", type=Path, default=None, metavar="PATH",
                   help="also render the run offscreen to PATH: .gif, .mp4 (the 'video' extra) or .png (one frame); "
                        "as `isf-robot render`, which has the frame size and rate options")
    add_recording_args(p)
    p.set_defaults(handler=_cmd_run)

    p = subparsers.add_parser(
        "compare", help="compare the strategies over seeded episodes",
        description="Run the strategies on the same seeds and print mean ± std per strategy.")
    _add_scene_args(p)
    p.add_argument("--episodes", type=int, default=5, help="episodes per strategy (default 5)")
    p.add_argument("--filters", nargs="+", choices=strategy_names(), default=list(strategy_names()),
                   metavar="FILTER", help=f"strategies (default: {' '.join(strategy_names())})")
    p.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    p.add_argument("--jobs", type=int, default=1, metavar="K",
                   help="worker processes (default 1)")
    p.add_argument("--coordination", choices=("central", "decentral"), default=None,
                   help=COORDINATION_HELP + " (default both)")
    _add_filter_args(p, several_levels=True)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    add_recording_args(p, per_run=True)
    p.set_defaults(handler=_cmd_compare)

    p = subparsers.add_parser(
        "demo", help=f"short comparison of the three strategies on {DEMO_SCENE}",
        description=f"A short comparison (nominal, cbf, isf) on the {DEMO_SCENE} scene.",
        conflict_handler="resolve")
    p.add_argument("--scene", default=DEMO_SCENE, metavar="NAME",
                   help=f"scene (default {DEMO_SCENE})")
    p.add_argument("--episodes", type=int, default=3, help="episodes per strategy (default 3)")
    p.add_argument("--duration", type=float, default=8.0, metavar="S",
                   help="simulated time per episode [s] (default 8)")
    p.add_argument("--jobs", type=int, default=None, metavar="K",
                   help="worker processes (default: up to 2)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=_cmd_demo)


# ----------------------------------------------------------------------------- handlers


def _cmd_scenes(args: argparse.Namespace) -> int:
    from isf_robot.arm.scene import list_scenes

    scenes = list_scenes()
    width = max((len(s.name) for s in scenes), default=0)
    for s in scenes:
        print(f"{s.name.ljust(width)}  {s.description}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    video = None
    if args.video is not None:  # the offscreen GL backend is chosen before MuJoCo is imported
        from isf_robot.arm.render import VideoRecorder, select_gl

        video = VideoRecorder(args.video)  # checks the path and format before anything runs
        if "mujoco" not in sys.modules:
            select_gl()
    _check_seed(args)
    scene = _spec(args).load()
    check_coordination(args, scene)
    kwargs = _params(args, scene)
    sim = _simulation(args, scene, **kwargs)  # validates before any output
    sim.control_steps(args.duration)
    observers = [make_observer(args, "arm", name=f"{scene.name}-{args.filter}-seed{args.seed}"), video]
    if args.view:
        from isf_robot.arm.viewer import LiveViewer, check_display

        check_display()
        observers.append(LiveViewer(speed=args.view_speed, show_collision=args.view_collision))
    if any(o is not None for o in observers):
        sim.observers = Observers(observers)  # (drops None)
    progress = None if args.quiet else TerminalProgress.for_stream(sys.stderr, f"{scene.name} {args.filter}")
    sim.progress = progress
    try:
        if scene.arms:
            return team_report(args, sim)
        d = to_jsonable(sim.run(args.duration).as_dict())
    finally:
        if progress is not None:
            progress.close()
    if args.json:
        print(json.dumps(with_schema("isf-robot-run", d)))
        return 0
    torque = d.get("level") == "torque"
    print(f"scene {d['scene']}, filter {d['filter']}, seed {d['seed']}{', torque level' if torque else ''}: "
          f"{d['duration_s']:.3f} s simulated, {d['control_steps']} control steps in "
          f"{d['wall_s']:.2f} s")
    rows = [
        ("duty cycle", d["duty_cycle"]), ("on switches", d["on_switches"]),
        ("mean off period [s]", d["mean_off_s"]), ("min off period [s]", d["min_off_s"]),
        ("min barrier [m] (true geometry)", d["min_barrier"]),
        ("collision steps", d["collisions"]), ("goals reached", d["goals_reached"]),
        ("intervention [rad^2/s]", d["intervention"]), ("QP solves", d["qp_solves"]),
        ("fallbacks (braking)", d["fallbacks"]), ("d_bar [rad/s]", d["d_bar"]),
        ("tracking error q99 [rad/s]", d["tracking_error_q99"]),
        ("largest command step at a switch", d["switch_jump_max"]),
        ("designed off bound [s]", d["off_bound_min_s"]),
    ]
    if "shoot_choices" in d:  # (maneuvers by shooting: how often the push level was chosen, and raised above b)
        rows += [("maneuver level choices", d["shoot_choices"]), ("  of them above b", d["shoot_raised"])]
    if torque:  # (the same figures in the torque level's units)
        rows = [(k.replace("[rad^2/s]", "[N^2 m^2 s]").replace("[rad/s]", "[rad/s^2]").replace(
            "tracking error", "model error").replace("(braking)", "(damping to rest)"), v) for k, v in rows]
        rows += [("largest |tau| / tau_max", d["tau_peak_ratio"]),
                 ("reference tracking q99 [rad/s]", d["reference_error_q99"])]
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k.ljust(w)}  {format_value(v)}")
    if d["filter"] != "nominal" and not d["d_bar_covered"]:
        what, unit = ("model error", "rad/s^2") if torque else ("tracking error", "rad/s")
        print(f"warning: {what} q99 {d['tracking_error_q99']:.3g} {unit} > d_bar {d['d_bar']:.3g}: the "
              "robust term does not cover it (safety rests on the clearance the filter keeps)", file=sys.stderr)
    if d.get("chatter"):
        print(f"warning: {d['chatter']}", file=sys.stderr)
    return 0


def _progress(quiet: bool, label: str = "") -> Any:
    if quiet:
        return None

    def report(done: int, total: int, task: Any, r: Any) -> None:
        print(f"[{done}/{total}] {label}{task.strategy} seed {task.seed}: duty "
              f"{r['duty_cycle']:.3f}, min h {format_value(r['min_barrier'])} m, "
              f"{r['collisions']} collision steps, {r['wall_s']:.2f} s", file=sys.stderr,
              flush=True)

    return report


def _print_comparison(comp: Any, as_json: bool) -> None:
    from isf_robot.arm.compare import format_table

    print(json.dumps(with_schema("isf-robot-compare", comp.as_dict())) if as_json else format_table(comp), flush=True)


def _keep_partial(fn: Any) -> Any:
    """On Ctrl-C / SIGTERM, print the episodes that finished (marked partial), then re-raise."""

    @functools.wraps(fn)
    def wrapper(args: argparse.Namespace) -> int:
        try:
            return int(fn(args))
        except Interrupted as exc:
            if exc.partial is not None:
                _print_comparison(exc.partial, args.json)
            raise

    return wrapper


@_keep_partial
def _cmd_compare(args: argparse.Namespace) -> int:
    from isf_robot.arm.compare import compare_strategies

    _check_seed(args)
    levels = list(dict.fromkeys(args.level or ()))  # (a level named twice runs once)
    args.level = levels[0] if len(levels) == 1 else None
    if len(levels) > 1:
        _check_levels(args)
    spec = _spec(args)
    scene = spec.load()
    check_coordination(args, scene)
    if len(levels) > 1:
        return _compare_levels(args, spec, scene, levels)
    params = _params(args, scene)
    if scene.arms:
        return team_compare(args, spec, scene, params)
    obs = make_observer(args, "arm")
    comp = compare_strategies(spec, args.episodes, strategies=args.filters,
                              duration=args.duration, seed0=args.seed, jobs=args.jobs,
                              params={**params, **({"observers": [obs]} if obs else {})},
                              progress=_progress(args.quiet), level=_level(args, scene))
    _print_comparison(comp, args.json)
    if args.rrd is not None:
        from isf_robot.record.side_by_side import write_side_by_side

        for path in write_side_by_side(args.rrd, order=args.filters):
            print(f"side by side: {path}", file=sys.stderr)
    return 0


def _check_levels(args: argparse.Namespace) -> None:
    """What ``compare`` cannot do at several levels at once (before any scene loads)."""
    if args.d_bar is not None:
        raise ConfigError("--d-bar with two levels: its unit is the level's (rad/s at the velocity level, rad/s^2 "
                          "at the torque level); leave it out (each level takes its own) or compare one level")
    if args.rrd is not None or args.spawn or args.connect is not None:
        raise ConfigError("recording compares one level at a time: give one --level with --rrd, --spawn or --connect")


def _compare_levels(args: argparse.Namespace, spec: Any, scene: Any, levels: list[str]) -> int:
    """``compare`` at each level on the same seeds, then one table (JSON: one comparison per level).

    Every level's parameters are resolved (and checked) before the first episode runs. On Ctrl-C
    or SIGTERM the levels done and the interrupted one's finished episodes are printed (partial).
    """
    from isf_robot.arm.compare import compare_strategies, format_levels

    params = {}
    for level in levels:
        args.level = level
        params[level] = _params(args, scene)
    comps: list[Any] = []

    def show() -> None:
        if args.json:
            doc = {"scene": scene.name, "levels": {c.level: c.as_dict() for c in comps}}
            print(json.dumps(with_schema("isf-robot-compare-levels", doc)), flush=True)
        else:
            print(format_levels(comps), flush=True)

    for level in levels:
        try:
            comps.append(compare_strategies(spec, args.episodes, strategies=args.filters, duration=args.duration,
                                            seed0=args.seed, jobs=args.jobs, params=params[level],
                                            progress=_progress(args.quiet, f"{level} "), level=level))
        except Interrupted as exc:
            if exc.partial is not None:
                comps.append(exc.partial)
            exc.partial = None  # (printed here, with the levels done)
            if comps:
                show()
            raise
    show()
    return 0


DEMO_PLAIN_NOTICE = ("the fast kernels are not compiled for this machine yet, so this demo runs the plain NumPy "
                     "path (the same numbers); the first `isf-robot run` or `compare` compiles them once (about "
                     "30-45 s), and later runs, this demo included, use them")


@_keep_partial
def _cmd_demo(args: argparse.Namespace) -> int:
    from isf_robot.arm import kernels
    from isf_robot.arm.compare import SceneSpec, compare_strategies, format_table

    held, count = kernels.compiled_here()
    if count and not held:  # (the first command after an install)
        print(f"isf-robot demo: {DEMO_PLAIN_NOTICE}", file=sys.stderr)
    jobs = args.jobs if args.jobs is not None else max(1, min(2, os.cpu_count() or 1))
    before = os.environ.get(JIT_ENV)
    if count:  # (the demo never waits for the compiler: the kernels numba's cache holds, the rest as written)
        # (this process and the workers it starts; put back after the comparison. None held: the plain path
        # outright, so that no worker imports numba only to find its cache empty, about 0.4 s each)
        os.environ[JIT_ENV] = CACHED_ONLY if held else "0"
    try:
        comp = compare_strategies(SceneSpec(name=args.scene), args.episodes, duration=args.duration,
                                  jobs=jobs, progress=_progress(False))
    finally:
        if count and before is None:
            os.environ.pop(JIT_ENV, None)
        elif count and before is not None:
            os.environ[JIT_ENV] = before
    if args.json:
        print(json.dumps(with_schema("isf-robot-compare", comp.as_dict())))
        return 0
    print(format_table(comp))
    isf, cbf = comp.results.get("isf", {}), comp.results.get("cbf", {})
    if isf.get("qp_solves") is not None and cbf.get("qp_solves"):
        print(f"\nThe intermittent filter solved {isf['qp_solves'] / cbf['qp_solves']:.0%} of "
              f"the standard filter's QPs and was on {isf['duty_cycle']:.0%} of the time.")
    return 0
