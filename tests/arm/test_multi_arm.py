"""Arms sharing a workspace: [[arm]] tables, inter-arm rows, central and decentral (share) filters."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, collision_pairs, list_scenes, load_scene, load_scene_from_files
from isf_robot.arm.arms import geom_arms
from isf_robot.arm.config_toml import parse_config
from isf_robot.arm.multi_arm import MultiArmSimulation, run_team
from isf_robot.arm.one_arm import arm_scene
from isf_robot.arm.team_nominal import TeamReaching
from isf_robot.core import ConfigError, FilterSpec, LieData, QPSolver, UnknownNameError
from isf_robot.core.shares import row_agents
from isf_robot.core.strategies import make_strategy
from isf_robot.core.team import CentralFilter, SharedFilter


def _arm(p: str, x: float, yaw: float) -> str:
    return f"""
    <body name="{p}l1" pos="{x} 0 0.2" euler="0 0 {yaw}">
      <joint name="{p}q1" type="hinge" axis="0 0 1" range="-2.9 2.9" damping="0.5" armature="0.01"/>
      <geom name="{p}g1" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
      <body name="{p}l2" pos="0.3 0 0">
        <joint name="{p}q2" type="hinge" axis="0 0 1" range="-2.6 2.6" damping="0.5" armature="0.01"/>
        <geom name="{p}g2" type="capsule" fromto="0 0 0 0.25 0 0" size="0.025" mass="0.6"/>
        <site name="{p}ee" pos="0.27 0 0" size="0.01"/>
      </body>
    </body>"""


TWO_ARMS_XML = f"""<mujoco><compiler angle="radian"/><option timestep="0.002"/><worldbody>
  {_arm("a_", 0.0, 0.0)}{_arm("b_", 0.9, 3.14159265)}
  <geom name="post" type="capsule" fromto="0.45 0.45 0 0.45 0.45 0.3" size="0.03"/>
  <site name="a_g1" pos="0.5 0.22 0.2"/><site name="a_g2" pos="0.5 -0.22 0.2"/>
  <site name="b_g1" pos="0.4 -0.22 0.2"/><site name="b_g2" pos="0.4 0.22 0.2"/>
</worldbody><actuator>
  <motor joint="a_q1" ctrlrange="-20 20" ctrllimited="true"/><motor joint="a_q2" ctrlrange="-15 15" ctrllimited="true"/>
  <motor joint="b_q1" ctrlrange="-20 20" ctrllimited="true"/><motor joint="b_q2" ctrlrange="-15 15" ctrllimited="true"/>
</actuator></mujoco>"""

TWO_ARMS_TOML = """
[scene]
name = "two_arms"
model = "two_arms.xml"

[[arm]]
name = "a"
prefix = "a_"
joints = ["q1", "q2"]
geoms = ["g1", "g2"]
ee_site = "ee"
home = [0.3, -0.6]
goals = [{ site = "g1", dwell = 0.1 }, { site = "g2", dwell = 0.1 }]

[[arm]]
name = "b"
prefix = "b_"
like = "a"

[obstacles]
geoms = ["post"]

[task]
duration = 3.0

[barrier]
cutoff = 0.25

[gains]
max_ee_speed = 0.6
tracking_kp = [300.0, 200.0]  # one arm's: every arm gets them
tracking_kd = [30.0, 20.0]

