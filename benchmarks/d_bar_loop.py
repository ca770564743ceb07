"""d_bar with the filter in the loop against the open-loop calibration (issue 13, item 4), to RESULTS.md.

    nice -n 19 python benchmarks/d_bar_loop.py [--scenes ...] [--strategies cbf isf] [--eval-seeds 10-13]
        [--duration 6] [--jobs 1] [--no-write]

Per scene and strategy: the open-loop ``d_bar`` (:func:`~isf_robot.arm.calibration.calibrate_d_bar`, the
scenes' shipped filter parameters), the in-loop ``d_bar``
(:func:`~isf_robot.arm.calibration_loop.calibrate_in_loop`, its default seeds 0-5, 6 s), and, on held-out
seeds (not used by either calibration), the tracking error q99 each produces, how many episodes the
``d_bar`` in use covers, violations on the true geometry, duty cycle and goals with each.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import cpu_model, write_section  # noqa: E402

from isf_robot.arm import ArmSimulation, load_scene  # noqa: E402
from isf_robot.arm.calibration_loop import calibrate_in_loop  # noqa: E402
from isf_robot.arm.params import resolve_params  # noqa: E402
from isf_robot.support.files import write_text_atomic  # noqa: E402
from isf_robot.support.parallel import Interrupted, run_tasks  # noqa: E402

START, END = "<!-- d_bar_loop:start -->", "<!-- d_bar_loop:end -->"


def run_combo(task: dict[str, Any]) -> dict[str, Any]:
    """Calibrate in the loop and evaluate both d_bar on the held-out seeds (a worker's function)."""
    scene = load_scene(task["scene"])
    t0 = time.perf_counter()
    p0 = resolve_params(scene)
    cal = calibrate_in_loop(scene, task["strategy"], p0)
    out: dict[str, Any] = {"scene": task["scene"], "strategy": task["strategy"], "calibration": cal.as_dict()}
    for label, d in (("open", p0.d_bar), ("loop", cal.d_bar)):
        p = resolve_params(scene, d_bar=d)
        runs = [ArmSimulation(scene, task["strategy"], seed=s, params=p).run(task["duration"])
                for s in task["eval_seeds"]]
        out[label] = {"d_bar": d, "q99": [r.tracking_error_q99 for r in runs],
                      "covered": sum(r.tracking_error_q99 <= d for r in runs),
                      "violations": sum(r.collisions for r in runs),
                      "min_barrier": min(r.min_barrier for r in runs),
                      "duty": statistics.fmean(r.duty_cycle for r in runs),
                      "goals": statistics.fmean(r.goals_reached for r in runs)}
    out["wall_s"] = time.perf_counter() - t0
    return out


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["panda_pole", "panda_shelf", "panda_moving", "panda_servo"])
    ap.add_argument("--strategies", nargs="+", default=["cbf", "isf"])
    ap.add_argument("--eval-seeds", default="10-13", help="held-out seeds LO-HI (default 10-13)")
    ap.add_argument("--duration", type=float, default=6.0, help="simulated time per evaluation episode [s]")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    seeds = _seeds(args.eval_seeds)
    tasks = [{"scene": sc, "strategy": st, "eval_seeds": seeds, "duration": args.duration}
             for sc in args.scenes for st in args.strategies]
    started = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    t0 = time.time()

    def progress(done: int, total: int, task: dict[str, Any], r: dict[str, Any]) -> None:
        print(f"[{done}/{total}] {r['scene']} {r['strategy']}: d_bar {r['open']['d_bar']:.4f} -> "
              f"{r['loop']['d_bar']:.4f}, covered {r['open']['covered']} -> {r['loop']['covered']} of {len(seeds)}, "
              f"{r['wall_s']:.0f} s", file=sys.stderr, flush=True)

    partial = False
    try:
        done = run_tasks(run_combo, tasks, jobs=args.jobs, on_result=progress)
    except Interrupted as exc:
        done, partial = exc.done, True
    rows = [r for _, r in done]
    head = ("| scene | strategy | d_bar open loop | in-loop rounds (d_bar used: worst q99) | d_bar in loop | "
            "covered open / in loop | worst q99 open / in loop | violations open / in loop | "
            "duty open / in loop | goals open / in loop |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        o, lp, cal = r["open"], r["loop"], r["calibration"]
        rounds = "; ".join(f"{d:.4f}: {w:.4f}" for d, w in cal["rounds"])
        rounds += "" if cal["covered"] else " (not settled)"
        lines.append(
            f"| {r['scene']} | {r['strategy']} | {o['d_bar']:.4f} | {rounds} | "
            f"{lp['d_bar']:.4f} | {o['covered']}/{len(seeds)} / {lp['covered']}/{len(seeds)} | "
            f"{max(o['q99']):.4f} / {max(lp['q99']):.4f} | {o['violations']} / {lp['violations']} | "
            f"{o['duty']:.3f} / {lp['duty']:.3f} | {o['goals']:.2f} / {lp['goals']:.2f} |")
    cmd = (f"nice -n 19 python benchmarks/d_bar_loop.py --scenes {' '.join(args.scenes)} --strategies "
           f"{' '.join(args.strategies)} --eval-seeds {args.eval_seeds} --duration {args.duration:g} "
           f"--jobs {args.jobs}")
    body = "\n".join([
        "", f"`{cmd}`", "",
        f"Started {started} on {cpu_model()} ({os.cpu_count()} logical CPUs, shared), "
        f"{(time.time() - t0) / 60:.1f} min wall, load average at the end {os.getloadavg()[0]:.1f}"
        f"{', interrupted: partial' if partial else ''}. Calibration in the loop: seeds 0-5, 6 s, factor 1.25; "
        f"evaluation on held-out seeds {args.eval_seeds}, {args.duration:g} s.", "", *lines, ""])
    print(body)
    if not args.no_write:
        write_section(ROOT / "RESULTS.md", START, END, body, write_text_atomic)
    if partial:
        sys.exit(130)


if __name__ == "__main__":
    main()
