"""Cost of one arm control step as a multiple of one ``mj_step``, measured side by side.

For each Panda scene and each strategy (seed 0, the scene's nominal task, 1 kHz control: a 1 ms
control period is one physics step) the script runs ``--repeats`` episodes with a step clock in
place of the loop's phase timers: it takes the wall time of every control step (from ``sense``
to the end of ``act``, QP and metrics included) and, every 10th step, right after it, the time
of 5 ``mj_step`` calls on a copy of the run's current state (same model, same state, same moment
of the machine's load). The episodes are deterministic, so every repeat runs the same steps from
the same states: each step's cost is its least wall time over the repeats, and each ``mj_step``
sample's likewise (a preemption or a burst of another job stretches one repeat's step, rarely the
same step in every repeat), and the figure is the mean of those per-step costs over every step of
the episode, its ratio the step cost in ``mj_step`` units. No step is dropped: a step that is dear
in every repeat (a rollout of the predictive off trigger, a re-solve) counts in full. On a shared
machine this keeps the ratio honest where a whole-episode wall or CPU time does not (other jobs
stretch both; a VM counts the host's steal as CPU time). ``mj_step`` from a state with the arm at rest is not used: the
arm falls onto its joint limits within a second and ``mj_step`` then costs about 20% more, with
limit constraints the runs never have.

The same clock gives the split, each phase's least time per step over the repeats (wall time; sense =
``mj_step1``; barriers = collision pairs within the cut-off, joint limits, the tick's true-geometry accounting
and the filter rows; nominal; strategy = the core filter step, QP included; act = torques, ``mj_step2`` and
the sub-steps' safety checks). ``QP/step`` is the honest QP cost: every solve of the step with its polish and
checks, from ``QPResult.solve_time_s`` (the standard filter's closed form: its one compiled call, ``Xi_on``
included; the intermittent filter's on step: its one call with the promotion pass). The QP backend comparison
runs the cbf episode with ``QPSolver(backend="daqp")`` and ``backend="proxsuite"`` in turns. With
``benchmarks/_scenes.py`` present, panda_pole with 64 extra far-away spheres is compared to panda_pole itself
(broad-phase cost, the same step clock): the arm's own cost per step (the step minus one ``mj_step`` of the
same episode) with and without them, since MuJoCo's own collision of the spheres makes ``mj_step`` itself
dearer (see :func:`bench_far`). panda_pole's isf also runs without its designed options (the predictive off
trigger, then the hand-over too) and with maneuvers by shooting, to show what they cost per step
(:func:`bench_isf_options`).

Results go to ``BENCHMARKS.md`` between the ``arm-bench`` markers (written atomically), with
machine and date:

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

from isf_robot.arm import kernels, load_scene  # noqa: E402
from isf_robot.arm import sim as sim_module  # noqa: E402
from isf_robot.arm.params import resolve_params  # noqa: E402
from isf_robot.arm.sim import ArmSimulation  # noqa: E402
from isf_robot.core import QPSolver  # noqa: E402
from isf_robot.support.files import write_text_atomic  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
START, END = "<!-- arm-bench:start -->", "<!-- arm-bench:end -->"
STRATEGIES = ("nominal", "cbf", "isf")  # the strategies this benchmark reports on
TARGET = {"cbf": 6.6, "isf": 8.2}  # per-step cost as a multiple of mj_step (issue "One source per formula")


class _StepClock:
    """Stands in for the loop's ``PhaseTimers`` (see the module docstring): the wall time of every
    step (from the start of ``sense`` to the end of ``act``: the loop's own work between the phases
    included) and of its phases, and ``mj_step`` samples on a copy of the run's state every 10th step."""

    every, block = 10, 5

    def __init__(self, phases: dict) -> None:
        self.totals = dict.fromkeys(phases, 0.0)
        self.per: dict[str, list[float]] = {name: [] for name in phases}
        self.mj: list[float] = []
        self.steps: list[float] = []
        self._t_step = 0.0
        ep = phases["sense"].__self__  # the loop's episode: its model and live data
        model, scratch = ep.model, mujoco.MjData(ep.model)
        perf = time.perf_counter

        def wrap(name: str, fn):  # type: ignore[no-untyped-def]
            rec = self.per[name]
            first, last = name == "sense", name == "act"

            def timed(*args):  # type: ignore[no-untyped-def]
                t0 = perf()
                if first:
                    self._t_step = t0
                out = fn(*args)
                t1 = perf()
                rec.append(t1 - t0)
                if last:
                    self.steps.append(t1 - self._t_step)  # the whole step: the loop's own work between phases too
                    if args[0] % self.every == 0:
                        mujoco.mj_copyData(scratch, model, ep.data)
                        t2 = perf()
                        for _ in range(self.block):
                            mujoco.mj_step(model, scratch)
                        self.mj.append((perf() - t2) / self.block)
                return out

            return timed

        for name, fn in list(phases.items()):
            phases[name] = wrap(name, fn)



