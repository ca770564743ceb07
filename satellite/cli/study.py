"""``isf-satellite study``: paired orbits for every trigger x controller, reductions with 95 % CIs."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from isf_robot.core import ConfigError
from isf_robot.support.extras import install_hint
from isf_robot.support.parallel import BACKENDS, MAX_JOBS, Interrupted, check_backend
from isf_robot.support.report import with_schema
from satellite.control.tau import load_tau
from satellite.gravity.fields import DEFAULT_GRAVITY, GRAVITY_MODELS, load_field
from satellite.study.paired import STUDY_TRIGGERS, StudySettings, StudyTask, controllers, plan, run_study
from satellite.study.stats import format_study

__all__ = ["register", "run", "parse_tau"]

SCHEMA = "isf-satellite-study"


def register(subparsers: Any) -> None:
    """Add the ``study`` subcommand."""
    p = subparsers.add_parser(
        "study",
        help="paired orbits: greedy / maneuver / periodic x controllers from the same starts, with 95 %% CIs",
        description=(
            "Flies every configuration (trigger x controller) from the same starts (seed x inclination) and "
            "compares them orbit by orbit: mean paired reduction of impulses and delta-v with a 95 % "
            "confidence interval (paired t; percentile bootstrap beside it), min h, band exits and surface "
            "contacts per configuration. Progress on stderr; Ctrl-C stops the workers and keeps what finished."
        ),
    )
    p.add_argument("--hours", type=float, default=2400.0, help="simulated time per orbit (default 2400, the paper's)")
    p.add_argument("--seeds", type=int, default=17, metavar="N", help="seeds per inclination (default 17)")
    p.add_argument("--first-seed", type=int, default=0, metavar="S", help="seeds S..S+N-1 (default 0)")
    p.add_argument("--inclinations", type=float, nargs="+", default=[15.0, 45.0, 75.0], metavar="DEG",
                   help="inclinations to the equator; every seed with every one (default 15 45 75: 51 starts)")
    p.add_argument("--triggers", nargs="+", default=list(STUDY_TRIGGERS), metavar="T",
                   help=f"triggers to compare, of {', '.join(STUDY_TRIGGERS)} (default all)")
    p.add_argument("--controllers", nargs="+", default=["kepler"], metavar="C",
                   help=f"safeguarding controllers, of {', '.join(controllers())} (default kepler)")
    p.add_argument("--period-h", type=float, nargs="+", default=[0.25], metavar="HOURS",
                   help="periods of the periodic baseline (default 0.25: the longest that kept 5 of 5 "
                        "240 h orbits in the band)")
    p.add_argument("--tau", action="append", default=[], metavar="[CONTROLLER=]FILE",
                   help="tau_p file from `isf-satellite tau` for the maneuver trigger; FILE for every "
                        "controller or CONTROLLER=FILE (repeat)")
    p.add_argument("--gravity", default=DEFAULT_GRAVITY,
                   metavar="{" + ",".join(GRAVITY_MODELS) + "}|FILE.json|FILE.npz",
                   help="truth gravity (default table: the exact polyhedron field, tabulated)")
    p.add_argument("--no-spin", action="store_true", help="freeze the body")
    p.add_argument("--disturbance-scale", type=float, default=1.0, metavar="K",
                   help="experiment: scale the non-Kepler gravity by K (default 1)")
    p.add_argument("--alpha-gain", type=float, default=None, metavar="PER_S",
                   help="alpha(h) = gain * h (default: mean motion at 2R)")
    p.add_argument("--surface-barrier", action="store_true",
                   help="greedy and maneuver runs add the surface-clearance barrier (as `isf-satellite run "
                        "--surface-barrier`); without it contact with the surface is counted, not prevented")
    p.add_argument("--rtol", type=float, default=1e-10, help="integrator rtol (default 1e-10)")
    p.add_argument("--jobs", type=int, default=1, metavar="K",
                   help="worker processes, or Ray tasks in flight (default 1)")
    p.add_argument("--backend", default="processes", metavar="{" + ",".join(BACKENDS) + "}",
                   help=f"processes (default) or ray (the optional 'ray' extra: {install_hint('ray')})")
    p.add_argument("--address", default=None, metavar="ADDR",
                   help="with --backend ray: cluster to join ('auto' or HOST:PORT; default a local instance)")
    p.add_argument("--out", metavar="FILE.json",
                   help="write the study here (atomically; rewritten after every finished orbit, marked partial)")
    p.add_argument("--resume", action="store_true",
                   help="with --out: keep the finished orbits of that file (same settings; maneuver runs only "
                        "with the same tau file) and run the rest, e.g. configurations added since")
    p.add_argument("--json", action="store_true", help="print the JSON document on stdout instead of the table")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=run)


def parse_tau(items: list[str], ctrls: list[str]) -> dict[str, str]:
    """``--tau`` values as ``{controller: file}`` (a bare FILE applies to every controller).

    Raises:
        ConfigError: Unknown controller, two files for one controller, a file that is not a tau file.

    """
    out: dict[str, str] = {}
    for item in items:
        name, sep, path = item.partition("=")
        targets = [name] if sep and name in controllers() else list(ctrls)
        if sep and name not in controllers():
            if Path(item).exists():  # a file whose name has '='
                path = item
            else:
                raise ConfigError(f"--tau {item!r}: unknown controller {name!r}; valid: {', '.join(controllers())}")
        if not sep:
            path = item
        load_tau(path)  # one-line error for a missing or bad file, before anything runs
        for t in targets:
            if t in out and out[t] != path:
                raise ConfigError(f"two tau files for controller {t}: {out[t]} and {path}")
            out[t] = path
    return out


def _resumed(path: str, settings: StudySettings) -> list[dict[str, Any]]:
    p = Path(path)
    if not p.exists():
        return []
    try:
        doc = json.loads(p.read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"--resume: cannot read {path}: {exc}") from None
    if not isinstance(doc, dict) or not str(doc.get("schema", "")).startswith(SCHEMA + "/"):
        raise ConfigError(f"--resume: {path} is not an isf-satellite study file")
    old = dict(doc.get("settings") or {})
    old.setdefault("surface_barrier", False)  # files written before the option
    new = json.loads(json.dumps(settings.as_dict()))
    old_tau, new_tau = old.pop("tau", {}) or {}, new.pop("tau")
    if old != new:
        raise ConfigError(f"--resume: {path} was made with other settings ({old}); "
                          "use the same options or another --out")
    # the tau files only matter to maneuver runs: keep those flown with the same file
    return [r for r in doc.get("runs", []) if not str(r.get("config", "")).startswith("maneuver/")
            or old_tau.get(r["config"].split("/", 1)[1]) == new_tau.get(r["config"].split("/", 1)[1])]


def run(args: argparse.Namespace) -> int:
    """Execute ``isf-satellite study``; return the exit status."""
    from isf_robot.support.files import check_output_path, write_text_atomic

    if args.seeds < 1 or args.first_seed < 0:
        raise ConfigError(f"--seeds must be >= 1 and --first-seed >= 0, got {args.seeds} and {args.first_seed}")
    if not math.isfinite(args.hours) or args.hours <= 0:
        raise ConfigError(f"--hours must be a finite number > 0, got {args.hours:g}")
    for inc in args.inclinations:
        if not 0.0 <= inc <= 180.0:
            raise ConfigError(f"--inclinations must lie in [0, 180] degrees, got {inc:g}")
    if not 1 <= args.jobs <= MAX_JOBS:
        raise ConfigError(f"--jobs must be between 1 and {MAX_JOBS}, got {args.jobs}")
    if not (math.isfinite(args.rtol) and 0 < args.rtol < 1e-3):
        raise ConfigError(f"--rtol must be in (0, 1e-3), got {args.rtol:g}")
    if args.resume and not args.out:
        raise ConfigError("--resume needs --out FILE (the study to continue)")
    check_backend(args.backend, args.address)
    periods = args.period_h if "periodic" in args.triggers else []
    configs = plan(args.triggers, args.controllers, periods)
    if args.tau and "maneuver" not in args.triggers:
        raise ConfigError("--tau goes with the maneuver trigger")
    tau = parse_tau(args.tau, args.controllers) if "maneuver" in args.triggers else {}
    if "maneuver" in args.triggers:
        missing = [c for c in args.controllers if c not in tau]
        if missing:
            raise ConfigError(f"the maneuver trigger needs a tau_p file for {', '.join(missing)}: --tau FILE or "
                              f"--tau CONTROLLER=FILE (make one with `isf-satellite tau --out FILE`)")
    load_field(args.gravity)
    settings = StudySettings(hours=float(args.hours), gravity=args.gravity, spin=not args.no_spin,
                             disturbance_scale=args.disturbance_scale, alpha_gain=args.alpha_gain,
                             rtol=args.rtol, tau=tau, surface_barrier=args.surface_barrier)
    if args.out:
        check_output_path(args.out, "--out")
    done_runs = _resumed(args.out, settings) if args.resume else []
    starts = [(s, float(i)) for s in range(args.first_seed, args.first_seed + args.seeds)
              for i in dict.fromkeys(args.inclinations)]  # seed by seed: every inclination as it goes

    def save(doc: dict[str, Any]) -> None:
        if args.out:
            write_text_atomic(args.out, json.dumps(with_schema(SCHEMA, doc), indent=1) + "\n")

    def progress(done: int, total: int, task: StudyTask, r: dict[str, Any]) -> None:
        if not args.quiet:
            exit_note = f", left the band at {r['left_band_h']:.3g} h" if r["left_band_h"] is not None else ""
            print(f"[{done}/{total}] {r['config']} seed {r['seed']} inc {r['inclination_deg']:g}: "
                  f"{r['triggers']} impulses, min h {r['min_h']:.4g}, {r['surface_contacts']} contacts"
                  f"{exit_note}, {r['wall_s']:.1f} s", file=sys.stderr, flush=True)

    def emit(doc: dict[str, Any]) -> None:
        save(doc)
        if args.out and not args.quiet:
            print(f"study written to {args.out}", file=sys.stderr)
        print(json.dumps(with_schema(SCHEMA, doc)) if args.json else format_study(doc), flush=True)

    try:
        doc = run_study(configs, starts, settings, jobs=args.jobs, backend=args.backend, address=args.address,
                        done_runs=done_runs, progress=progress, checkpoint=save)
    except Interrupted as exc:
        if exc.partial is not None:
            emit(exc.partial)
        raise
    emit(doc)
    return 0
