"""Cost of ``CollisionBarriers.evaluate`` on panda_pole vs panda_pole with far-away spheres.

The far-spheres scene (:func:`_scenes.far_spheres_scene`) adds ``--spheres`` static spheres
3 m from the arm, each an obstacle of every robot geom, none ever within the cut-off. Both
scenes are evaluated at the same arm configurations (home plus Gaussian noise, seeded), in turns
(``--repeats`` rounds of ``--calls`` calls per scene), in one process; the script prints the
median time per call of each scene and their ratio (1.0: far obstacles cost nothing).

    python benchmarks/broadphase_bench.py
    python benchmarks/broadphase_bench.py --spheres 128 --repeats 60
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from _common import cpu_model  # noqa: E402  (benchmarks/ is on sys.path as a script)
from _scenes import far_spheres_scene  # noqa: E402

from isf_robot.arm import CollisionBarriers, Scene, load_scene  # noqa: E402


def states(scene: Scene, qs: list[np.ndarray]) -> list[mujoco.MjData]:
    """One ``MjData`` per configuration, kinematics done."""
    out = []
    for q in qs:
        d = mujoco.MjData(scene.model)
        d.qpos[scene.qpos_adr] = q
        mujoco.mj_forward(scene.model, d)
        out.append(d)
    return out


def per_call_us(cb: CollisionBarriers, datas: list[mujoco.MjData], calls: int) -> float:
    """Mean time of one ``evaluate`` [us] over ``calls`` calls cycling through ``datas``."""
    n = len(datas)
    evaluate = cb.evaluate
    t0 = time.perf_counter()
    for i in range(calls):
        evaluate(datas[i % n])
    return (time.perf_counter() - t0) / calls * 1e6


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--spheres", type=int, default=64, help="extra far spheres (default 64)")
    p.add_argument("--repeats", type=int, default=40, help="interleaved rounds (default 40)")
    p.add_argument("--calls", type=int, default=500, help="calls per scene per round (default 500)")
    p.add_argument("--noise", type=float, default=0.3, help="std of the joint noise [rad] (default 0.3)")
    args = p.parse_args()

    base, far = load_scene("panda_pole"), far_spheres_scene(args.spheres)
    rng = np.random.default_rng(0)
    qs = [base.home + rng.normal(0.0, args.noise, base.n_joints) for _ in range(50)]
    runs = {}
    for sc in (base, far):
        cb = CollisionBarriers.from_scene(sc)
        runs[sc.name] = (cb, states(sc, qs), [])
        per_call_us(cb, runs[sc.name][1], args.calls)  # warm-up
    active = float(np.mean([runs[base.name][0].evaluate(d).active.sum() for d in runs[base.name][1]]))
    for _ in range(args.repeats):
        for cb, datas, times in runs.values():
            times.append(per_call_us(cb, datas, args.calls))

    print(f"CollisionBarriers.evaluate, median of {args.repeats} interleaved rounds x {args.calls} calls "
          f"({cpu_model()}; {active:.1f} active pairs on average)")
    med = {}
    for name, (cb, _, times) in runs.items():
        med[name] = statistics.median(times)
        print(f"  {name:<20} {cb.pairs.k:4d} pairs ({cb.broadphase.live.size:3d} tested per call)  "
              f"{med[name]:7.2f} us/call")
    print(f"  ratio far/panda_pole: {med[far.name] / med[base.name]:.3f}")


if __name__ == "__main__":
    main()