def combine(clocks: list[_StepClock]) -> tuple[float, dict[str, float], float]:
    """(step cost [us], mean per phase [us], mj_step [us]) of repeats of one episode: each step's
    (phase's, ``mj_step`` sample's) least time over the repeats, then the mean over every step."""
    def least_mean(series: list[list[float]]) -> float:
        n = min(len(v) for v in series)
        return sum(min(v[i] for v in series) for i in range(n)) / n * 1e6

    split = {k: least_mean([c.per[k] for c in clocks]) for k in clocks[0].per}
    return least_mean([c.steps for c in clocks]), split, least_mean([c.mj for c in clocks])


def clocked(scene, strategy: str, params, duration: float, period: float | None, sim_type=ArmSimulation,
            **kw) -> tuple[_StepClock, object]:
    """One episode of ``sim_type`` (seed 0; ``period`` None: the scene's) under the step clock: (its clock, result)."""
    clocks: list[_StepClock] = []

    def make(phases: dict) -> _StepClock:
        clocks.append(_StepClock(phases))
        return clocks[-1]

    saved = sim_module.PhaseTimers
    sim_module.PhaseTimers = make  # the loop wraps its phases with whatever this name holds
    try:
        r = sim_type(scene, strategy, seed=0, params=params, control_period=period, timing=True, **kw).run(duration)
    finally:
        sim_module.PhaseTimers = saved
    return clocks[0], r


def bench_scene(name: str, args: argparse.Namespace) -> dict:
    scene = load_scene(name)
    params = resolve_params(scene)
    runs: dict[str, list] = {s: [] for s in STRATEGIES}
    for _ in range(args.repeats):
        for s in STRATEGIES:
            runs[s].append(clocked(scene, s, params, args.duration, args.period))
    out = {"scene": name, "d_bar": params.d_bar, "rows": {}}
    for s in STRATEGIES:
        us, split, mj = combine([c for c, _ in runs[s]])
        r = runs[s][-1][1]  # (every repeat runs the same steps: the same counts)
        out["rows"][s] = {
            "us": us, "mj_us": mj, "ratio": us / mj, "split": split,
            "duty": r.duty_cycle, "qp_solves": r.qp_solves, "closed_form": r.qp_closed_form,
            "qp_us": r.qp_time_median_us, "solver_us": r.solver_time_median_us, "resolves": r.resolves,
        }
    return out


def bench_backends(args: argparse.Namespace) -> dict:
    scene = load_scene("panda_pole")
    params = resolve_params(scene)
    runs: dict[str, list] = {b: [] for b in ("daqp", "proxsuite")}
    for _ in range(args.repeats):
        for b, rs in runs.items():
            rs.append(clocked(scene, "cbf", params, args.duration, args.period, solver=QPSolver(backend=b)))
    return {b: {"us": combine([c for c, _ in rs])[0],
                "qp": statistics.median(r.qp_time_median_us or 0.0 for _, r in rs),
                "solver": statistics.median(r.solver_time_median_us or 0.0 for _, r in rs)}
            for b, rs in runs.items()}


ISF_VARIANTS = (("designed options", {}), ("no predictive off trigger (horizon 0)", {"horizon": 0.0}),
                ("neither trigger nor hand-over (horizon 0, blend 0)", {"horizon": 0.0, "blend": 0.0}),
                ("designed options and maneuvers by shooting (shoot 0.5)", {"shoot": 0.5}))


def bench_isf_options(args: argparse.Namespace) -> list[dict]:
    """panda_pole's isf with its options (the predictive off trigger and the hand-over, designed from the
    scene: :mod:`isf_robot.arm.filter_design`) and without them, each figure as in :func:`bench_scene`:
    what the options cost per step."""
    scene = load_scene("panda_pole")
    out = []
    for label, kw in ISF_VARIANTS:
        params = resolve_params(scene, **kw)
        runs = [clocked(scene, "isf", params, args.duration, args.period) for _ in range(args.repeats)]
        us, split, mj = combine([c for c, _ in runs])
        r = runs[-1][1]
        out.append({"label": label, "us": us, "mj_us": mj, "ratio": us / mj, "strategy": split["strategy"],
                    "duty": r.duty_cycle, "switches": r.on_switches})
    return out