[filter]
alpha = 5.0
c = 0.05
b = 0.02
d_bar = 0.05
"""


@pytest.fixture(scope="module")
def two_arms(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    d = tmp_path_factory.mktemp("two_arms")
    (d / "two_arms.xml").write_text(TWO_ARMS_XML)
    (d / "two_arms.toml").write_text(TWO_ARMS_TOML)
    return load_scene_from_files(d / "two_arms.xml", d / "two_arms.toml")


# ----------------------------------------------------------------------------- the schema


def test_arm_tables_build_the_robot(two_arms) -> None:  # type: ignore[no-untyped-def]
    cfg = two_arms.config
    assert cfg.robot.joints == ("a_q1", "a_q2", "b_q1", "b_q2")
    assert cfg.robot.geoms == ("a_g1", "a_g2", "b_g1", "b_g2")
    assert [a.name for a in two_arms.arms] == ["a", "b"]
    assert cfg.arms[1].goals[0].site == "b_g1"  # 'like' takes the names as written, then the arm's prefix
    np.testing.assert_allclose(two_arms.home, [0.3, -0.6, 0.3, -0.6])
    assert cfg.gains.tracking_kp == (300.0, 200.0, 300.0, 200.0)  # one arm's gains stand for every arm's
    np.testing.assert_allclose(two_arms.goal_positions[two_arms.arms[1].goals], [[0.4, -0.22, 0.2], [0.4, 0.22, 0.2]])
    one = arm_scene(two_arms, 1)
    assert one.n_joints == 2 and one.joint_names == ("b_q1", "b_q2") and one.arms == ()


@pytest.mark.parametrize(("edit", "message"), [
    (lambda t: t.replace('[obstacles]', '[robot]\nee_site = "a_ee"\ngeoms = ["a_g1"]\n[obstacles]'), "not both"),
    (lambda t: t.replace('like = "a"', 'like = "c"'), "valid: ['a']"),
    (lambda t: t.replace('home = [0.3, -0.6]', 'home = [0.3]'), "expected 2 numbers"),
    (lambda t: t.replace('[task]', '[task]\ngoals = [{ site = "a_g1" }]'), "each arm's goals"),
    (lambda t: t.replace('prefix = "b_"', 'prefix = "b_"\nspeed = 1'), "unknown key 'speed'"),
    (lambda t: t.replace('prefix = "b_"', 'prefix = "b_"\nself_collision = true'), "the same value"),
])
def test_bad_arm_tables_say_what_is_valid(edit, message) -> None:  # type: ignore[no-untyped-def]
    import tomllib

    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("]", r"\]").replace("(", r"\(")):
        parse_config(tomllib.loads(edit(TWO_ARMS_TOML)), origin="two_arms.toml")


def test_unknown_arm_geom_lists_the_model_names(tmp_path: Path) -> None:
    (tmp_path / "two_arms.xml").write_text(TWO_ARMS_XML)
    (tmp_path / "two_arms.toml").write_text(TWO_ARMS_TOML.replace('geoms = ["g1", "g2"]', 'geoms = ["g1", "g9"]'))
    with pytest.raises(UnknownNameError, match="a_g9"):
        load_scene_from_files(tmp_path / "two_arms.xml", tmp_path / "two_arms.toml")


def test_single_arm_scene_has_no_arms_and_unchanged_pairs() -> None:
    sc = load_scene("panda_pole")
    assert sc.arms == ()
    assert CollisionBarriers.from_scene(sc).pairs.k == 28


def test_self_collision_of_every_arm_adds_each_arms_own_pairs() -> None:
    sc = load_scene("panda_quad")  # self_collision = true in the first [[arm]], taken by the others through 'like'
    assert [a.self_collision for a in sc.config.arms] == [True] * 4
    p = CollisionBarriers.from_scene(sc).pairs
    arm = geom_arms(sc.arms, np.arange(sc.model.ngeom))
    same = arm[p.geom1] == arm[p.geom2]
    one = collision_pairs(sc.model, sc.arms[0].geom_ids, [], margin=0.0, self_collision=True, self_margin=0.01)
    assert same.sum() == 4 * one.k and np.all(p.margin[same] == 0.01)  # each arm's own pairs, with self_margin
    assert np.all(p.margin[p.is_self & ~same] == 0.02) and (p.is_self & ~same).sum() == 6 * 14 * 14  # arm-arm


# ----------------------------------------------------------------------------- inter-arm rows


def test_inter_arm_rows_match_finite_differences(two_arms, rng, fd_grad) -> None:  # type: ignore[no-untyped-def]
    cb = CollisionBarriers.from_scene(two_arms)
    p = cb.pairs
    between = [i for i, (g1, g2) in enumerate(zip(p.geom1, p.geom2))
               if {two_arms.model.geom(int(g1)).name[0], two_arms.model.geom(int(g2)).name[0]} == {"a", "b"}]
    assert len(between) == 4 and p.is_self[between].all()  # every a-b geom pair, as two-moving-body rows
    m, d = two_arms.model, mujoco.MjData(two_arms.model)
    checked = 0
    for _ in range(40):
        d.qpos[:] = rng.uniform([-0.2, -1.5, -0.2, -1.5], [0.8, 1.5, 0.8, 1.5])
        mujoco.mj_forward(m, d)
        b = cb.evaluate(d)
        rows = [i for i in between if b.active[i] and b.h[i] > 0.01]
        if not rows:
            continue
        fd = fd_grad(m, d, lambda dd: cb.evaluate(dd).h[rows], two_arms.dof_adr)
        np.testing.assert_allclose(b.grad[rows], fd, atol=1e-6)
        assert np.all(np.abs(b.grad[rows][:, :2]).sum(axis=1) > 0)  # arm a's joints move the distance
        assert np.all(np.abs(b.grad[rows][:, 2:]).sum(axis=1) > 0)  # and arm b's
        checked += len(rows)
    assert checked >= 10


# ----------------------------------------------------------------------------- the share


def test_shares_meet_the_pair_condition(rng) -> None:  # type: ignore[no-untyped-def]
    """Whatever the nominal, the agents' commands together meet every row's robust condition (cbf and isf)."""
    spec = FilterSpec(alpha=5.0, c=0.05, b=0.02, d_bar=0.05, blend=0.0, horizon=0.0)
    blocks = (slice(0, 2), slice(2, 4))
    for name in ("cbf", "isf"):
        team = SharedFilter([make_strategy(name, spec, solver=QPSolver(few_rows=True)) for _ in blocks],
                            blocks, ("a", "b"), 0.002)
        for k in range(300):
            lg = rng.normal(size=(3, 4))
            lg[0, 2:] = 0.0  # row 0: arm a's only (an obstacle row); row 2 shared (2 rows per arm: feasible)
            lg[1, :2] = 0.0  # row 1: arm b's only
            lie = LieData(rng.uniform(0.0, 0.2, 3), rng.normal(0.0, 0.3, 3), lg, np.linalg.norm(lg, axis=1))
            u_nom = rng.normal(0.0, 2.0, 4)
            step = team.step_lie(k * 0.002, lie, u_nom)
            lhs = lie.lf + lie.lg @ step.u - lie.grad_norm * spec.d_bar
            assert np.all(lhs >= -spec.alpha * lie.h - 1e-7), (name, k)
            if not step.on:
                np.testing.assert_array_equal(step.u, u_nom)
        np.testing.assert_array_equal(row_agents(lg, blocks), [[1, 0], [0, 1], [1, 1]])


@pytest.mark.parametrize("coordination", ["central", "decentral"])
def test_team_run_is_safe_and_its_arm_figures_add_up(two_arms, coordination) -> None:  # type: ignore[no-untyped-def]
    nominal = run_team(two_arms, "nominal", coordination, duration=3.0, seed=0)
    assert nominal.contacts["arm-arm"] > 0 or nominal.run.collisions > 0  # the tasks cross: the arms collide
    # the nominal's clearance by kind is measured too (it has no rows of its own): at the ticks, never below the
    # run's true-geometry minimum over every physics step, and the arm-arm pairs the closest on this crossing
    assert np.isfinite(nominal.clearance["arm-arm"]) and np.isfinite(nominal.clearance["arm-obstacle"])
    assert min(nominal.clearance.values()) >= nominal.run.min_barrier - 1e-12
    assert nominal.clearance["arm-arm"] == min(nominal.clearance.values())
    for strategy in ("cbf", "isf"):
        r = run_team(two_arms, strategy, coordination, duration=3.0, seed=0)
        assert r.violations == 0 and r.run.collisions == 0 and r.run.fallbacks == 0, (strategy, r.contacts)
        assert r.clearance["arm-arm"] > 0.0
        arms = r.arms
        assert [a["name"] for a in arms] == ["a", "b"]
        # intervention is a sum over joints: the arms' shares add up to the team's
        assert sum(a["intervention"] for a in arms) == pytest.approx(r.run.metrics.intervention, rel=1e-9, abs=1e-12)
        assert sum(a["goals_reached"] for a in arms) == r.run.goals_reached
        assert any(a["coordination_steps"] > 0 for a in arms)
        for a in arms:
            assert a["coordination_steps"] <= round(a["duty_cycle"] * a["control_steps"]) + 1
            assert a["coordination_events"] <= a["coordination_steps"]
            if coordination == "central":
                assert a["duty_cycle"] == pytest.approx(r.run.metrics.duty_cycle)


def test_clearance_by_kind_is_each_kinds_smallest_tick_value(two_arms) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.core import Observer

    records = []

    class Keep(Observer):
        def on_step(self, record):  # type: ignore[no-untyped-def]
            records.append(record)

    sim = MultiArmSimulation(two_arms, "nominal", coordination="central", seed=0, observers=[Keep()])
    r = sim.run_team(2.0)
    pairs, arm = sim.coll.pairs, sim.geom_arm
    a1, a2 = arm[pairs.geom1], arm[pairs.geom2]
    kind = np.where((a1 >= 0) & (a2 >= 0), np.where(a1 != a2, "arm-arm", "self"), "arm-obstacle")
    want = dict.fromkeys(r.clearance, np.inf)
    for rec in records:  # (a record's h: the tick's values; its witness names: the pairs within the cut-off)
        for name in rec.witness_names:
            i = rec.names.index(name)
            want[kind[i]] = min(want[kind[i]], rec.h[i])
    assert r.clearance == want and np.isfinite(want["arm-arm"])


def test_team_reaching_stacks_each_arms_controller(two_arms) -> None:  # type: ignore[no-untyped-def]
    team = TeamReaching(two_arms)
    d = two_arms.make_data()
    mujoco.mj_step1(two_arms.model, d)
    u = team(0.01, d).copy()
    for i, c in enumerate(team.arms):
        c.reset()
        np.testing.assert_allclose(u[two_arms.arms[i].joints], c(0.01, d))


def test_single_arm_paths_refuse_several_arms(two_arms) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.arm.nominal import ReachingController
    from isf_robot.arm.sim import ArmSimulation

    for build in (lambda: ReachingController(two_arms), lambda: ArmSimulation(two_arms, "cbf", d_bar=0.05)):
        with pytest.raises(ConfigError, match="has 2 arms: its nominal task is every arm's"):
            build()


def test_multi_arm_simulation_refuses_one_arm_and_unknown_coordination(two_arms) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError, match="one arm"):
        MultiArmSimulation(load_scene("planar"), "cbf", d_bar=0.05)
    with pytest.raises(UnknownNameError, match="central"):
        MultiArmSimulation(two_arms, "cbf", coordination="both")


# ----------------------------------------------------------------------------- the command line


@pytest.fixture(scope="module")
def two_arm_files(two_arms):  # type: ignore[no-untyped-def]
    return ["--model", str(two_arms.xml_path), "--config", str(two_arms.config.source)]


@pytest.fixture(scope="module")
def decentral_recording(two_arm_files, tmp_path_factory):  # type: ignore[no-untyped-def]
    """``(path, run JSON)`` of one recorded 3 s isf run of the two arms per arm, shared by the tests that read it."""
    pytest.importorskip("rerun")
    import contextlib
    import io

    from isf_robot.cli import main

    rrd = tmp_path_factory.mktemp("decentral") / "pair.rrd"
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["run", *two_arm_files, "--filter", "isf", "--coordination", "decentral", "--duration", "3",
                     "--rrd", str(rrd), "--json"]) == 0
    return rrd, json.loads(out.getvalue())


def test_run_prints_a_line_per_arm(capsys, two_arm_files) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    assert main(["run", *two_arm_files, "--filter", "isf", "--coordination", "decentral", "--duration", "1"]) == 0
    out = capsys.readouterr().out
    assert "(decentral)" in out and "penetrating contacts" in out
    lines = out.splitlines()
    assert sum(ln.split()[0] in ("a", "b") for ln in lines if ln.strip()) == 2
    assert main(["run", *two_arm_files, "--filter", "cbf", "--duration", "1", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["coordination"] == "central" and [a["name"] for a in d["arms"]] == ["a", "b"]
    assert d["violations"] == 0 and d["schema"].startswith("isf-robot-run")


def test_compare_runs_each_way_on_the_same_seeds(capsys, two_arm_files) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    assert main(["compare", *two_arm_files, "--filters", "cbf", "isf", "--episodes", "1", "--duration", "1",
                 "--json", "--quiet"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert set(d["results"]) == {"cbf/central", "cbf/decentral", "isf/central", "isf/decentral"}
    assert all(r["violations"] == 0 and len(r["arms"]) == 2 for r in d["results"].values())
    # --jobs 2: the same episodes in worker processes, the same figures (only the wall time per step differs)
    assert main(["compare", *two_arm_files, "--filters", "cbf", "isf", "--episodes", "1", "--duration", "1",
                 "--json", "--quiet", "--jobs", "2"]) == 0
    par = json.loads(capsys.readouterr().out)
    assert d["partial"] is False and par["partial"] is False
    for key, row in d["results"].items():
        assert {k: v for k, v in par["results"][key].items() if k != "step_us"} == \
            {k: v for k, v in row.items() if k != "step_us"}, key


def test_coordination_on_one_arm_is_a_one_line_error(capsys) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    assert main(["run", "--scene", "planar", "--coordination", "decentral", "--duration", "0.1", "--d-bar", "0.1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "several arms" in err and "'planar' has one" in err


def test_init_writes_an_arm_table_per_arm(tmp_path: Path) -> None:
    import shutil

    from isf_robot.arm.starter import starter_toml
    from isf_robot.paths import models_dir

    for f in ("panda_pair.xml", "panda_arm.xml"):
        shutil.copy(models_dir() / f, tmp_path / f)
    text = starter_toml(tmp_path / "panda_pair.xml")
    assert text.count("\n[[arm]]") == 2 and "\n[robot]" not in text and 'prefix = "right_"' in text
    (tmp_path / "panda_pair.toml").write_text(text)
    sc = load_scene_from_files(tmp_path / "panda_pair.xml", tmp_path / "panda_pair.toml")  # loads as it is
    assert [a.name for a in sc.arms] == ["left", "right"] and sc.n_joints == 14
    assert sc.config.arms[1].goals[0].site == "right_goal_a"
    assert CollisionBarriers.from_scene(sc).pairs.k == 252


def test_per_arm_intervention_reads_back_from_a_recording(decentral_recording) -> None:  # type: ignore[no-untyped-def]
    """The recording's per-joint correction ``u - u_nom``, summed over each arm's joints, gives the arm's figure."""
    from isf_robot.record import read_columns

    rrd, d = decentral_recording
    col = read_columns(rrd, "/plots/joints/correction", ["Scalars:scalars"])["Scalars:scalars"]
    assert col.shape == (d["control_steps"], 4)
    for arm, cols in zip(d["arms"], (slice(0, 2), slice(2, 4))):
        again = float(np.sum(col[:, cols] ** 2) * d["control_period"])
        assert again == pytest.approx(arm["intervention"], rel=1e-9, abs=1e-12), arm["name"]
    assert sum(a["intervention"] for a in d["arms"]) > 0  # the filter acted


