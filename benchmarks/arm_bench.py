"""Cost of one arm control step, split by phase, for the standard and intermittent filters.

For each Panda scene and for ``cbf`` and ``isf`` (seed 0, the scene's nominal task, 1 kHz
control: control period 1 ms = one physics step), the script runs

* ``--repeats`` untimed episodes: control steps per second of wall time (median), and
* one episode with per-phase timers: physics (``mj_step1``/``mj_step2`` and the torque
  controller), barriers (collision pairs, joint limits, the true-geometry safety check at the
  tick, assembling the filter's rows), nominal controller, trigger/filter logic (the filter
  call minus the QP) and QP solves, in microseconds per control step.

The figures are written to ``BENCHMARKS.md`` between the ``arm-bench`` markers with the
machine, date and load. Run from the repository root:

    python benchmarks/arm_bench.py            # all Panda scenes, writes BENCHMARKS.md
    python benchmarks/arm_bench.py --no-write --scenes panda_pole --duration 3
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import datetime as _dt  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from _common import cpu_model, write_section  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

from isf_robot.arm import calibrate_d_bar, load_scene, run_episode  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
START, END = "<!-- arm-bench:start -->", "<!-- arm-bench:end -->"
PHASES = ("physics", "barriers", "nominal", "trigger", "qp")
TARGET_STEPS = 10_000  # isf control steps per second of wall time, panda_pole, 1 kHz
TARGET_QP_US = 30.0




def bench(scene_name: str, strategy: str, duration: float, repeats: int, period: float,
          d_bar: float) -> dict:
    scene = load_scene(scene_name)
    runs = [run_episode(scene, strategy, duration, 0, control_period=period, d_bar=d_bar)
            for _ in range(repeats)]
    rates = [r.control_steps / r.wall_s for r in runs]
    walls = [r.wall_s for r in runs]
    timed = run_episode(scene, strategy, duration, 0, control_period=period, d_bar=d_bar,
                        timing=True)
    n = timed.control_steps
    split = {k: timed.timings.get(k, 0.0) / n * 1e6 for k in PHASES}
    per_solve = (timed.timings.get("qp", 0.0) / timed.qp_solves * 1e6
                 if timed.qp_solves else None)
    return {
        "scene": scene_name, "strategy": strategy, "steps_per_s": statistics.median(rates),
        "rates": rates, "wall_s": statistics.median(walls), "control_steps": runs[0].control_steps,
        "duty": runs[0].duty_cycle, "qp_solves": runs[0].qp_solves,
        "qp_median_us": runs[0].qp_time_median_us, "qp_mean_us": per_solve, "split": split,
        "closed_form": runs[0].qp_closed_form, "proxqp_median_us": runs[0].proxqp_time_median_us,
        "timed_total_us": timed.wall_s / n * 1e6,
    }


def _fmt(v: float | None, f: str = ".1f") -> str:
    return "-" if v is None else format(v, f)


def render(rows: list[dict], args: argparse.Namespace, d_bars: dict[str, float]) -> str:
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M")
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    out = [
        "## Arm (`benchmarks/arm_bench.py`)",
        "",
        f"Machine: {platform.platform()}; CPU {cpu_model()}; {os.cpu_count()} cores; Python "
        f"{platform.python_version()}; MuJoCo {mujoco.__version__}. Date (UTC): {now}. "
        f"One process pinned to one core, BLAS threads 1. Load average at the end (1/5/15 min): "
        f"{load} (a shared machine: other jobs may run).",
        "",
        f"Episodes of {args.duration:g} s, seed 0, control period {args.period * 1e3:g} ms "
        f"(1 kHz) with a 1 ms physics step, d_bar as calibrated ("
        + ", ".join(f"{k} {v:.3f} rad/s" for k, v in d_bars.items())
        + f"). Steps/s: median of {args.repeats} untimed episodes. The split comes from one "
        "more episode with per-phase timers (their own cost is included in the phases), in "
        "microseconds per control step averaged over all steps; `QP` per step is the QP time "
        "over the whole episode divided by the control steps, `QP median` is per solve. Rows "
        "of the filter with a large slack under the nominal command are left out of the QP "
        "(checked at the solution, re-solved with every row if one is violated), so many QPs "
        "have one row and are solved in closed form (`closed form` of the `QP solves`); "
        "`ProxQP median` is over the others. The QP time is measured inside the core's "
        "`QPSolver.solve` (Python overhead included). For `isf`, while the filter is off and "
        "every `Xi_on` is positive the filter is not called (its step would pass `u_nom` "
        "through); that test runs on the rows computed for the pruning and is counted in "
        "`barriers`.",
        "",
        "| scene | filter | steps/s | x real time | wall/episode [s] | duty | QP solves | "
        "physics | barriers | nominal | trigger+filter | QP (per step) | QP median [us] | "
        "closed form | ProxQP median [us] | total [us] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        s = r["split"]
        out.append(
            f"| {r['scene']} | {r['strategy']} | **{r['steps_per_s']:.0f}** | "
            f"{r['steps_per_s'] * args.period:.1f} | {r['wall_s']:.3f} | {r['duty']:.3f} | "
            f"{r['qp_solves']} | {s['physics']:.1f} | {s['barriers']:.1f} | {s['nominal']:.1f} | "
            f"{s['trigger']:.1f} | {s['qp']:.1f} | {_fmt(r['qp_median_us'])} | "
            f"{r['closed_form']} | {_fmt(r['proxqp_median_us'])} | {r['timed_total_us']:.1f} |")
    out.append("")
    by = {(r["scene"], r["strategy"]): r for r in rows}
    checks = []
    pole = by.get(("panda_pole", "isf"))
    if pole is not None:
        ok = pole["steps_per_s"] >= TARGET_STEPS
        checks.append(f"- isf on panda_pole at 1 kHz: {pole['steps_per_s']:.0f} control steps/s "
                      f"(target >= {TARGET_STEPS}): **{'met' if ok else 'NOT met'}**.")
    qps = [r["qp_median_us"] for r in rows if r["qp_median_us"] is not None]
    pqs = [r["proxqp_median_us"] for r in rows if r["proxqp_median_us"] is not None]
    if qps:
        ok = max(qps) < TARGET_QP_US
        checks.append(f"- QP median per solve: {min(qps):.1f} to {max(qps):.1f} us over the rows "
                      f"above (target < {TARGET_QP_US:g} us): **{'met' if ok else 'NOT met'}**"
                      + (f"; ProxQP solves alone: {min(pqs):.1f} to {max(pqs):.1f} us "
                         f"(**{'met' if max(pqs) < TARGET_QP_US else 'NOT met'}**)." if pqs
                         else "."))
    for scene in dict.fromkeys(r["scene"] for r in rows):
        c, i = by.get((scene, "cbf")), by.get((scene, "isf"))
        if c and i:
            ok = i["wall_s"] < c["wall_s"]
            checks.append(f"- {scene}: isf episode wall {i['wall_s']:.3f} s vs cbf "
                          f"{c['wall_s']:.3f} s: **{'isf faster' if ok else 'isf NOT faster'}**.")
    out += checks
    out += ["", "Reproduce: `python benchmarks/arm_bench.py` (add `--no-write` to only print)."]
    return "\n".join(out)




def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=["panda_pole", "panda_shelf", "panda_moving"])
    p.add_argument("--duration", type=float, default=10.0, help="episode length [s]")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--period", type=float, default=0.001, help="control period [s]")
    p.add_argument("--no-write", action="store_true", help="print only")
    args = p.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        cpus = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpus[-1]})
    np.random.seed(0)
    rows, d_bars = [], {}
    for name in args.scenes:
        d_bars[name] = calibrate_d_bar(load_scene(name)).d_bar
        for strategy in ("cbf", "isf"):
            r = bench(name, strategy, args.duration, args.repeats, args.period, d_bars[name])
            print(f"{name:13s} {strategy}: {r['steps_per_s']:7.0f} steps/s, QP median "
                  f"{_fmt(r['qp_median_us'])} us, split "
                  + ", ".join(f"{k} {v:.1f}" for k, v in r["split"].items()), file=sys.stderr)
            rows.append(r)
    section = render(rows, args, d_bars)
    print(section)
    if not args.no_write:
        write_section(ROOT / "BENCHMARKS.md", START, END, section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
