"""Arms sharing a workspace: violations, per-arm duty against cbf, off periods and step cost.

    nice -n 19 python benchmarks/multi_arm_targets.py [--episodes 20] [--jobs 2] \
        [--scenes panda_pair panda_quad] [--cost-repeats 3] [--marker multi_arm] [--cost-only | --no-cost] [--no-write]

For each scene with several arms, ``cbf`` and ``isf`` with each coordination (``central``: one filter over
every arm's joints; ``decentral``: one filter per arm with an equal share of each inter-arm row) on seeds
0..N-1 at the scene's episode length, the scene's shipped parameters (``d_bar`` calibrated), plus
``nominal`` (no filter) to show the tasks collide. Reports per scene and way: violations (physics steps
with a pair below its margin, and penetrating contacts at the control ticks by kind: arm-arm,
arm-obstacle, self), per arm the mean duty cycle, on-switches, intervention, goals reached and missed,
coordination steps and events, and the shortest complete off period of any episode.

Step cost: the wall time of every control step of a 6 s episode (seed 0), each step's least over
``--cost-repeats`` repeats, then the mean over the steps (``arm_bench.py``'s step clock: a burst of another
job stretches one repeat's step, rarely the same step in every repeat), for ``panda_pole`` (one arm) and the
scenes with several arms, each strategy and coordination, the repeats interleaved in one process. Run it
alone on a quiet machine.

Writes the outcome tables into RESULTS.md between ``<!-- MARKER:start -->`` and ``<!-- MARKER:end -->``, and
the step cost into BENCHMARKS.md between ``<!-- team-step:start -->`` and ``<!-- team-step:end -->`` with the
machine, the load and the date (``--cost-only``: the step cost alone; ``--no-cost``: the tables alone;
``--no-write``: print only).
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import cpu_model, write_section  # noqa: E402

WAYS = ("central", "decentral")


def _episode(job: tuple[str, str, str, int, float | None]) -> dict[str, Any]:
    from isf_robot.arm import load_scene
    from isf_robot.arm.multi_arm import run_team
    from isf_robot.arm.params import resolve_params

    name, strategy, way, seed, duration = job
    scene = load_scene(name)
    r = run_team(scene, strategy, way, duration=duration, seed=seed, params=resolve_params(scene))
    return {"scene": name, "strategy": strategy, "way": way, "seed": seed, "violations": r.violations,
            "collisions": r.run.collisions, "contacts": r.contacts, "min_barrier": r.run.min_barrier,
            "arms": list(r.arms), "fallbacks": r.run.stats.fallbacks}


def _fmt(x: Any, spec: str = ".3f") -> str:
    return "-" if x is None else format(x, spec)


def outcome_table(rows: list[dict[str, Any]], scene: str) -> str:
    out = [f"**{scene}**", "",
           "| strategy | way | violations (steps / arm-arm / arm-obstacle / self contacts) | min h [m] | arm | duty "
           "| duty / cbf | on sw | min off [s] | intervention | goals (missed) | coordination steps (events) |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    keys = [("nominal", WAYS[0])] + [(s, w) for s in ("cbf", "isf") for w in WAYS]
    for strategy, way in keys:
        eps = [r for r in rows if r["scene"] == scene and r["strategy"] == strategy and r["way"] == way]
        if not eps:
            continue
        cbf = [r for r in rows if r["scene"] == scene and r["strategy"] == "cbf" and r["way"] == way]
        viol = (f"{sum(r['violations'] for r in eps)} ({sum(r['collisions'] for r in eps)} / "
                + " / ".join(str(sum(r["contacts"][k] for r in eps)) for k in ("arm-arm", "arm-obstacle", "self"))
                + ")")
        for i, arm in enumerate(eps[0]["arms"]):
            def mean(key: str, group: list[dict[str, Any]] = eps, i: int = i) -> float:
                return statistics.fmean(r["arms"][i][key] for r in group)

            offs = [r["arms"][i]["min_off_s"] for r in eps if r["arms"][i]["min_off_s"] is not None]
            ratio = (mean("duty_cycle") / mean("duty_cycle", cbf)) if cbf and strategy != "nominal" and mean(
                "duty_cycle", cbf) > 0 else None
            head = (f"| {strategy} | {way if strategy != 'nominal' else '-'} | {viol} | "
                    f"{min(r['min_barrier'] for r in eps):.4f} |") if i == 0 else "| | | | |"
            out.append(f"{head} {arm['name']} | {mean('duty_cycle'):.3f} | {_fmt(ratio, '.2f')} | "
                       f"{mean('on_switches'):.1f} | {_fmt(min(offs) if offs else None)} | "
                       f"{mean('intervention'):.3f} | {mean('goals_reached'):.1f} ({mean('goals_missed'):.1f}) | "
                       f"{mean('coordination_steps'):.0f} ({mean('coordination_events'):.1f}) |")
    return "\n".join(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scenes", nargs="+", default=["panda_pair", "panda_quad"])
    ap.add_argument("--duration", type=float, default=None, help="episode length [s] (default: the scene's)")
    ap.add_argument("--cost-repeats", type=int, default=3)
    ap.add_argument("--marker", default="multi_arm")
    ap.add_argument("--cost-only", action="store_true", help="measure the step cost only (BENCHMARKS.md)")
    ap.add_argument("--no-cost", action="store_true", help="the outcome tables only (RESULTS.md)")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()

    if not args.cost_only:
        jobs = [(s, st, w, seed, args.duration) for s in args.scenes for st in ("nominal", "cbf", "isf")
                for w in (WAYS if st != "nominal" else WAYS[:1]) for seed in range(args.episodes)]
        with ProcessPoolExecutor(args.jobs) as pool:
            rows = list(pool.map(_episode, jobs))
        lines = [f"Measured {datetime.date.today()} on {cpu_model()}: {args.episodes} seeds per row, the scenes' "
                 "episode length, shipped parameters (`d_bar` calibrated). Regenerate with "
                 f"`nice -n 19 python benchmarks/multi_arm_targets.py --episodes {args.episodes}`; the step cost is "
                 "in BENCHMARKS.md.", ""]
        for s in args.scenes:
            lines += [outcome_table(rows, s), ""]
        body = "\n".join(lines).rstrip()
        print(body)
        if not args.no_write:
            write_section(ROOT / "RESULTS.md", f"<!-- {args.marker}:start -->", f"<!-- {args.marker}:end -->", body)
    if args.no_cost:
        return 0
    cost = step_cost(args.scenes, args.cost_repeats)
    print(cost)
    if not args.no_write:
        write_section(ROOT / "BENCHMARKS.md", "<!-- team-step:start -->", "<!-- team-step:end -->", cost)
    return 0


def step_cost(scenes: list[str], repeats: int) -> str:
    """The step-cost section: one arm against the scenes with several arms, each strategy and way."""
    from arm_bench import clocked, combine  # (benchmarks/ is on sys.path)

    from isf_robot.arm import load_scene
    from isf_robot.arm.multi_arm import MultiArmSimulation
    from isf_robot.arm.params import resolve_params

    load = os.getloadavg()
    configs = [(st, None, None) for st in ("cbf", "isf")] + [
        (st, sc, w) for st in ("cbf", "isf") for sc in scenes for w in WAYS]
    scenes_by_name = {name: load_scene(name) for name in ["panda_pole", *scenes]}
    params = {name: resolve_params(sc) for name, sc in scenes_by_name.items()}

    def run(st: str, sc: str | None, w: str | None, duration: float) -> Any:
        name = sc or "panda_pole"
        if sc is None:
            return clocked(scenes_by_name[name], st, params[name], duration, None)[0]
        return clocked(scenes_by_name[name], st, params[name], duration, None, MultiArmSimulation, coordination=w)[0]

    for cfg in configs:  # (warm-up: every compiled kernel a configuration uses is loaded before the timing)
        run(*cfg, 0.5)
    clocks: dict[tuple[str, str | None, str | None], list[Any]] = {cfg: [] for cfg in configs}
    for _ in range(repeats):  # (one process; the configurations interleaved, so load changes hit all alike)
        for cfg in configs:
            clocks[cfg].append(run(*cfg, 6.0))
    cost, mj = {}, {}
    for (st, sc, w), cs in clocks.items():
        key = f"panda_pole {st}" if sc is None else f"{sc} {st} {w}"
        cost[key], _, mj[key] = combine(cs)
    after = os.getloadavg()
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    lines = ["## Arms sharing a workspace: the control step (`benchmarks/multi_arm_targets.py --cost-only`)", "",
             f"Machine: {platform.platform()}; CPU {cpu_model()}; {os.cpu_count()} cores; Python "
             f"{platform.python_version()}. Date (UTC): {now}. Load average before: {load[0]:.2f}, {load[1]:.2f}, "
             f"{load[2]:.2f}; after: {after[0]:.2f}, {after[1]:.2f}, {after[2]:.2f}.", "",
             "Wall time per control step (everything the loop does: physics, rows, nominal, filter, accounting) of "
             f"a 6 s episode, seed 0: each step's least time over {repeats} repeats, then the mean over the steps "
             "(the step clock of `arm_bench.py`), the repeats of every configuration interleaved in one process; "
             "`mj_step` timed the same way on copies of each episode's states. Targets: two arms <= 2.2x one arm's "
             "step (the same strategy, same run); four arms <= 0.5 ms.", "",
             "| run | us / step | x one arm (same strategy) | mj_step [us] |", "|---|---|---|---|"]
    for key, us in cost.items():
        st = key.split()[1]
        lines.append(f"| {key} | {us:.0f} | {us / cost[f'panda_pole {st}']:.2f} | {mj[key]:.1f} |")
    lines += ["", "Reproduce: `python benchmarks/multi_arm_targets.py --cost-only` (add `--no-write` to only print)."]
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