@pytest.mark.parametrize("name", [s.name for s in list_scenes() if load_scene(s.name).arms])
def test_shipped_multi_arm_tasks_collide_without_a_filter(name: str) -> None:
    """Every arm's nominal task, rolled out kinematically (q_dot = u_nom), brings two arms into contact."""
    sc = load_scene(name)
    cb, team = CollisionBarriers.from_scene(sc), TeamReaching(sc)
    m, d = sc.model, sc.make_data()
    arm = geom_arms(sc.arms, np.arange(m.ngeom))
    between = np.flatnonzero((arm[cb.pairs.geom1] >= 0) & (arm[cb.pairs.geom2] >= 0))  # (arm-arm pairs)
    q, dt, worst = sc.home.copy(), 0.01, np.inf
    for k in range(int(6.0 / dt)):
        d.qpos[sc.qpos_adr] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        worst = min(worst, float(np.min(cb.evaluate(d).h[between])))
        if worst < 0.0:
            break
        q = q + dt * team(k * dt, d)
    assert worst < 0.0


# ----------------------------------------------------------------------------- promotion and off hold of a team


def _one_row(h: float = 0.01) -> LieData:
    return LieData(np.array([h]), np.zeros(1), np.array([[1.0]]), np.ones(1))


def test_unpromotable_row_keeps_the_robust_condition_only() -> None:
    """On, a row with ``Xi_on < c`` is promoted (``Lg h u >= b``) unless ``promotable`` leaves it out."""
    spec = FilterSpec(alpha=5.0, c=0.05, b=0.02, d_bar=0.0, blend=0.0, horizon=0.0)
    u = {}
    for promotable in (None, np.array([False])):
        f = make_strategy("isf", spec)
        step = f.step_lie(0.0, _one_row(), np.array([-1.0]), promotable=promotable)
        assert step.on
        u[promotable is None] = float(step.u[0])
    assert u[True] == pytest.approx(0.02, abs=1e-6)  # promoted: the pair opens at rate b
    assert u[False] == pytest.approx(-0.05, abs=1e-6)  # robust condition: may close at alpha h


