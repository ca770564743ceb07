"""Velocity level against torque level on the shipped Panda and UR5e scenes (RESULTS.md, "Torque level").

Usage::

    python benchmarks/torque_level_table.py [--seeds N] [--duration S] [--jobs K] [--json PATH]
                                            [--levels velocity torque] [--tables-from PATH ...]

For every scene and level it runs ``isf-robot compare --level {velocity,torque} --filters nominal cbf isf``
(the same library call, :func:`isf_robot.arm.compare.compare_strategies`, seeds 0 .. N-1, each level's
``d_bar`` calibrated as a user gets it) and prints one Markdown table per scene: duty cycle, on
switches, shortest off period, intervention (in the level's units), goals, time to the last goal,
model or tracking error against ``d_bar``, collisions (true geometry, every physics step), fallbacks,
the largest torque against its limit (torque level) and the wall time per simulated second. The torque
level has the arm's self-collision rows on whatever the scene says
(:class:`~isf_robot.arm.torque_sim.TorqueSimulation`). Below each table: per level and filter, the
shortest off period of each episode (worst, median) and the episodes where it is under 0.25 s.

``--levels torque`` runs one level only; ``--tables-from A.json B.json`` runs nothing and prints the
tables from saved ``--json`` files (a later file's ``scene/level`` entries replace an earlier one's:
the velocity rows of one run with the torque rows of another).

``--vary NAME=V1,V2,...`` instead runs the intermittent filter alone at the torque level with each value of
one design option (any parameter ``isf-robot sweep`` takes: ``horizon``, ``off_hold``, ...), everything
else as designed, through :func:`isf_robot.arm.sweep.run_sweep` (the same as ``isf-robot sweep --level
torque --filters isf --NAME V1,V2``), and prints one table of all scenes: duty, switches, intervention,
goals, the worst shortest off period, the episodes and the off periods under 0.25 s, fallbacks and
collision steps (RESULTS.md "The predictive horizon at the torque level" and "The off hold").
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


def _offs(level: str, strategy: str, runs: list[dict]) -> str:
    """Each episode's shortest off period: the worst, the median, the episodes under 0.25 s."""
    per = sorted(r["min_off_s"] for r in runs if r.get("min_off_s") is not None)
    if not per:
        return f"{level} {strategy}: no complete off period"
    short = sum(x < 0.25 for x in per)
    return (f"{level} {strategy}: shortest off per episode worst {per[0]:.3f} s, median {per[len(per) // 2]:.3f} s, "
            f"under 0.25 s in {short} of {len(runs)} episodes")


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
    ap.add_argument("--levels", nargs="+", default=list(LEVELS), choices=LEVELS)
    ap.add_argument("--tables-from", nargs="+", type=Path, default=None,
                    help="run nothing: print the tables from these --json files (later files win)")
    ap.add_argument("--vary", default=None, metavar="NAME=V1,V2",
                    help="isf at the torque level with each value of one design option (e.g. horizon=0,0.26,0.5)")
    args = ap.parse_args(argv)
    if args.vary:
        return _vary(args)
    if args.tables_from:
        saved: dict[str, dict] = {}
        for path in args.tables_from:
            saved.update(json.loads(path.read_text()))
        scenes = [s for s in args.scenes if any(f"{s}/{lv}" in saved for lv in LEVELS)]
        for scene in scenes:
            _table(scene, {lv: saved[f"{scene}/{lv}"] for lv in LEVELS if f"{scene}/{lv}" in saved})
        return 0
    warnings.simplefilter("ignore")
    from isf_robot.arm.compare import SceneSpec, compare_strategies

    out: dict[str, dict] = {}
    print(f"seeds 0..{args.seeds - 1}, {args.duration:g} s per episode; error: tracking |q_dot - u| [rad/s] "
          "(velocity) or model error |q_ddot - (a0 + Minv tau)| [rad/s^2] (torque), q99 per episode (mean) against "
          "d_bar; intervention in [rad^2/s] (velocity) or [N^2 m^2 s] (torque)\n")
    for scene in args.scenes:
        done = {}
        for level in args.levels:
            t0 = time.perf_counter()
            comp = compare_strategies(SceneSpec(name=scene), args.seeds, strategies=list(STRATEGIES),
                                      duration=args.duration, jobs=args.jobs, level=level)
            print(f"[{scene} {level}: {time.perf_counter() - t0:.0f} s]", file=sys.stderr, flush=True)
            done[level] = out[f"{scene}/{level}"] = comp.as_dict()
            if args.json is not None:  # after every comparison, so a long run that is cut short keeps what it has
                args.json.write_text(json.dumps(out))
        _table(scene, done)
    return 0


def _vary(args: argparse.Namespace) -> int:
    """``--vary NAME=V1,V2``: isf at the torque level per value, one table over the scenes (module docstring)."""
    warnings.simplefilter("ignore")
    from isf_robot.arm.compare import SceneSpec
    from isf_robot.arm.sweep import PARAMETERS, SweepPoint, run_sweep

    name, sep, text = args.vary.partition("=")
    if not sep or name not in PARAMETERS:
        raise SystemExit(f"--vary NAME=V1,V2: NAME one of {', '.join(PARAMETERS)}; got {args.vary!r}")
    values = [float(v) for v in text.split(",") if v.strip()]
    points = [SweepPoint("isf", {name: v}) for v in values]
    t0 = time.perf_counter()
    sweep = run_sweep([SceneSpec(name=s) for s in args.scenes], points, list(range(args.seeds)),
                      duration=args.duration, jobs=args.jobs, level="torque")
    print(f"[{time.perf_counter() - t0:.0f} s]", file=sys.stderr, flush=True)
    if args.json is not None:
        args.json.write_text(json.dumps(sweep))
    head = ["scene", name, "duty", "switches", "intervention [N^2 m^2 s]", "goals", "shortest off: worst [s]",
            "episodes < 0.25 s", "off periods < 0.25 s", "fallbacks", "collision steps"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for scene in sweep["scenes"]:
        for pt in scene["points"]:
            runs = pt["runs"]
            offs = [r["min_off_s"] for r in runs if r.get("min_off_s") is not None]
            mean = {k: sum(float(r[k]) for r in runs) / len(runs)
                    for k in ("duty_cycle", "on_switches", "intervention", "goals_reached")}
            print(f"| {scene['scene']} | {pt['values'][name]:g} | {mean['duty_cycle']:.3f} | "
                  f"{mean['on_switches']:.1f} | {mean['intervention']:.3g} | {mean['goals_reached']:.2f} | "
                  + (f"{min(offs):.3f}" if offs else "-")
                  + f" | {sum(x < 0.25 for x in offs)} of {len(runs)} | {sum(int(r['short_offs']) for r in runs)} | "
                  f"{sum(int(r['fallbacks']) for r in runs)} | {sum(int(r['collisions']) for r in runs)} |")
    return 0


def _table(scene: str, by_level: dict[str, dict]) -> None:
    """Print one scene's table (the levels in ``by_level``) and its off-period lines."""
    print(f"### {scene}\n")
    print("| " + " | ".join(HEADER) + " |")
    print("|" + "---|" * len(HEADER))
    for level, d in by_level.items():
        for s in STRATEGIES:
            print("| " + " | ".join(_row(level, s, d["results"][s]["episodes"])) + " |")
    print()
    for level, d in by_level.items():
        for s in STRATEGIES[1:]:
            print(f"* {_offs(level, s, d['results'][s]['episodes'])}")
    print(flush=True)


if __name__ == "__main__":
    sys.exit(main())
