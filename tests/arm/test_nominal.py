"""Nominal controllers, the low-level velocity tracker and the d_bar calibration."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from isf_robot.arm import (
    GoalSequence,
    JointPDController,
    ReachingController,
    VelocityTracker,
    calibrate_d_bar,
    load_scene,
    load_scene_from_files,
)
from isf_robot.core import ConfigError, ShapeError

# ----------------------------------------------------------------------------- goals


def test_goal_sequence_reach_dwell_advance_loop() -> None:
    g = GoalSequence(2, [0.5, 0.0], tolerance=0.1, loop=True)
    g.update(0.0, 1.0)
    assert (g.index, g.reached) == (0, 0)
    g.update(1.0, 0.05)  # arrive at goal 0
    assert (g.index, g.reached) == (0, 1)
    g.update(1.4, 0.05)  # still dwelling
    assert g.index == 0
    g.update(1.5, 0.5)  # dwell over (even if it drifted away)
    assert g.index == 1
    g.update(1.6, 0.01)  # arrive at goal 1, no dwell
    g.update(1.7, 0.01)
    assert (g.index, g.reached) == (0, 2)  # looped


def test_goal_sequence_holds_last_goal_without_loop() -> None:
    g = GoalSequence(1, [0.0], tolerance=0.1, loop=False)
    for t in (0.0, 0.1, 0.2, 0.3):
        g.update(t, 0.0)
    assert (g.index, g.reached) == (0, 1)


def test_goal_sequence_timeout_gives_up() -> None:
    g = GoalSequence(3, [0.0, 0.0, 0.0], tolerance=0.1, timeout=2.0)
    g.update(0.0, 1.0)
    g.update(1.9, 1.0)
    assert g.index == 0
    g.update(2.0, 1.0)
    assert (g.index, g.missed, g.reached) == (1, 1, 0)


@pytest.mark.parametrize("kwargs", [dict(n_goals=0, dwell=[], tolerance=0.1),
                                    dict(n_goals=1, dwell=[-1.0], tolerance=0.1),
                                    dict(n_goals=1, dwell=[0.0], tolerance=0.0),
                                    dict(n_goals=1, dwell=[0.0], tolerance=0.1, timeout=0.0)])
def test_goal_sequence_rejects_bad_input(kwargs: dict) -> None:
    with pytest.raises(ConfigError):
        GoalSequence(**kwargs)


# ----------------------------------------------------------------------------- reaching


def _data_at(scene, q):  # type: ignore[no-untyped-def]
    data = mujoco.MjData(scene.model)
    data.qpos[scene.qpos_adr] = q
    mujoco.mj_forward(scene.model, data)
    return data


def test_reaching_command_decreases_goal_error(planar, rng) -> None:  # type: ignore[no-untyped-def]
    ctrl = ReachingController(planar, max_joint_acc=math.inf)
    jac = np.zeros((3, planar.model.nv))
    for _ in range(10):
        q = planar.home + rng.normal(0.0, 0.3, planar.n_joints)
        data = _data_at(planar, q)
        u = ctrl(0.0, data)
        mujoco.mj_jacSite(planar.model, data, jac, None, planar.ee_site_id)
        err = ctrl.goal_positions[ctrl.goal_index] - data.site_xpos[planar.ee_site_id]
        # first-order change of |err|^2 along u is negative
        assert float(err @ (jac[:, planar.dof_adr] @ u)) > 0.0
        assert np.max(np.abs(u)) <= ctrl.max_joint_speed + 1e-12


@pytest.mark.parametrize("jit", [True, False])
def test_reaching_matches_dls_formula(planar, jit) -> None:  # type: ignore[no-untyped-def]
    ctrl = ReachingController(planar, kp=1.0, max_ee_speed=100.0, max_joint_speed=100.0,
                              max_joint_acc=math.inf, damping=0.1, jit=jit)
    data = _data_at(planar, planar.home)
    u = ctrl(0.0, data)
    jac = np.zeros((3, planar.model.nv))
    mujoco.mj_jacSite(planar.model, data, jac, None, planar.ee_site_id)
    j = jac[:, planar.dof_adr]
    v = ctrl.goal_positions[0] - data.site_xpos[planar.ee_site_id]
    expected = j.T @ np.linalg.solve(j @ j.T + 0.01 * np.eye(3), v)
    np.testing.assert_allclose(u, expected, rtol=1e-10, atol=1e-12)


def test_reaching_rate_limit_starts_at_rest(planar) -> None:  # type: ignore[no-untyped-def]
    ctrl = ReachingController(planar, max_joint_acc=10.0)
    data = _data_at(planar, planar.home)
    u0 = ctrl(0.0, data).copy()
    u1 = ctrl(0.002, data).copy()
    assert np.all(u0 == 0.0)
    assert np.max(np.abs(u1 - u0)) <= 10.0 * 0.002 + 1e-12
    ctrl.reset()
    assert np.all(ctrl(0.0, data) == 0.0)


def test_reaching_rejects_bad_goals(planar) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ShapeError):
        ReachingController(planar, goals=np.zeros((2, 2)))
    with pytest.raises(ConfigError):
        ReachingController(planar, kp=-1.0)


def test_joint_pd_converges_on_kinematic_model(planar) -> None:  # type: ignore[no-untyped-def]
    target = planar.home + np.array([0.2, -0.1, 0.3])
    ctrl = JointPDController(planar, target, kp=3.0, max_joint_acc=math.inf, loop=False)
    data = _data_at(planar, planar.home)
    dt = 0.01
    for k in range(400):
        u = ctrl(k * dt, data)
        data.qpos[planar.qpos_adr] += u * dt
    np.testing.assert_allclose(data.qpos[planar.qpos_adr], target, atol=1e-3)
    assert ctrl.goals_reached == 1
    with pytest.raises(ShapeError):
        JointPDController(planar, np.zeros(5))


# ----------------------------------------------------------------------------- tracking


def test_tracker_follows_constant_velocity(planar) -> None:  # type: ignore[no-untyped-def]
    model = planar.model
    data = planar.make_data()
    tr = VelocityTracker(planar)
    tr.reset(data)
    u = np.array([0.3, -0.2, 0.1])
    for i in range(400):  # 0.4 s, far from the poles for these speeds
        mujoco.mj_step1(model, data)
        if i % 2 == 0:
            tr.set_command(u, 0.002)
        tr.apply(data)
        mujoco.mj_step2(model, data)
    np.testing.assert_allclose(data.qvel[planar.dof_adr], u, atol=2e-3)



def test_tracker_views_equal_the_indexed_path() -> None:
    """``apply`` works in views bound once per MjData; the indexed path (copies) gives the same numbers (1e-12).

    Two Panda arms stepped side by side with changing commands (torque limits reached too); the
    second tracker is forced onto the indexed path. Then the first is handed a fresh MjData: it
    must write that one's ``ctrl`` (rebinding), not the old one's.
    """
    scene = load_scene("panda_pole")
    model = scene.model
    datas = [scene.make_data(), scene.make_data()]
    trackers = [VelocityTracker(scene), VelocityTracker(scene)]
    for tr, d in zip(trackers, datas):
        mujoco.mj_forward(model, d)
        tr.reset(d)
    trackers[1]._data, trackers[1]._views = datas[1], None  # the indexed path
    rng = np.random.default_rng(7)
    for i in range(300):
        u = rng.normal(scale=1.5 if i % 50 < 5 else 0.3, size=scene.n_joints)
        for tr, d in zip(trackers, datas):
            mujoco.mj_step1(model, d)
            tr.set_command(u, 0.001)
            tr.apply(d)
        np.testing.assert_allclose(datas[0].ctrl, datas[1].ctrl, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(trackers[0].q_ref, trackers[1].q_ref, rtol=1e-12, atol=1e-12)
        for d in datas:
            mujoco.mj_step2(model, d)
    assert trackers[0]._views is not None and trackers[1]._views is None
    assert np.any(np.abs(datas[0].ctrl) >= np.abs(model.actuator_ctrlrange[:scene.n_joints, 1]) - 1e-12)
    fresh, other = scene.make_data(), scene.make_data()
    before = datas[0].ctrl.copy()
    for tr, d in ((trackers[0], fresh), (VelocityTracker(scene), other)):
        mujoco.mj_forward(model, d)
        tr.reset(d)
        tr.set_command(np.full(scene.n_joints, 0.1), 0.001)
        mujoco.mj_step1(model, d)
        tr.apply(d)
    assert np.array_equal(datas[0].ctrl, before)  # the old data is left alone
    assert np.array_equal(fresh.ctrl, other.ctrl) and not np.array_equal(fresh.ctrl, before)


_NO_MOTOR_XML = """
<mujoco>
  <option timestep="0.001"/>
  <worldbody>
    <body name="l1">
      <joint name="j1" type="hinge" axis="0 0 1" range="-2 2" limited="true"/>
      <geom name="g1" type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
      <site name="ee" pos="0.3 0 0"/>
    </body>
    <geom name="wall" type="box" size="0.05 0.05 0.05" pos="0.5 0.3 0"/>
  </worldbody>
  <actuator><position joint="j1" kp="10"/></actuator>