def test_team_promotes_no_shared_row_and_holds_off() -> None:
    """Central and per arm: a shared row keeps its (share of the) robust condition; off only after the hold."""
    spec = FilterSpec(alpha=5.0, c=0.05, b=0.02, d_bar=0.0, blend=0.0, horizon=0.0, off_hold=0.01)
    blocks = (slice(0, 1), slice(1, 2))
    lie = LieData(np.array([0.01]), np.zeros(1), np.array([[1.0, 1.0]]), np.ones(1) * np.sqrt(2))  # shared row
    teams = [CentralFilter(make_strategy("isf", spec), blocks, ("a", "b"), 0.002),
             SharedFilter([make_strategy("isf", spec) for _ in blocks], blocks, ("a", "b"), 0.002)]
    for team in teams:
        step = team.step_lie(0.0, lie, np.array([-1.0, -1.0]))
        assert step.on and float(lie.lg[0] @ step.u) == pytest.approx(-0.05, abs=1e-6)  # not held apart at b
        t, offs = 0.002, []
        while t < 0.05:
            offs.append((t, team.step_lie(t, lie, np.array([1.0, 1.0])).on))
            t += 0.002
        first_off = next(s for s, on in offs if not on)
        assert 0.01 <= first_off <= 0.0101  # on at 0 (the condition failed there): off once it held 0.01 s