def bench_far(args: argparse.Namespace) -> dict | None:
    """panda_pole with 64 far spheres against panda_pole, episode pairs back to back.

    Three ratios per strategy (each episode's figures from its repeats, :func:`combine`): ``arm``,
    the arm's own cost per step (step minus S ``mj_step`` of the same episode: a step holds S physics steps) with the
    spheres over without, the figure the target is about; ``x_mj``, the step in ``mj_step`` units of
    its own episode, with over without; ``wall``, the step's wall time with over without. ``mj``:
    the ``mj_step`` cost with over without (MuJoCo's own collision of the extra geoms).
    """
    try:
        from _scenes import far_spheres_scene
    except ImportError:
        return None
    base, far = load_scene("panda_pole"), far_spheres_scene(64)
    params = resolve_params(base)
    S = max(1, round(args.period / base.model.opt.timestep))  # physics steps per control step
    out: dict[str, dict[str, float]] = {}
    for s in STRATEGIES:
        a_runs, b_runs = [], []
        for _ in range(args.repeats):  # the two scenes back to back
            a_runs.append(clocked(base, s, params, args.duration, args.period)[0])
            b_runs.append(clocked(far, s, params, args.duration, args.period)[0])
        (a_us, _, a_mj), (b_us, _, b_mj) = combine(a_runs), combine(b_runs)
        out[s] = {"arm": (b_us - S * b_mj) / (a_us - S * a_mj), "x_mj": (b_us / b_mj) / (a_us / a_mj),
                  "wall": b_us / a_us, "mj": b_mj / a_mj}
    return out


def _f(v: float | None, fmt: str = ".1f") -> str:
    return "-" if v is None else format(v, fmt)


def _kernels() -> str:
    if not kernels.available():
        return "numpy (numba not installed, or ISF_ROBOT_JIT=0)"
    import numba

    return f"compiled (numba {numba.__version__})"


