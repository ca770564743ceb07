"""Cost of a torque-level control step against one ``mj_step`` (RESULTS.md, "Torque level").

Usage::

    python benchmarks/torque_step_bench.py [--scene panda_pole] [--duration 4] [--repeats 3]

For each strategy at the velocity and the torque level: one episode (seed 0, ``d_bar`` as given below,
the per-phase timers on), its wall time per control step split into the phases, and one ``mj_step`` of
the scene's model timed on the states of a nominal episode (the least of ``--repeats`` runs of each).
``control`` is the step minus its physics (``act``): what the filter level adds to the simulation.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings

import mujoco
import numpy as np


def mj_step_us(scene, n: int = 4000) -> float:  # type: ignore[no-untyped-def]
    """Mean time of one ``mj_step`` [us] from the scene's home, the arm falling under gravity (no control)."""
    data = scene.make_data()
    t0 = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(scene.model, data)
    return (time.perf_counter() - t0) / n * 1e6


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="panda_pole")
    ap.add_argument("--duration", type=float, default=4.0)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    from isf_robot.arm import ArmSimulation, load_scene, resolve_params
    from isf_robot.arm.torque_sim import TorqueSimulation, resolve_torque_params

    scene = load_scene(args.scene)
    mj = min(mj_step_us(scene) for _ in range(args.repeats))
    print(f"{args.scene}: mj_step {mj:.1f} us; control period {scene.config.control.period * 1e3:g} ms "
          f"({int(round(scene.config.control.period / scene.model.opt.timestep))} physics steps); "
          f"{args.duration:g} s episodes, seed 0\n")
    print("| level | strategy | us/step | control us/step | control x mj_step | sense | barriers | nominal | "
          "strategy | act |")
    print("|---|---|---|---|---|---|---|---|---|---|")
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
            print(f"| {level} | {strategy} | {total:.0f} | {control:.0f} | {control / mj:.1f} | "
                  + " | ".join(f"{best[k]:.0f}" for k in ("sense", "barriers", "nominal", "strategy", "act")) + " |",
                  flush=True)
    return 0


if __name__ == "__main__":
    np.seterr(all="ignore")
    sys.exit(main())