def test_isf_team_passes_the_head_on_crossing() -> None:
    """panda_pair seed 1: promoting the inter-arm rows held the arms apart on the crossing (4 goals in 7 s, on
    0.52 of the time); with only the robust condition on them they pass each other (6 goals, on 0.35)."""
    r = run_team(load_scene("panda_pair"), "isf", "central", duration=7.0, seed=1, d_bar=0.12)
    assert r.violations == 0
    assert r.run.goals_reached >= 6
    assert all(a["goals_missed"] == 0 and a["duty_cycle"] < 0.45 for a in r.arms)


def test_a_team_gets_the_designed_predictive_off_trigger() -> None:
    from isf_robot.arm.params import resolve_params

    pair, pole = load_scene("panda_pair"), load_scene("panda_pole")
    designed = resolve_params(pole, d_bar=0.1).horizon
    assert designed > 0.0 and resolve_params(pair, d_bar=0.1).horizon == designed  # (as one arm's)
    assert resolve_params(pair, d_bar=0.1, horizon=0.0).horizon == 0.0  # (an explicit value still applies)


def test_the_rollout_leaves_the_steps_nominal_command_alone() -> None:
    """The team's rollout calls every arm's controller at predicted states: the step's nominal command stays the
    tick's. (It did not while the team controller returned one buffer for every call: the nominal command jumped
    to a rollout point's every few steps, the tracking error q99 rose to 0.44 rad/s against ``d_bar`` 0.12.)"""
    from isf_robot.arm.params import resolve_params

    pair = load_scene("panda_pair")
    cmds: list[np.ndarray] = []

    class Steps:
        def on_start(self, info): ...  # type: ignore[no-untyped-def]
        def on_step(self, rec): cmds.append(np.asarray(rec.u_nom).copy())  # type: ignore[no-untyped-def]
        def on_event(self, ev): ...  # type: ignore[no-untyped-def]
        def on_finish(self, summary): ...  # type: ignore[no-untyped-def]
        def on_abort(self, exc): ...  # type: ignore[no-untyped-def]

    sim = MultiArmSimulation(pair, "isf", coordination="central", seed=1, observers=[Steps()],
                             params=resolve_params(pair, d_bar=0.12, horizon=0.26))
    r = sim.run(3.0)
    assert sim.strategy.inner.predictor.rollouts >= 10  # (the rollout ran)
    a_max = max(c._rate.a_max for c in sim.nominal.arms)
    jumps = np.abs(np.diff(np.array(cmds), axis=0)).max()
    assert jumps <= a_max * sim.control_period * (1 + 1e-9)  # (the controllers' rate limit: nothing else moves it)
    assert r.tracking_error_q99 < 0.12
    u1, u2 = sim.nominal(0.0, sim.last_episode.data), sim.nominal(0.0, sim.last_episode.data)
    assert u1 is not u2  # (a fresh array each call)