def render(scenes: list[dict], backends: dict, far: dict | None, args: argparse.Namespace,
           options: list[dict] | None = None) -> str:
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M")
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    out = [
        "## Arm (`benchmarks/arm_bench.py`)", "",
        f"Machine: {platform.platform()}; CPU {cpu_model()}; {os.cpu_count()} cores; Python "
        f"{platform.python_version()}; MuJoCo {mujoco.__version__}. Date (UTC): {now}. One process "
        f"pinned to one core, BLAS threads 1. Load average at the end (1/5/15 min): {load} (a shared "
        "machine: absolute figures move with it, the ratios measured side by side much less). Barrier "
        f"kernels: {_kernels()} (`isf_robot/arm/kernels.py`).", "",
        f"Episodes of {args.duration:g} s, seed 0, control period {args.period * 1e3:g} ms with a 1 ms physics "
        f"step, d_bar as calibrated; {args.repeats} repeats of each (deterministic) episode. `us/step`: wall time "
        "of a control step (QP, metrics and the predictive trigger's rollouts included), `mj_step`: one `mj_step` "
        "on a copy of the run's state taken every 10th step; each step's and each sample's least time over the "
        "repeats, then the mean over every step of the episode (none dropped); `x mj_step` their ratio. "
        "Split: the same per phase (the per-phase "
        "timers, about 1 us per step, are included in `us/step`); `QP/step` is the median QP cost of a step "
        "that solved one (every solve, polish and checks included; the standard filter's closed form is one "
        "compiled call with its `Xi_on` pass, the intermittent filter's on step one with its promotion pass); "
        "`backend` the median over the steps that "
        "went to the QP backend or, with several rows (at most `FEW_ROWS`), to its exact closed forms (one or two "
        "active; else the certified active-set iteration) (`QPSolver(few_rows=True)`, the arm's default; not the "
        "one-row closed form).", "",
        "| scene | strategy | us/step | mj_step [us] | x mj_step | target | sense | barriers | nominal | strategy | "
        "act | duty | QP steps | closed form | re-solves | QP/step [us] | backend [us] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for sc in scenes:
        for s, r in sc["rows"].items():
            sp = r["split"]
            tgt = TARGET.get(s)
            tgt_s = f"<= {tgt:g}" if tgt else "-"
            out.append(
                f"| {sc['scene']} | {s} | {r['us']:.1f} | {r['mj_us']:.2f} | **{r['ratio']:.1f}** | "
                f"{tgt_s} | {sp['sense']:.1f} | {sp['barriers']:.1f} | {sp['nominal']:.1f} | "
                f"{sp['strategy']:.1f} | {sp['act']:.1f} | {r['duty']:.3f} | {r['qp_solves']} | {r['closed_form']} | "
                f"{r['resolves']} | {_f(r['qp_us'])} | {_f(r['solver_us'])} |")
    out += [""]
    out += ["QP backends, cbf on panda_pole, same episode (identical commands: the golden tests pin "
            "the runs to 1e-9 across backends):", "",
            "| backend | us/step | QP/step [us] | backend solves [us] |", "|---|---|---|---|"]
    for b, d in backends.items():
        out.append(f"| {b} | {d['us']:.1f} | {d['qp']:.1f} | {d['solver']:.1f} |")
    if options:
        out += ["", "The intermittent filter's options on panda_pole (designed from the scene: a predictive off "
                "trigger, `horizon = 0.26` s with a rollout at most every 5 steps while it holds, and a hand-over "
                "`blend = 0.15` s), and with maneuvers by shooting (`--shoot 0.5`: three QP solves and three rollouts "
                "over 0.5 s at each on switch and then at most every 5 steps while on): the isf step with and "
                "without them, measured as above:", "",
                "| isf on panda_pole | us/step | mj_step [us] | x mj_step | strategy [us] | duty | on switches |",
                "|---|---|---|---|---|---|---|"]
        out += [f"| {o['label']} | {o['us']:.1f} | {o['mj_us']:.2f} | **{o['ratio']:.1f}** | {o['strategy']:.1f} | "
                f"{o['duty']:.3f} | {o['switches']} |" for o in options]
    if far is not None:
        out += ["", "Broad phase: panda_pole with 64 extra static spheres 3 m from the arm (never within the cut-off), "
                "cost per control step over panda_pole's (target <= 1.1), in the arm's own cost per step (the step "
                "minus its physics steps, each costed as one `mj_step` of the same episode): "
                + ", ".join(f"{s} **{v['arm']:.2f}**" for s, v in far.items()) + ". For comparison, the step in "
                "`mj_step` units of its own episode: " + ", ".join(f"{s} {v['x_mj']:.2f}" for s, v in far.items())
                + "; the step's wall time: " + ", ".join(f"{s} {v['wall']:.2f}" for s, v in far.items())
                + "; `mj_step` itself: " + ", ".join(f"{s} {v['mj']:.2f}" for s, v in far.items()) + ". The "
                "spheres are real obstacles to MuJoCo too: its own collision detection of 64 more geoms makes "
                "every `mj_step` dearer, which no broad phase of ours can avoid, and a wall-time ratio of two "
                "episodes also moves with the machine's load between them; the arm's own cost is what the "
                "broad phase decides."]
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
        print(f"{name}: " + "; ".join(f"{s} {r['us']:.1f} us = {r['ratio']:.1f}x mj_step ({r['mj_us']:.2f} us)"
                                      for s, r in sc["rows"].items()), file=sys.stderr)
    backends = bench_backends(args)
    print("backends: " + "; ".join(f"{b} {d['us']:.1f} us/step, QP {d['qp']:.1f} us" for b, d in backends.items()),
          file=sys.stderr)
    far = bench_far(args)
    if far is not None:
        print("far spheres: " + "; ".join(f"{s} arm {v['arm']:.2f} x_mj {v['x_mj']:.2f} wall {v['wall']:.2f} "
                                          f"mj_step {v['mj']:.2f}" for s, v in far.items()), file=sys.stderr)
    options = bench_isf_options(args) if "panda_pole" in args.scenes else []
    if options:
        print("isf options: " + "; ".join(f"{o['label']} {o['ratio']:.1f}x" for o in options), file=sys.stderr)
    section = render(scenes, backends, far, args, options)
    print(section)
    if not args.no_write:
        write_section(ROOT / "BENCHMARKS.md", START, END, section, write_text_atomic)
    return 0


if __name__ == "__main__":
    sys.exit(main())
