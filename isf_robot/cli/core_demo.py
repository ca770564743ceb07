"""``isf-robot core-demo``: the engine-free core demo (:mod:`isf_robot.demo_core`) from the command line."""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from isf_robot.core.exceptions import ConfigError
from isf_robot.support.report import with_schema

__all__ = ["register", "add_arguments", "handle"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``core-demo``."""
    p.add_argument("--episodes", type=int, default=5, help="number of seeds (default 5)")
    p.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    p.add_argument("--duration", type=float, default=20.0, help="episode length [s] (default 20)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")


def handle(args: argparse.Namespace) -> int:
    """Run the core demo."""
    if args.episodes < 1:
        raise ConfigError(f"--episodes must be >= 1, got {args.episodes}")
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise ConfigError(f"--duration must be a finite number > 0, got {args.duration}")
    if args.seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {args.seed}")
    from isf_robot.demo_core import MAX_STEPS

    if args.duration / 0.01 > MAX_STEPS:
        raise ConfigError(f"--duration {args.duration:g} s is more than {MAX_STEPS:.0e} steps of 0.01 s")
    seeds = list(range(args.seed, args.seed + args.episodes))
    if not args.json:
        print(f"core demo: planar single integrator past 4 discs, {len(seeds)} seeds, "
              f"{args.duration:g} s each, dt = 0.01 s", file=sys.stderr)
    from isf_robot.demo_core import compare, format_table

    results = compare(seeds, duration=args.duration)
    if args.json:
        print(json.dumps(with_schema("isf-robot-core-demo", {"episodes": len(seeds), "results": results})))
    else:
        print(format_table(results))
    return 0


def register(sub: Any) -> None:
    """Register ``core-demo``."""
    p = sub.add_parser(
        "core-demo",
        help="planar single integrator past discs: no filter vs standard vs intermittent filter",
        description="Run the engine-free core demo on the same seeds three ways and print a comparison table.",
    )
    add_arguments(p)
    p.set_defaults(handler=handle)
