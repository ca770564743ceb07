"""Cost of the intermittent filter's options on the arm (issue 13): the rollout of the predictive
off trigger and whole episodes with each option, written to BENCHMARKS.md.

    python benchmarks/intermittent_bench.py [--repeats 5] [--duration 4]

Figures: the median wall time of one rollout (``NominalRollout``: at most 10 predicted points,
each a nominal evaluation, kinematics and the scene's barrier rows on a scratch MjData), beside
the median wall time of a whole control step of a plain isf run; and episodes (median over repeats
of the same seed) with each option, as ratios to the plain isf episode.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import mujoco

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import cpu_model, write_section  # noqa: E402

from isf_robot.arm import ArmSimulation, load_scene  # noqa: E402
from isf_robot.arm.params import resolve_params  # noqa: E402
from isf_robot.support.files import write_text_atomic  # noqa: E402

START, END = "<!-- intermittent_bench:start -->", "<!-- intermittent_bench:end -->"
OFF = {"blend": 0.0, "horizon": 0.0}
OPTIONS = {"plain (no options)": OFF, "blend 0.05": {**OFF, "blend": 0.05},
           "min_off 0.25": {**OFF, "min_off": 0.25}, "horizon 0.3 (every 5)": {**OFF, "horizon": 0.3},
           "blend 0.05 + horizon 0.3 (shipped)": {"blend": 0.05, "horizon": 0.3},
           "horizon 0.3 (every 1)": {**OFF, "horizon": 0.3, "predict_every": 1}}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--duration", type=float, default=4.0)
    ap.add_argument("--scene", default="panda_pole")
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args()
    scene = load_scene(args.scene)
    base = resolve_params(scene)
    rows, plain = [], None
    for label, kw in OPTIONS.items():
        p = resolve_params(scene, d_bar=base.d_bar, **kw)
        walls, res = [], None
        for _ in range(args.repeats):
            sim = ArmSimulation(scene, "isf", seed=args.seed, params=p)
            res = sim.run(args.duration)
            walls.append(res.wall_s / res.control_steps)
        med = statistics.median(walls)
        plain = med if plain is None else plain
        rolls = sim.strategy.predictor.rollouts if sim.strategy.predictor is not None else 0
        rows.append(f"| {label} | {med * 1e6:.0f} | {med / plain:.2f} | {rolls} | {res.duty_cycle:.3f} | "
                    f"{res.on_switches} |")
    # one rollout, timed alone from a state of the episode
    p = resolve_params(scene, d_bar=base.d_bar, horizon=0.3)
    sim = ArmSimulation(scene, "isf", seed=args.seed, params=p)
    roll = sim.strategy.predictor.rollout
    data = mujoco.MjData(scene.model)
    data.qpos[scene.qpos_adr] = sim.setup.q0
    mujoco.mj_forward(scene.model, data)
    times = []
    for _ in range(200):
        t0 = time.perf_counter()
        roll(0.5, data)
        times.append(time.perf_counter() - t0)
    one = statistics.median(times)
    body = "\n".join([
        "## Intermittent filter options (`benchmarks/intermittent_bench.py`)",
        "",
        f"{cpu_model()}, scene {args.scene}, seed {args.seed}, isf episodes of {args.duration:g} s "
        f"({int(round(args.duration / sim.control_period))} control steps of {sim.control_period * 1e3:g} ms), "
        f"median over {args.repeats} repeats of the wall time per control step (whole loop: physics, barriers, "
        "filter). The machine was shared with other jobs: compare the ratios.",
        "",
        f"One rollout of the predictive off trigger (horizon 0.3 s, {roll.n} points of {roll.dt * 1e3:g} ms): "
        f"median {one * 1e6:.0f} us over 200 calls, i.e. {one / plain:.1f} plain control steps. The filter runs "
        "at most one every `predict_every` control steps, and only while it is on with every Xi_on above the "
        f"margin: the bound on the added cost per step is {one * 1e6:.0f} us / predict_every "
        f"({one / 5 * 1e6:.0f} us at the default 5).",
        "",
        "| isf option | per step [us] | / plain | rollouts | duty | switches |",
        "|---|---:|---:|---:|---:|---:|",
        *rows,
    ])
    write_section(ROOT / "BENCHMARKS.md", START, END, body, write_text_atomic)
    print(body)


if __name__ == "__main__":
    main()