@pytest.mark.parametrize("coordination", ["central", "decentral"])
def test_each_arms_series_read_back_give_its_figures(capsys, two_arm_files, tmp_path: Path, coordination) -> None:  # type: ignore[no-untyped-def]
    """Each arm's logged mode, correction and barrier series give back the run's per-arm figures."""
    pytest.importorskip("rerun")
    from isf_robot.cli import main
    from isf_robot.core.metrics import compute_metrics
    from isf_robot.record import read_columns, read_rrd, replay_metrics

    rrd = tmp_path / f"pair_{coordination}.rrd"
    assert main(["run", *two_arm_files, "--filter", "isf", "--coordination", coordination, "--duration", "3",
                 "--rrd", str(rrd), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    n, T = d["control_steps"], d["control_period"]
    (log,) = read_rrd(rrd)
    assert list(log.arms) == ["a", "b"]
    per_arm_min = []
    for arm in d["arms"]:
        name = arm["name"]
        on = read_columns(rrd, f"/arms/{name}/mode", ["Scalars:scalars"])["Scalars:scalars"]
        corr = read_columns(rrd, f"/arms/{name}/correction_norm", ["Scalars:scalars"])["Scalars:scalars"]
        hmin = read_columns(rrd, f"/arms/{name}/barrier_min", ["Scalars:scalars"])["Scalars:scalars"]
        assert on.shape == corr.shape == hmin.shape == (n,)
        assert set(np.unique(on)) <= {0.0, 1.0}
        assert float(np.mean(on)) == pytest.approx(arm["duty_cycle"], abs=1e-12)
        assert int(np.sum(np.diff(np.concatenate(([0.0], on))) > 0)) == arm["on_switches"]
        assert float(np.sum(corr ** 2) * T) == pytest.approx(arm["intervention"], rel=1e-9, abs=1e-12)
        cols = log.arms[name]  # the arm's replay columns: every figure of the run, recomputed
        again = compute_metrics(cols["t"], cols["dt"], cols["on"], cols["intervention_rate"], cols["qp_solved"])
        for key in ("on_switches", "short_offs"):  # counts exactly, figures to rounding
            assert again.as_dict()[key] == arm[key], (name, key)
        for key in ("duty_cycle", "min_off_s", "mean_off_s", "intervention"):
            want = arm[key]
            assert again.as_dict()[key] == (None if want is None else pytest.approx(want, rel=1e-12, abs=1e-15)), key
        ee = read_columns(rrd, f"/world/arms/{name}/ee", ["Points3D:positions"])["Points3D:positions"]
        assert ee.shape == (n, 1, 3) or ee.shape == (n, 3)
        per_arm_min.append(float(hmin.min()))
    if coordination == "central":  # one filter: every arm's mode is its mode
        np.testing.assert_array_equal(log.arms["a"]["on"], log.steps["on"])
    else:  # the team is on when any arm's filter is on
        np.testing.assert_array_equal(log.arms["a"]["on"] | log.arms["b"]["on"], log.steps["on"])
    assert sum(a["duty_cycle"] > 0 for a in d["arms"]) >= 1
    # every collision pair is some arm's: the smallest of the arms' minima is the run's clearance at the ticks
    measured = [v for v in d["clearance"].values() if v is not None]  # (JSON: a kind with no pair in reach is null)
    assert min(per_arm_min) == pytest.approx(min(measured), abs=1e-12)
    assert replay_metrics(log)["arms"][1]["duty_cycle"] == d["arms"][1]["duty_cycle"]


def test_replay_of_a_team_recording_prints_each_arm(capsys, decentral_recording) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    rrd, d = decentral_recording
    assert main(["replay", str(rrd)]) == 0
    out = capsys.readouterr().out
    assert "per arm:" in out
    header = next(ln for ln in out.splitlines()[out.splitlines().index(next(
        ln for ln in out.splitlines() if ln.endswith("per arm:"))):] if ln.startswith("metric"))
    assert header.split()[1:] == ["a", "b"]
    assert main(["replay", str(rrd), "--json"]) == 0
    m = json.loads(capsys.readouterr().out)["recordings"][0]["metrics"]
    assert m["duty_cycle"] == d["duty_cycle"] and m["intervention"] == pytest.approx(d["intervention"], rel=1e-12)
    assert [(a["name"], a["duty_cycle"], a["on_switches"]) for a in m["arms"]] == [
        (a["name"], a["duty_cycle"], a["on_switches"]) for a in d["arms"]]


def test_team_blueprint_has_a_tab_per_arm() -> None:
    pytest.importorskip("rerun")
    from isf_robot.record.blueprints import team_blueprint
    from isf_robot.record.errors import RecordError

    def tabs(x):  # type: ignore[no-untyped-def]
        if type(x).__name__ == "Tabs":
            return [[v.origin for v in tab.contents] for tab in x.contents]
        return next((t for y in (getattr(x, "contents", None) or []) if not isinstance(y, str)
                     for t in [tabs(y)] if t), None)

    bp = team_blueprint(["left", "right"], duration_s=2.0, c=0.05)
    assert tabs(bp.root_container) == [[f"/arms/{a}/{s}" for s in ("mode", "barrier_min", "correction_norm")]
                                       for a in ("left", "right")]
    with pytest.raises(RecordError, match="at least one arm"):
        team_blueprint([])


def test_plot_draws_a_team_recording_per_arm(capsys, decentral_recording, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """``plot`` on a team recording: the team's row and a row per arm, each from that arm's logged series."""
    pytest.importorskip("rerun")
    pytest.importorskip("matplotlib")
    from isf_robot.cli import main
    from isf_robot.plots import RunSeries, team_run_figure
    from isf_robot.record import read_rrd
    from isf_robot.record.figure_data import arm_series, team_arm_series

    rrd, d = decentral_recording
    png = tmp_path / "team.png"
    assert main(["plot", str(rrd), "-o", str(png)]) == 0
    assert png.stat().st_size > 1000 and "team run" in capsys.readouterr().err
    (log,) = read_rrd(rrd)
    arms = [RunSeries(**a) for a in team_arm_series(log)]
    team = RunSeries(**arm_series(log))
    fig = team_run_figure(team, arms, list(log.arms))
    axes = fig.get_axes()
    assert len(axes) == 1 + 2 * len(arms)
    for i, (arm, run) in enumerate(zip(d["arms"], arms)):
        assert float(np.mean(run.on)) == pytest.approx(arm["duty_cycle"], abs=1e-12)
        assert len(run.intervals) == arm["on_switches"] + (1 if run.on[0] else 0)
        h_line = axes[1 + 2 * i].get_lines()[0]
        np.testing.assert_array_equal(h_line.get_ydata(), run.h)  # the arm's own barrier series, as logged
        assert axes[1 + 2 * i].get_title(loc="left").startswith(f"{arm['name']}: duty cycle")


def test_plot_draws_a_team_comparison_per_arm(capsys, two_arm_files, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """``compare --rrd DIR`` on a team writes a recording per run; ``plot`` draws each arm per way, as does its JSON."""
    pytest.importorskip("rerun")
    pytest.importorskip("matplotlib")
    from isf_robot.cli import main
    from isf_robot.plots import TeamBars
    from isf_robot.record import read_many
    from isf_robot.record.figure_data import team_bars

    out = tmp_path / "cmp"
    assert main(["compare", *two_arm_files, "--filters", "cbf", "isf", "--episodes", "1", "--duration", "2",
                 "--rrd", str(out), "--json", "--quiet"]) == 0
    d = json.loads(capsys.readouterr().out)
    files = sorted(p.name for p in out.glob("*.rrd"))
    assert files == [f"two_arms-{s}-{w}-seed0.rrd" for s in ("cbf", "isf") for w in ("central", "decentral")]
    bars = [TeamBars(**b) for b in team_bars(read_many([out]), ["cbf", "isf"])]
    assert [b.group for b in bars] == ["cbf/central", "cbf/decentral", "isf/central", "isf/decentral"]
    for b in bars:  # each arm's replayed figures are the compare's (one episode: the means)
        row = d["results"][b.group]["arms"]
        assert b.arms == ("a", "b")
        np.testing.assert_allclose(b.duty_cycle[0], [a["duty_cycle"] for a in row], rtol=0, atol=1e-12)
        np.testing.assert_allclose(b.intervention[0], [a["intervention"] for a in row], rtol=1e-9)
    png = tmp_path / "cmp.png"
    assert main(["plot", str(out), "-o", str(png)]) == 0
    assert png.stat().st_size > 1000 and "4 way(s) of filtering" in capsys.readouterr().err
    doc = tmp_path / "cmp.json"
    doc.write_text(json.dumps(d))
    svg = tmp_path / "cmp.svg"
    assert main(["plot", str(doc), "-o", str(svg)]) == 0
    assert svg.stat().st_size > 1000
    mixed = list(out.glob("*.rrd"))[:1]
    single = tmp_path / "one.rrd"
    assert main(["run", "--scene", "planar", "--duration", "0.2", "--d-bar", "0.1", "--rrd", str(single)]) == 0
    capsys.readouterr()
    assert main(["plot", str(mixed[0]), str(single), "-o", str(png)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "one kind at a time" in err


def test_sweep_runs_a_team_each_way_with_each_arms_figures(capsys, two_arm_files, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """A tiny sweep of a team: every point once per way of filtering; each arm's figures are those of `run`."""
    from isf_robot.cli import main

    assert main(["sweep", *two_arm_files, "--filters", "isf", "--c", "0.02,0.1", "--episodes", "1",
                 "--duration", "2", "--json", "--quiet"]) == 0
    doc = json.loads(capsys.readouterr().out)
    (sc,) = doc["scenes"]
    labels = [r["label"] for r in sc["points"]]
    assert labels == ["isf/central c=0.02", "isf/decentral c=0.02", "isf/central c=0.1", "isf/decentral c=0.1"]
    for r in sc["points"]:
        assert r["coordination"] in ("central", "decentral") and [a["name"] for a in r["arms"]] == ["a", "b"]
        assert r["violations"] == 0
        (run,) = r["runs"]
        assert r["duty_cycle"] == run["duty_cycle"]  # the team's: a filter on
        assert max(a["duty_cycle"] for a in r["arms"]) <= r["duty_cycle"] + 1e-12
    # the same episode through `run`: each arm's figures are the sweep's
    row = sc["points"][3]
    assert main(["run", *two_arm_files, "--filter", "isf", "--coordination", "decentral", "--c", "0.1",
                 "--duration", "2", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert sum(a["duty_cycle"] for a in d["arms"]) > 0  # the filters acted
    for a, b in zip(row["arms"], d["arms"]):
        assert (a["name"], a["duty_cycle"], a["on_switches"], a["min_off_all_s"]) == (
            b["name"], b["duty_cycle"], b["on_switches"], b["min_off_s"])
        assert a["intervention"] == pytest.approx(b["intervention"], rel=1e-12)
    # the text output: the Pareto table and the per-arm table
    assert main(["sweep", *two_arm_files, "--filters", "cbf", "--episodes", "1", "--duration", "1",
                 "--coordination", "central", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "cbf/central" in out and "per arm" in out and "cbf/decentral" not in out
    assert sum(ln.split()[1:2] in (["a"], ["b"]) for ln in out.splitlines() if ln.startswith("cbf/central")) == 2


def test_sweep_refusals_on_teams_are_one_line(capsys, two_arm_files, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    for argv, words in (
        ([*two_arm_files, "--write-config", str(tmp_path / "f.toml")], ("--write-config", "2 arms")),
        (["--scenes", "planar", "--coordination", "central", "--d-bar", "0.1"], ("several arms", "planar")),
        ([*two_arm_files, "--level", "torque"], ("torque", "2 arms")),
    ):
        assert main(["sweep", *argv, "--episodes", "1", "--duration", "0.2", "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and all(w in err for w in words), err
    assert not (tmp_path / "f.toml").exists()


def test_render_takes_the_coordination(two_arm_files, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    out = tmp_path / "pair.png"
    proc = subprocess.run([sys.executable, "-m", "isf_robot.cli", "render", *two_arm_files, "--filter", "isf",
                           "--coordination", "decentral", "--duration", "0.2", "-o", str(out), "--width", "96",
                           "--height", "72"], capture_output=True, text=True, env=env, timeout=300)
    if proc.returncode == 2 and "offscreen rendering is not available" in proc.stderr:
        pytest.skip(f"no offscreen OpenGL here: {proc.stderr.strip()}")
    assert proc.returncode == 0, proc.stderr
    assert out.stat().st_size > 0 and "isf decentral, seed 0" in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "isf_robot.cli", "render", "--scene", "planar", "--coordination",
                           "central", "-o", str(out)], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1 and "several arms" in proc.stderr


def test_check_on_a_team_finds_no_chatter_risk_with_the_design() -> None:
    """A team's filters get the designed hand-over and predictive off trigger, as one arm's: `check` has nothing."""
    from isf_robot.arm.diagnostics import filter_findings

    assert filter_findings(load_scene("panda_pair")) == []


def test_a_team_simulation_runs_again_the_same_and_takes_the_given_solver(two_arms) -> None:  # type: ignore[no-untyped-def]
    """A second run of the same simulation object gives the first's figures (nothing kept from the first run's
    rollouts), and a decentral team's arms use the solver it was given."""
    solver = QPSolver(few_rows=True)
    from isf_robot.arm import resolve_params

    params = resolve_params(two_arms, d_bar=0.1, horizon=0.1, calibrate=False)  # (with a rollout shared by the arms)
    sim = MultiArmSimulation(two_arms, "isf", coordination="decentral", seed=0, params=params, solver=solver)
    assert all(f.solver is solver for f in sim.strategy.agents)
    first, second = sim.run_team(1.5), sim.run_team(1.5)
    assert first.arms == second.arms and first.clearance == second.clearance
    with pytest.raises(ConfigError, match="TeamReaching"):
        MultiArmSimulation(two_arms, "isf", nominal=object(), d_bar=0.1)  # type: ignore[arg-type]


def test_each_way_builds_only_its_own_filters(two_arms, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Central: one strategy over every joint; decentral: one per arm, each with its own solver unless one is
    given, and no central strategy built to be thrown away."""
    from isf_robot.arm import multi_arm, sim

    made: list[str] = []

    def counting(real):  # type: ignore[no-untyped-def]
        def make(*a, **kw):  # type: ignore[no-untyped-def]
            made.append(real.__module__)
            return real(*a, **kw)
        return make

    monkeypatch.setattr(sim, "make_strategy", counting(sim.make_strategy))
    monkeypatch.setattr(multi_arm, "make_strategy", counting(multi_arm.make_strategy))
    central = MultiArmSimulation(two_arms, "cbf", coordination="central", seed=0, d_bar=0.1)
    assert len(made) == 1 and isinstance(central.strategy, CentralFilter)
    made.clear()
    decentral = MultiArmSimulation(two_arms, "cbf", coordination="decentral", seed=0, d_bar=0.1)
    assert len(made) == 2 and isinstance(decentral.strategy, SharedFilter)
    a, b = decentral.strategy.agents
    assert a.solver is not b.solver


def test_the_off_hold_is_a_filter_parameter_of_teams(two_arms) -> None:  # type: ignore[no-untyped-def]
    """`off_hold` ([filter] key, --off-hold): the team's filters take it; validated; recorded; one arm's is 0 unless
    given."""
    from isf_robot.arm import ArmSimulation
    from isf_robot.arm.multi_arm import OFF_HOLD_S
    from isf_robot.arm.params import resolve_params

    base = resolve_params(two_arms, d_bar=0.1, calibrate=False)
    assert base.off_hold is None and "off_hold" not in base.as_info()
    for way in ("central", "decentral"):
        sim = MultiArmSimulation(two_arms, "isf", coordination=way, params=base)
        assert _holds(sim) == {OFF_HOLD_S} and sim.params.off_hold == OFF_HOLD_S  # (the default, recorded)
        sim = MultiArmSimulation(two_arms, "isf", coordination=way, params=base.replace(off_hold=0.25))
        assert _holds(sim) == {0.25}
        sim = MultiArmSimulation(two_arms, "isf", coordination=way, params=base.replace(off_hold=0.25), off_hold=0.0)
        assert _holds(sim) == {0.0}  # (the argument first)
    assert base.replace(off_hold=0.3).as_info()["off_hold"] == 0.3
    with pytest.raises(ConfigError, match="off_hold must be >= 0"):
        base.replace(off_hold=-0.1)
    assert FilterSpec.from_mapping({"off_hold": 0.2}).off_hold == 0.2
    pole = load_scene("panda_pole")
    assert ArmSimulation(pole, "isf", params=resolve_params(pole, d_bar=0.1, calibrate=False)).strategy.trigger.off_hold == 0
    one = ArmSimulation(pole, "isf", params=resolve_params(pole, d_bar=0.1, off_hold=0.2, calibrate=False))
    assert one.strategy.trigger.off_hold == 0.2
    from isf_robot.arm.torque_sim import TorqueSimulation, resolve_torque_params

    torque = resolve_torque_params(pole, d_bar=0.5, off_hold=0.2, calibrate=False)
    assert TorqueSimulation(pole, "isf", params=torque).strategy.trigger.off_hold == 0.2  # (the torque level too)


def _holds(sim: MultiArmSimulation) -> set[float]:
    agents = [sim.strategy.inner] if sim.coordination == "central" else sim.strategy.agents
    return {a.trigger.off_hold for a in agents}