</mujoco>
"""

_NO_MOTOR_TOML = """
[scene]
name = "tiny"
description = "one link"
model = "tiny.xml"
[robot]
joints = ["j1"]
ee_site = "ee"
geoms = ["g1"]
[obstacles]
geoms = ["wall"]
[task]
[[task.goals]]
pos = [0.0, 0.3, 0.0]
[control]
period = 0.001
"""


def test_tracker_rejects_non_motor_actuators(tmp_path: Path) -> None:
    (tmp_path / "tiny.xml").write_text(_NO_MOTOR_XML)
    (tmp_path / "tiny.toml").write_text(_NO_MOTOR_TOML)
    scene = load_scene_from_files(tmp_path / "tiny.xml", tmp_path / "tiny.toml")
    with pytest.raises(ConfigError, match="not a motor"):
        VelocityTracker(scene)


def test_tracker_rejects_bad_gains(planar) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError):
        VelocityTracker(planar, kp=[1.0, 2.0])
    with pytest.raises(ConfigError):
        VelocityTracker(planar, kd=-1.0)


# ----------------------------------------------------------------------------- calibration


def test_calibration_measures_and_caches(planar) -> None:  # type: ignore[no-untyped-def]
    cal = calibrate_d_bar(planar, duration=1.0)
    assert 0.0 < cal.quantile_value <= cal.max_error
    assert cal.d_bar == pytest.approx(cal.factor * cal.quantile_value)
    assert cal.samples == 1000
    assert calibrate_d_bar(planar, duration=1.0) is cal
    # a smooth task alone is tracked far better than the bound with command steps
    smooth = calibrate_d_bar(planar, duration=1.0, excitation=0.0, use_cache=False)
    assert smooth.quantile_value < cal.quantile_value
    # the scene's model is left untouched (contacts are switched off on a copy)
    assert all(planar.model.geom_contype[g] != 0 for g in planar.obstacle_geom_ids)


def test_calibration_rejects_bad_parameters(planar) -> None:  # type: ignore[no-untyped-def]
    for kw in (dict(duration=0.0), dict(quantile=1.5), dict(factor=0.5), dict(switch_period=0.0)):
        with pytest.raises(ConfigError):
            calibrate_d_bar(planar, **kw)


def test_calibration_of_moving_scene(planar_moving) -> None:  # type: ignore[no-untyped-def]
    cal = calibrate_d_bar(planar_moving, duration=0.5)
    assert math.isfinite(cal.d_bar) and cal.d_bar > 0
    assert dataclasses.asdict(cal) == cal.as_dict()


def test_panda_calibration_is_small_for_smooth_tracking() -> None:
    panda = load_scene("panda_pole")
    cal = calibrate_d_bar(panda, duration=1.0, excitation=0.0, use_cache=False)
    assert cal.max_error < 0.1
