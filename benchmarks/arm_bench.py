"""Cost of one arm control step as a multiple of one ``mj_step``, measured side by side.

For each Panda scene and each strategy (seed 0, the scene's nominal task, 1 kHz control: a 1 ms
control period is one physics step) the script interleaves, ``--repeats`` times,

* ``mj_step`` on the same model (median per call over 2000 calls), and
* one untimed episode per strategy (wall time of ``ArmSimulation.run`` per control step),

and reports the medians and their ratio. One more episode with phase timers gives the split
(sense = ``mj_step1``; barriers = collision pairs, joint limits, the tick's true-geometry check
and the filter rows; nominal; strategy = the core filter step, QP included; act = torques,
``mj_step2`` and the sub-steps' safety checks). ``QP/step`` is the honest QP cost: every solve of
the step with its polish and checks, from ``QPResult.solve_time_s``. The QP backend comparison
runs the cbf episode with ``QPSolver(backend="daqp")`` and ``backend="proxsuite"`` in turns.
With ``benchmarks/_scenes.py`` present, panda_pole with 64 extra far-away spheres is compared
to panda_pole itself (broad-phase cost).

Results go to ``BENCHMARKS.md`` between the ``arm-bench`` markers, with machine and date:

    python benchmarks/arm_bench.py            # all Panda scenes, writes BENCHMARKS.md
    python benchmarks/arm_bench.py --no-write --scenes panda_pole --duration 2
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
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402
from _common import cpu_model, write_section  # noqa: E402  (benchmarks/ is on sys.path as a script)

from isf_robot.arm import load_scene  # noqa: E402
from isf_robot.arm.params import resolve_params  # noqa: E402
from isf_robot.arm.sim import PHASES, ArmSimulation  # noqa: E402
from isf_robot.core import QPSolver  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
START, END = "<!-- arm-bench:start -->", "<!-- arm-bench:end -->"
STRATEGIES = ("nominal", "cbf", "isf")  # the strategies this benchmark reports on
TARGET = {"cbf": 10.0, "isf": 8.0}  # per-step cost as a multiple of mj_step (issue "Arm step rebuilt")


def mj_step_us(scene, n: int = 2000) -> float:
    m = scene.model
    d = scene.make_data()
    t0 = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(m, d)
    return (time.perf_counter() - t0) / n * 1e6


def step_us(scene, strategy: str, params, duration: float, period: float, **kw) -> tuple[float, object]:
    sim = ArmSimulation(scene, strategy, seed=0, params=params, control_period=period, **kw)
    r = sim.run(duration)
    return r.wall_s / r.control_steps * 1e6, r


def bench_scene(name: str, args: argparse.Namespace) -> dict:
    scene = load_scene(name)
    params = resolve_params(scene)
    mj, cost = [], {s: [] for s in STRATEGIES}
    for _ in range(args.repeats):
        mj.append(mj_step_us(scene))
        for s in STRATEGIES:
            cost[s].append(step_us(scene, s, params, args.duration, args.period)[0])
    mj_med = statistics.median(mj)
    out = {"scene": name, "mj_step_us": mj_med, "d_bar": params.d_bar, "rows": {}}
    for s in STRATEGIES:
        _, timed = step_us(scene, s, params, args.duration, args.period, timing=True)
        n = timed.control_steps
        med = statistics.median(cost[s])
        out["rows"][s] = {
            "us": med, "ratio": med / mj_med, "split": {k: timed.timings[k] / n * 1e6 for k in PHASES},
            "duty": timed.duty_cycle, "qp_solves": timed.qp_solves, "closed_form": timed.qp_closed_form,
            "qp_us": timed.qp_time_median_us, "solver_us": timed.solver_time_median_us,
            "resolves": timed.resolves,
        }
    return out


def bench_backends(args: argparse.Namespace) -> dict:
    scene = load_scene("panda_pole")
    params = resolve_params(scene)
    res: dict[str, dict[str, list[float]]] = {b: {"us": [], "qp": [], "solver": []} for b in ("daqp", "proxsuite")}
    for _ in range(args.repeats):
        for b in res:
            us, r = step_us(scene, "cbf", params, args.duration, args.period, solver=QPSolver(backend=b))
            res[b]["us"].append(us)
            res[b]["qp"].append(r.qp_time_median_us or 0.0)
            res[b]["solver"].append(r.solver_time_median_us or 0.0)
    return {b: {k: statistics.median(v) for k, v in d.items()} for b, d in res.items()}


def bench_far(args: argparse.Namespace) -> dict | None:
    try:
        from _scenes import far_spheres_scene
    except ImportError:
        return None
    base, far = load_scene("panda_pole"), far_spheres_scene(64)
    params = resolve_params(base)
    ratios = {s: [] for s in ("nominal", "cbf", "isf")}
    for _ in range(args.repeats):
        for s in ratios:
            a = step_us(base, s, params, args.duration, args.period)[0]
            b = step_us(far, s, params, args.duration, args.period)[0]
            ratios[s].append(b / a)
    return {s: statistics.median(v) for s, v in ratios.items()}


def _f(v: float | None, fmt: str = ".1f") -> str:
    return "-" if v is None else format(v, fmt)


def render(scenes: list[dict], backends: dict, far: dict | None, args: argparse.Namespace) -> str:
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M")
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    out = [
        "## Arm (`benchmarks/arm_bench.py`)", "",
        f"Machine: {platform.platform()}; CPU {cpu_model()}; {os.cpu_count()} cores; Python "
        f"{platform.python_version()}; MuJoCo {mujoco.__version__}. Date (UTC): {now}. One process "
        f"pinned to one core, BLAS threads 1. Load average at the end (1/5/15 min): {load} (a shared "
        "machine: absolute figures move with it, the ratios measured side by side much less).", "",
        f"Episodes of {args.duration:g} s, seed 0, control period {args.period * 1e3:g} ms with a 1 ms physics "
        f"step, d_bar as calibrated; medians of {args.repeats} interleaved repeats. `x mj_step`: cost of a "
        "control step over one `mj_step` on the same model in the same process. Split (us per control "
        "step) from one more episode with phase timers; `QP/step` is the median QP cost of a step that "
        "solved one (every solve, polish and checks included); `backend` the median over the steps that "
        "went to the QP backend (not the one-row closed form).", "",
        "| scene | strategy | us/step | x mj_step | target | sense | barriers | nominal | strategy | act | "
        "duty | QP steps | closed form | re-solves | QP/step [us] | backend [us] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for sc in scenes:
        for s, r in sc["rows"].items():
            sp = r["split"]
            tgt = TARGET.get(s)
            out.append(
                f"| {sc['scene']} | {s} | {r['us']:.1f} | **{r['ratio']:.1f}** | "
                f"{'<= %g' % tgt if tgt else '-'} | {sp['sense']:.1f} | {sp['barriers']:.1f} | {sp['nominal']:.1f} | "
                f"{sp['strategy']:.1f} | {sp['act']:.1f} | {r['duty']:.3f} | {r['qp_solves']} | {r['closed_form']} | "
                f"{r['resolves']} | {_f(r['qp_us'])} | {_f(r['solver_us'])} |")
    out += ["", "mj_step on each model: " + ", ".join(f"{sc['scene']} {sc['mj_step_us']:.2f} us" for sc in scenes)
            + ".", ""]
    out += ["QP backends, cbf on panda_pole, same episode (identical commands: the golden tests pin "
            "the runs to 1e-9 across backends):", "",
            "| backend | us/step | QP/step [us] | backend solves [us] |", "|---|---|---|---|"]
    for b, d in backends.items():
        out.append(f"| {b} | {d['us']:.1f} | {d['qp']:.1f} | {d['solver']:.1f} |")
    if far is not None:
        out += ["", "Broad phase: panda_pole with 64 extra static spheres far from the arm, cost per control "
                "step over panda_pole's (target <= 1.1): "
                + ", ".join(f"{s} **{v:.2f}**" for s, v in far.items()) + "."]
    checks = []
    for sc in scenes:
        for s, tgt in TARGET.items():
            r = sc["rows"][s]
            checks.append(f"- {sc['scene']} {s}: {r['ratio']:.1f}x mj_step (target <= {tgt:g}x): "
                          f"**{'met' if r['ratio'] <= tgt else 'NOT met'}**.")
    out += ["", *checks, "", "Reproduce: `python benchmarks/arm_bench.py` (add `--no-write` to only print)."]
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=["panda_pole", "panda_shelf", "panda_moving"])
    p.add_argument("--duration", type=float, default=4.0, help="episode length [s]")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--period", type=float, default=0.001, help="control period [s]")
    p.add_argument("--no-write", action="store_true", help="print only")
    args = p.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        cpus = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpus[-1]})
    scenes = []
    for name in args.scenes:
        sc = bench_scene(name, args)
        scenes.append(sc)
        print(f"{name}: mj_step {sc['mj_step_us']:.2f} us; " + "; ".join(
            f"{s} {r['us']:.1f} us = {r['ratio']:.1f}x" for s, r in sc["rows"].items()), file=sys.stderr)
    backends = bench_backends(args)
    print("backends: " + "; ".join(f"{b} {d['us']:.1f} us/step, QP {d['qp']:.1f} us" for b, d in backends.items()),
          file=sys.stderr)
    far = bench_far(args)
    section = render(scenes, backends, far, args)
    print(section)
    if not args.no_write:
        write_section(ROOT / "BENCHMARKS.md", START, END, section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
