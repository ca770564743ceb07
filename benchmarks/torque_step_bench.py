"""Cost of a torque-level control step against one ``mj_step`` (RESULTS.md, "Torque level").

Usage::

    python benchmarks/torque_step_bench.py [--scene panda_pole] [--duration 4] [--repeats 3] [--no-write]

For each strategy at the velocity and the torque level: one episode (seed 0, ``d_bar`` as given below,
the per-phase timers on), its wall time per control step split into the phases, and one ``mj_step`` of
the scene's model timed on the states of a nominal episode (the least of ``--repeats`` runs of each).
``control`` is the step minus its physics (``act``): what the filter level adds to the simulation.
The table goes to BENCHMARKS.md between the ``torque-bench`` markers (written atomically), with the
machine, the load and the date (``--no-write``: print only).
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import cpu_model, write_section  # noqa: E402

from isf_robot.support.files import write_text_atomic  # noqa: E402


def mj_step_us(scene, seconds: float = 2.0, every: int = 10, calls: int = 5) -> float:  # type: ignore[no-untyped-def]
    """Mean time of one ``mj_step`` [us] on the states of a velocity-level nominal episode (seed 0).

    Every ``every``-th control step, ``calls`` ``mj_step`` on a copy of the episode's state, as
    ``arm_bench.py`` does: from a state with the arm at rest and no control the arm falls onto its joint
    limits, and ``mj_step`` there costs 20-50 % more than in any run.
    """
    import copy

    from isf_robot.arm import ArmSimulation, resolve_params

    sim = ArmSimulation(scene, "nominal", seed=0, params=resolve_params(scene, d_bar=0.05, calibrate=False))
    T = sim.control_period
    n = int(round(seconds / T))
    ep = sim.episode(sim, n)
    samples = []
    for k in range(n):
        t = k * T
        ep.sense(k)
        _, lie = ep.barriers()
        step = ep.strategy(t, lie, ep.nominal(t))
        ep.act(k, step.u)
        if k % every == 0:
            d = copy.copy(ep.data)
            t0 = time.perf_counter()
            for _ in range(calls):
                mujoco.mj_step(scene.model, d)
            samples.append((time.perf_counter() - t0) / calls)
    return float(np.mean(samples)) * 1e6


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="panda_pole")
    ap.add_argument("--duration", type=float, default=4.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-write", action="store_true", help="print only; do not rewrite BENCHMARKS.md")
    args = ap.parse_args(argv)
    load = os.getloadavg()
    lines: list[str] = []

    def out(line: str = "") -> None:
        print(line, flush=True)
        lines.append(line)

    warnings.simplefilter("ignore")
    from isf_robot.arm import ArmSimulation, load_scene, resolve_params
    from isf_robot.arm.torque_sim import TorqueSimulation, resolve_torque_params

    scene = load_scene(args.scene)
    mj = min(mj_step_us(scene) for _ in range(args.repeats))
    out("## Torque-level control step (`benchmarks/torque_step_bench.py`)")
    out()
    out(f"Machine: {platform.platform()}; CPU {cpu_model()}; {os.cpu_count()} cores; Python "
        f"{platform.python_version()}. Date (UTC): {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M}. "
        f"Load average before: {load[0]:.2f}, {load[1]:.2f}, {load[2]:.2f}.")
    out()
    out(f"{args.scene}: mj_step {mj:.1f} us; control period {scene.config.control.period * 1e3:g} ms "
        f"({int(round(scene.config.control.period / scene.model.opt.timestep))} physics steps); "
        f"{args.duration:g} s episodes, seed 0; per phase the least of {args.repeats} runs [us/step]. Target: "
        "a torque-level step <= 10x `mj_step`.")
    out()
    out("| level | strategy | us/step | control us/step | control x mj_step | sense | barriers | nominal | "
        "strategy | act |")
    out("|---|---|---|---|---|---|---|---|---|---|")
    levels = (("velocity", ArmSimulation, resolve_params(scene)), ("torque", TorqueSimulation,
                                                                  resolve_torque_params(scene)))
    for level, cls, params in levels:
        for strategy in ("nominal", "cbf", "isf"):
            best = None
            for _ in range(args.repeats):
                r = cls(scene, strategy, seed=0, params=params, timing=True).run(args.duration)
                n = r.metrics.control_steps
                per = {k: v / n * 1e6 for k, v in r.timings.items()}
                if best is None or sum(per.values()) < sum(best.values()):
                    best = per
            assert best is not None
            total = sum(best.values())
            control = total - best["act"]
            out(f"| {level} | {strategy} | {total:.0f} | {control:.0f} | {control / mj:.1f} | "
                + " | ".join(f"{best[k]:.0f}" for k in ("sense", "barriers", "nominal", "strategy", "act")) + " |")
    out()
    tp = levels[1][2]
    out(f"Both isf rows run their designed predictive off trigger (horizon {tp.horizon:g} s, a rollout at most every "
        f"{tp.predict_every} steps while the off condition holds): at the torque level the rollout has one point per "
        "control period (`isf_robot/arm/torque_rollout.py`), which is most of that row's strategy phase; the "
        "velocity level's has at most 10. The torque nominal keeps only the tick's safety accounting (no rows).")
    out()
    out("Reproduce: `python benchmarks/torque_step_bench.py` (add `--no-write` to only print).")
    if not args.no_write:
        write_section(ROOT / "BENCHMARKS.md", "<!-- torque-bench:start -->", "<!-- torque-bench:end -->",
                      "\n".join(lines), write=write_text_atomic)
    return 0


if __name__ == "__main__":
    np.seterr(all="ignore")
    sys.exit(main())
