"""The benchmark scripts' own logic (no episodes run): the stress benchmark's paired draws and ratios,
the targets script's vendor-style arms, and scene_tables' replacement of one scene's tables."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture()
def bench() -> Iterator[dict[str, ModuleType]]:
    sys.path.insert(0, str(BENCH))
    try:
        import intermittent_targets
        import scene_tables
        import stress_bench

        yield {"stress": stress_bench, "tables": scene_tables, "targets": intermittent_targets}
    finally:
        sys.path.remove(str(BENCH))


def _ep(scene: str, strategy: str, **kw: float) -> dict:
    base = {"scene": scene, "strategy": strategy, "duty_cycle": 0.5, "on_switches": 2, "intervention": 1.0,
            "goals_reached": 1, "goal_times_s": [1.0], "duration_s": 4.0, "min_off_s": None, "collisions": 0}
    return {**base, **kw}


def test_stress_ratios_are_isf_over_cbf_on_the_same_draws(bench) -> None:  # type: ignore[no-untyped-def]
    st = bench["stress"]
    res = [_ep("a", "cbf"), _ep("a", "cbf", duty_cycle=0.3, goal_times_s=[2.0]),
           _ep("a", "isf", duty_cycle=0.2, on_switches=3, min_off_s=0.2, goal_times_s=[3.0]),
           _ep("a", "isf", duty_cycle=0.2, intervention=3.0, min_off_s=0.4, goal_times_s=[], collisions=2),
           _ep("b", "cbf"), _ep("b", "isf", duty_cycle=0.25), {"scene": "b", "strategy": "isf", "failure": "x"}]
    rows = {r["scene"]: r for r in st.ratios(res, ["a", "b"], {"a": 1, "b": 1})}
    a = rows["a"]
    assert a["duty"] == pytest.approx(0.2 / 0.4) and a["switches"] == pytest.approx(2.5 / 2)
    assert a["intervention"] == pytest.approx(2.0 / 1.0) and a["goals_isf"] == pytest.approx(1.0)
    # time to the first goal: an episode without it counts its whole duration (4 s)
    assert a["time_cbf"] == pytest.approx(1.5) and a["time_isf"] == pytest.approx(3.5)
    assert a["short_off_episodes"] == 1 and a["min_off_s"] == pytest.approx(0.2) and a["violation_episodes"] == 1
    # failures are left out; "all" pools the episodes and weights the scenes' times by their episodes
    assert rows["b"]["episodes"] == 1 and rows["all"]["episodes"] == 3
    assert rows["all"]["time_isf"] == pytest.approx((3.5 * 2 + 1.0) / 3)
    assert "| a | 2 | 0.50 | 1.25 | 2.00 |" in st.ratio_table(list(rows.values()))


def test_stress_defaults_draw_the_same_scene_and_alpha(bench) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.arm import load_scene

    st = bench["stress"]
    sc = load_scene("panda_pole")
    d = st.draw(sc, 0, 0, 7)
    assert d == st.draw(sc, 0, 0, 7)  # the same command gives the same draws
    assert d != st.draw(sc, 0, 0, 8)
    # the isf values are drawn in both modes (so the rest of the draw is the mode's too); --defaults ignores them
    assert set(d["isf"]) >= {"c", "b", "blend", "horizon"} and 2.0 <= d["alpha"] <= 10.0


def test_stress_start_slack_is_the_robust_condition_at_rest(bench) -> None:  # type: ignore[no-untyped-def]
    import mujoco

    from isf_robot.arm import load_scene
    from isf_robot.arm.collision import CollisionBarriers
    from isf_robot.arm.episode import EpisodeSetup, episode_setup
    from isf_robot.arm.joint_limits import JointLimitBarriers

    st = bench["stress"]
    sc = load_scene("panda_pole")
    setup = episode_setup(sc, 0)
    data = mujoco.MjData(sc.model)
    data.qpos[sc.qpos_adr] = setup.q0
    mujoco.mj_forward(sc.model, data)
    near = CollisionBarriers.from_scene(sc).near(data)
    joints = JointLimitBarriers.from_scene(sc)
    alpha, d_bar = 5.0, 0.04
    # static obstacles: Lf h = 0, so each row's slack is alpha h - |dh/dq| d_bar
    want = min(np.min(alpha * near.h - np.linalg.norm(near.grad, axis=1) * d_bar),
               np.min(alpha * joints.values(data) - np.linalg.norm(joints.grad, axis=1) * d_bar))
    assert st.start_slack(sc, setup, alpha, d_bar) == pytest.approx(float(want), rel=1e-12)
    assert st.start_slack(sc, setup, alpha, 10.0) < st.start_slack(sc, setup, alpha, 0.0)  # d_bar enters as -|J| d_bar
    near_far = EpisodeSetup(q0=setup.q0, goals=setup.goals, time_offset=setup.time_offset)
    assert st.start_slack(sc, near_far, alpha, 0.0) > 0.0  # at rest, without disturbance, a safe start is robust
    # panda_moving draw 109: the ball closes in on an arm at rest 1.2 mm outside the margin; the draw is made again
    moving = load_scene("panda_moving")
    d_bar_m = 0.0445
    d = st.draw(moving, 0, 2, 109)
    scene = st.perturbed(load_scene("panda_moving"), d)
    assert st.start_slack(scene, episode_setup(scene, 109), d["alpha"], d_bar_m) < -0.1
    r = st.run_one({"scene": "panda_moving", "scene_index": 2, "strategy": "cbf", "index": 109, "seed": 0,
                    "duration": 0.05, "d_bar": d_bar_m, "defaults": True})
    assert r["redraws_at_rest"] >= 1 and "failure" not in r


def test_targets_vendor_arms_are_files_with_configs(bench) -> None:  # type: ignore[no-untyped-def]
    tg = bench["targets"]
    specs = tg.vendor_specs()
    assert [Path(s.model).stem for s in specs] == list(tg.VENDOR)
    for s in specs:
        assert Path(s.model).is_file() and Path(s.config).is_file() and s.name is None


def test_scene_tables_replace_keeps_the_other_scenes(bench, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    tb = bench["tables"]
    path = tmp_path / "R.md"
    path.write_text(f"# R\n\n{tb.START}\nMeasured then.\n\n### a: A\n\nold a\n\n### b: B\n\nold b\n{tb.END}\n\nrest\n")
    body = tb.replaced(path, ["b"], ["### b: B", "", "new b", ""], "Measured now by `python x.py --episodes 2`.")
    assert body.startswith("Measured then.\nMeasured now (b only) by `python x.py --episodes 2 --scenes b --replace`.")
    assert "old a" in body and "new b" in body and "old b" not in body
    assert body.index("### a: A") < body.index("### b: B")
