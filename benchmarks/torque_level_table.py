"""Velocity level against torque level on the shipped Panda and UR5e scenes (RESULTS.md, "Torque level").

Usage::

    python benchmarks/torque_level_table.py [--seeds N] [--duration S] [--jobs K] [--json PATH]

For every scene and level it runs ``isf-robot compare --level {velocity,torque} --filters nominal cbf isf``
(the same library call, :func:`isf_robot.arm.compare.compare_strategies`, seeds 0 .. N-1, each level's
``d_bar`` calibrated as a user gets it) and prints one Markdown table per scene: duty cycle, on
switches, shortest off period, intervention (in the level's units), goals, time to the last goal,
model or tracking error against ``d_bar``, collisions (true geometry, every physics step), fallbacks,
the largest torque against its limit (torque level) and the wall time per simulated second. The torque
level has the arm's self-collision rows on whatever the scene says
(:class:`~isf_robot.arm.torque_sim.TorqueSimulation`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

SCENES = ("panda_pole", "panda_shelf", "panda_moving", "panda_servo", "ur5e_pole")
LEVELS = ("velocity", "torque")
STRATEGIES = ("nominal", "cbf", "isf")


def _row(level: str, strategy: str, runs: list[dict]) -> list[str]:
    def mean(key: str) -> float | None:
        vals = [r[key] for r in runs if r.get(key) is not None]
        return sum(vals) / len(vals) if vals else None

    def worst(key: str, fn=min) -> float | None:  # type: ignore[no-untyped-def]
        vals = [r[key] for r in runs if r.get(key) is not None]
        return fn(vals) if vals else None

    def f(v: float | None, fmt: str) -> str:
        return "-" if v is None else format(v, fmt)

    last_goal = [r["goal_times_s"][-1] for r in runs if r.get("goal_times_s")]
    covered = sum(bool(r["d_bar_covered"]) for r in runs)
    wall = sum(r["wall_s"] for r in runs) / sum(r["duration_s"] for r in runs)
    return [level, strategy, f(mean("duty_cycle"), ".3f"), f(mean("on_switches"), ".1f"),
            f(worst("min_off_s"), ".3f"), f(mean("intervention"), ".3g"), f(mean("goals_reached"), ".2f"),
            f(sum(last_goal) / len(last_goal) if last_goal else None, ".2f"),
            f"{mean('tracking_error_q99'):.3g} / {runs[0]['d_bar']:.3g} ({covered}/{len(runs)})",
            str(sum(r["collisions"] for r in runs)), f(worst("min_barrier"), ".4f"),
            str(sum(r["fallbacks"] for r in runs)), f(worst("tau_peak_ratio", max), ".2f"), f(wall, ".2f")]


HEADER = ["level", "strategy", "duty", "switches", "min off [s]", "intervention", "goals", "last goal [s]",
          "error q99 / d_bar (covered)", "collision steps", "min h [m]", "fallbacks", "max tau/limit",
          "wall / sim s"]


def main(argv: list[str] | None = None) -> int:
    """Run the comparisons and print the tables (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--duration", type=float, default=8.0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--json", type=Path, default=None, help="also write every run's JSON here")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    from isf_robot.arm.compare import SceneSpec, compare_strategies

    out: dict[str, dict] = {}
    print(f"seeds 0..{args.seeds - 1}, {args.duration:g} s per episode; error: tracking |q_dot - u| [rad/s] "
          "(velocity) or model error |q_ddot - (a0 + Minv tau)| [rad/s^2] (torque), q99 per episode (mean) against "
          "d_bar; intervention in [rad^2/s] (velocity) or [N^2 m^2 s] (torque)\n")
    for scene in args.scenes:
        rows = []
        for level in LEVELS:
            t0 = time.perf_counter()
            comp = compare_strategies(SceneSpec(name=scene), args.seeds, strategies=list(STRATEGIES),
                                      duration=args.duration, jobs=args.jobs, level=level)
            print(f"[{scene} {level}: {time.perf_counter() - t0:.0f} s]", file=sys.stderr, flush=True)
            d = comp.as_dict()
            out[f"{scene}/{level}"] = d
            if args.json is not None:  # after every comparison, so a long run that is cut short keeps what it has
                args.json.write_text(json.dumps(out))
            for s in STRATEGIES:
                rows.append(_row(level, s, d["results"][s]["episodes"]))
        print(f"### {scene}\n")
        print("| " + " | ".join(HEADER) + " |")
        print("|" + "---|" * len(HEADER))
        for r in rows:
            print("| " + " | ".join(r) + " |")
        print(flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
