"""``isf-satellite tau``: time-to-trigger data over the band and the fitted ``tau_p(h)``."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from isf_robot.core import ConfigError
from isf_robot.support.files import write_text_atomic
from satellite.cli.run import add_controller_args, control_from_args
from satellite.control.tau import DEFAULT_RADII, collect_tau, distinct_h_levels, fit_tau, tau_document
from satellite.gravity.fields import DEFAULT_GRAVITY, GRAVITY_MODELS, load_field
from satellite.orbit.model import OrbitModel

__all__ = ["register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``tau`` subcommand."""
    p = subparsers.add_parser(
        "tau",
        help="collect inter-event times per radius and fit tau_p(h)",
        description=(
            "For radii 1.60, 1.65, ..., 2.40 R and N random states per radius, apply the "
            "safeguarding controller, propagate to the greedy trigger, record the time; write the "
            "samples, the median per radius and a polynomial fit tau_p(h) to JSON."
        ),
    )
    p.add_argument("--samples", type=int, default=100, metavar="N", help="random states per radius (default 100)")
    p.add_argument("--out", required=True, metavar="FILE.json", help="output file")
    p.add_argument("--workers", type=int, default=None, help="processes (default: all cores)")
    p.add_argument("--seed", type=int, default=0, help="base seed (default 0)")
    p.add_argument("--max-hours", type=float, default=100.0, help="censoring time per sample in hours (default 100)")
    p.add_argument("--degree", type=int, default=2, help="degree of the polynomial fit in h (default 2)")
    p.add_argument("--disturbance-scale", type=float, default=1.0, metavar="K",
                   help="experiment: scale the non-Kepler gravity by K (default 1, the full field)")
    p.add_argument("--no-spin", action="store_true", help="freeze the body")
    p.add_argument("--gravity", default=DEFAULT_GRAVITY, metavar="{" + ",".join(GRAVITY_MODELS) + "}|FILE.json",
                   help="truth gravity (default table: the exact polyhedron field, tabulated; see run --help)")
    p.add_argument("--alpha-gain", type=float, default=None, metavar="PER_S",
                   help="alpha gain (default: mean motion at 2R)")
    p.add_argument("--d-bar", type=float, default=0.0, help="disturbance bound used in Xi (default 0)")
    add_controller_args(p)
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``isf-satellite tau``; return the exit status."""
    if args.samples < 1:
        raise ConfigError(f"--samples must be >= 1, got {args.samples}")
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {args.workers}")
    if not (math.isfinite(args.max_hours) and args.max_hours > 0):
        raise ConfigError(f"--max-hours must be positive, got {args.max_hours:g}")
    if not (math.isfinite(args.disturbance_scale) and args.disturbance_scale >= 0):
        raise ConfigError(f"--disturbance-scale must be >= 0, got {args.disturbance_scale:g}")

    levels = distinct_h_levels(DEFAULT_RADII)
    if not 1 <= args.degree < levels:
        raise ConfigError(f"--degree must be between 1 and {levels - 1} (the radius grid gives {levels} "
                          f"distinct barrier levels), got {args.degree}")
    out = Path(args.out)
    if not out.parent.is_dir():
        raise ConfigError(f"output directory does not exist: {out.parent}")
    field = load_field(args.gravity)  # fails here, once, on a bad name
    control = control_from_args(args)
    data = collect_tau(args.samples, seed=args.seed, workers=args.workers, spin=not args.no_spin,
                       control=control, max_hours=args.max_hours,
                       disturbance_scale=args.disturbance_scale, gravity=args.gravity)
    model = OrbitModel(field, spin=not args.no_spin)
    fit = fit_tau(data, model.h_max, model.R, args.degree)
    settings = {"alpha_gain": args.alpha_gain, "d_bar": args.d_bar, "degree": args.degree,
                "disturbance_scale": args.disturbance_scale, "gravity": args.gravity,
                "controller": control.controller}
    if control.controller == "shooting":
        settings["shooting"] = control.shooting.describe()
    write_text_atomic(out, json.dumps(tau_document(data, fit, settings), indent=1) + "\n")
    if not args.quiet:
        sys.stdout.write(f"wrote {out}: {args.samples} samples x {len(data.radii_over_R)} radii, "
                         f"{data.wall_s:.1f} s on {data.workers} workers\n")
        sys.stdout.write("r/R     median_h  censored  tau_p_h(fit)\n")
        for r, med, cen in zip(data.radii_over_R, data.medians_h, data.censored):
            h = model.h_max - ((r - 2.0) * model.R) ** 2
            sys.stdout.write(f"{r:5.2f}  {med:8.3f}  {int(cen):8d}  {fit.tau_p(h) / 3600:8.3f}\n")
    return 0
