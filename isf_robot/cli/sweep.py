"""``isf-robot sweep``: strategies x filter parameters x scenes x seeds, with a Pareto table.

Parameters are given as lists (``--c 0.05,0.2,0.5``: a grid over every combination) or, with
``--random N``, as ranges (``--c 0.05:0.5``: N random draws per intermittent strategy, seeded by
``--sweep-seed``). Episodes run in local worker processes (``--jobs K``) or on Ray (``--backend
ray``: a local Ray, or the cluster at ``--address``; the ``ray`` extra), with the same numbers on
both. Progress goes to stderr; ``--json`` prints the whole sweep (every episode's
result) and ``--output PATH.json`` writes it atomically. Ctrl-C stops the workers and prints (and
writes) what finished, marked partial. ``--model/--config`` sweep the user's own arm, and
``--write-config PATH.toml`` writes the chosen ``[filter]`` table with its evidence beside it
(:mod:`isf_robot.arm.tune`). A scene with several arms runs each point once per way of filtering
(``--coordination`` to keep one) and adds a table of each arm's figures; ``--write-config`` refuses it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from isf_robot.arm.config_schema import LEVELS  # (no MuJoCo)
from isf_robot.cli.plot import sweep_figure
from isf_robot.core.exceptions import ConfigError
from isf_robot.core.spec import PARAMETERS
from isf_robot.core.strategies import strategy_info, strategy_names
from isf_robot.support.extras import install_hint
from isf_robot.support.files import check_output_path, write_text_atomic
from isf_robot.support.parallel import BACKENDS, Interrupted, check_backend
from isf_robot.support.report import with_schema

__all__ = ["register"]

_FLAGS = {q.name: "--" + q.name.replace("_", "-") for q in PARAMETERS if q.swept}  # (the sweep's parameters' flags)


def register(subparsers: Any) -> None:
    """Add ``sweep`` to the CLI's subparsers."""
    p = subparsers.add_parser(
        "sweep", help="sweep filter parameters over scenes and seeds (Pareto table)",
        description="Run strategies over a grid (comma lists) or random draws (--random N with LO:HI ranges) "
                    "of filter parameters, on several scenes and seeds; print one table per scene with the "
                    "Pareto front (duty, switches, shortest off period, intervention, goals, violations).")
    p.add_argument("--scenes", nargs="+", default=None, metavar="NAME",
                   help="shipped scenes (default panda_pole, unless --model is given)")
    p.add_argument("--model", metavar="PATH.xml", help="your arm's MJCF file (with --config): swept too")
    p.add_argument("--config", metavar="PATH.toml", help="its scene config (with --model)")
    p.add_argument("--filters", nargs="+", choices=strategy_names(), default=["cbf", "isf"], metavar="FILTER",
                   help="strategies (default: cbf isf)")
    p.add_argument("--episodes", type=int, default=5, help="seeds per point (default 5)")
    p.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="simulated time per episode [s]")
    p.add_argument("--jobs", type=int, default=1, metavar="K",
                   help="worker processes; with --backend ray: local Ray CPUs, or tasks in flight on --address "
                        "(default 1)")
    p.add_argument("--backend", choices=BACKENDS, default="processes",
                   help="where episodes run: local worker processes (default) or Ray (the ray extra: "
                        f"{install_hint('ray')}); the numbers are the same on both")
    p.add_argument("--address", default=None, metavar="ADDR",
                   help="Ray cluster to join ('auto' or HOST:PORT; every node needs isf-robot installed); "
                        "default with --backend ray: start a local Ray with --jobs CPUs")
    p.add_argument("--level", choices=LEVELS, default="velocity",
                   help="what the filter commands: joint velocities (default) or joint torques on the full dynamics "
                        "(d_bar [rad/s^2], calibrated for it when --d-bar is not given)")
    p.add_argument("--coordination", choices=("central", "decentral"), default=None,
                   help="scenes with several arms: sweep this way of filtering only (default: both, each point "
                        "once per way; central: one filter over every arm's joints, decentral: one per arm)")
    p.add_argument("--d-bar", type=float, default=None, metavar="D",
                   help="tracking-error bound [rad/s] for every scene (default: each scene's, else calibrated)")
    for name, flag in _FLAGS.items():
        p.add_argument(flag, dest=name, default=None, metavar="V1,V2|LO:HI",
                       help=f"values of {name} (comma list; a LO:HI range with --random)")
    p.add_argument("--random", type=int, default=None, metavar="N",
                   help="N random draws per intermittent strategy from the LO:HI ranges")
    p.add_argument("--sweep-seed", type=int, default=0, help="seed of the random draws (default 0)")
    p.add_argument("--output", metavar="PATH.json", help="also write the JSON here (atomically)")
    p.add_argument("--write-config", metavar="PATH.toml", default=None,
                   help="one scene only: write the chosen intermittent point as a [filter] table to paste into "
                        "the scene file (lowest duty among the Pareto points with no violation, no off period "
                        "under 0.25 s and cbf's goals), with the evidence beside it: PATH.json (the sweep) and "
                        "PATH.txt (its table)")
    p.add_argument("--plot", metavar="FIG.png", default=None,
                   help="also draw the Pareto figure (duty vs intervention per scene; .png/.svg/.pdf; "
                        "the plots extra)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(handler=_cmd_sweep)


def _number(flag: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ConfigError(f"{flag}: {text!r} is not a number (give V1,V2,... or LO:HI with --random)") from None


def _points(args: argparse.Namespace) -> list[Any]:
    from isf_robot.arm.sweep import grid_points, random_points

    given = {k: getattr(args, k) for k in _FLAGS if getattr(args, k) is not None}
    if args.random is None:
        grid = {}
        for k, text in given.items():
            if ":" in text:
                raise ConfigError(f"{_FLAGS[k]} {text}: a LO:HI range needs --random N")
            grid[k] = [_number(_FLAGS[k], v) for v in text.split(",") if v.strip()]
        return grid_points(args.filters, grid)
    ranges = {}
    for k, text in given.items():
        lo, sep, hi = text.partition(":")
        if not sep:
            lo = hi = text
        ranges[k] = (_number(_FLAGS[k], lo), _number(_FLAGS[k], hi))
    return random_points(args.filters, ranges, args.random, args.sweep_seed)


def _emit(args: argparse.Namespace, sweep: dict[str, Any]) -> None:
    from isf_robot.arm.sweep import format_sweep

    doc = with_schema("isf-robot-sweep", sweep)
    if args.output:
        write_text_atomic(args.output, json.dumps(doc, indent=1) + "\n")
        print(f"sweep written to {args.output}", file=sys.stderr)
    if args.plot:
        from isf_robot.plots import save_figure

        fig, what = sweep_figure(doc)
        save_figure(fig, args.plot)
        print(f"wrote {args.plot}: {what}", file=sys.stderr)
    print(json.dumps(doc) if args.json else format_sweep(sweep), flush=True)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from isf_robot.arm.sweep import run_sweep

    if args.episodes < 1 or args.seed < 0:
        raise ConfigError(f"--episodes must be >= 1 and --seed >= 0, got {args.episodes} and {args.seed}")
    check_backend(args.backend, args.address)
    if args.output:
        check_output_path(args.output, "--output")
    if args.plot:
        from isf_robot.plots import check_figure_path, require_matplotlib

        check_figure_path(args.plot)
        require_matplotlib()
    specs = _specs(args)
    if args.write_config:
        if len(specs) != 1:
            raise ConfigError(f"--write-config writes one scene's [filter]: give one scene, got {len(specs)}")
        if args.level != "velocity":
            raise ConfigError("--write-config writes the velocity level's [filter] (d_bar in rad/s); sweep the "
                              "torque level without it")
        scene = specs[0].load()
        if scene.arms:
            raise ConfigError(f"--write-config chooses one arm's [filter] by its off periods; {scene.name} has "
                              f"{len(scene.arms)} arms, whose [filter] serves both ways of filtering: sweep it "
                              "without --write-config and read the per-arm table")
        for path in _evidence_paths(args.write_config):
            check_output_path(str(path), "--write-config")
    points = _points(args)
    if args.write_config and not any(strategy_info(pt.strategy).intermittent for pt in points):
        raise ConfigError("--write-config chooses an intermittent point: add an intermittent strategy to "
                          "--filters (e.g. cbf isf)")
    seeds = list(range(args.seed, args.seed + args.episodes))

    def progress(done: int, total: int, task: Any, r: Any) -> None:
        if not args.quiet:
            print(f"[{done}/{total}] {r['scene']} {task.label or points[task.point].label} seed {r['seed']}: duty "
                  f"{r['duty_cycle']:.3f}, switches {r['on_switches']}, {r['wall_s']:.2f} s",
                  file=sys.stderr, flush=True)

    try:
        sweep = run_sweep(specs, points, seeds, duration=args.duration,
                          jobs=args.jobs, d_bar=args.d_bar, progress=progress, backend=args.backend,
                          address=args.address, level=args.level,
                          coordinations=[args.coordination] if args.coordination else None)
    except Interrupted as exc:
        if exc.partial is not None:
            _emit(args, exc.partial)
        raise
    _emit(args, sweep)
    if args.write_config:
        _write_config(args.write_config, sweep)
    return 0


def _specs(args: argparse.Namespace) -> list[Any]:
    from isf_robot.arm.compare import SceneSpec

    files = args.model is not None or args.config is not None
    names = args.scenes if args.scenes is not None else ([] if files else ["panda_pole"])
    specs = [SceneSpec(name=n) for n in names]
    if files:
        specs.append(SceneSpec(model=args.model, config=args.config))  # (both or a one-line error)
    return specs


def _evidence_paths(path: str) -> tuple[Path, Path, Path]:
    """The ``[filter]`` file and its evidence beside it: ``PATH.toml``, ``PATH.json``, ``PATH.txt``."""
    p = Path(path)
    if p.suffix != ".toml":
        raise ConfigError(f"--write-config {path!r}: give a .toml path (the evidence goes beside it as .json and .txt)")
    return p, p.with_suffix(".json"), p.with_suffix(".txt")


def _write_config(path: str, sweep: dict[str, Any]) -> None:
    from isf_robot.arm.sweep import format_sweep
    from isf_robot.arm.tune import filter_section

    toml, js, txt = _evidence_paths(path)
    doc = with_schema("isf-robot-sweep", sweep)
    write_text_atomic(js, json.dumps(doc, indent=1) + "\n")
    write_text_atomic(txt, format_sweep(sweep) + "\n")
    text = filter_section(sweep["scenes"][0], sweep["seeds"], f"{js.name}, {txt.name}")
    write_text_atomic(toml, text)
    print(f"wrote {toml} (the chosen [filter]) and its evidence {js.name}, {txt.name}:\n{text}", file=sys.stderr,
          end="")
