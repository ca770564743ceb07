"""Actuator adapters: kind detection, torque path unchanged, position and velocity servos."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from isf_robot.arm import VelocityTracker, calibrate_d_bar, load_scene, load_scene_from_files
from isf_robot.arm.actuation import ServoTracker, TorqueTracker, actuator_info, make_actuation
from isf_robot.core import ConfigError, ShapeError
from isf_robot.paths import models_dir

MOTORS = """    <motor name="m1" joint="j1" class="planar" ctrlrange="-20 20"/>
    <motor name="m2" joint="j2" class="planar" ctrlrange="-15 15"/>
    <motor name="m3" joint="j3" class="planar" ctrlrange="-8 8"/>"""


def planar_with(tmp_path: Path, actuators: str, damping: float | None = None):  # type: ignore[no-untyped-def]
    """The shipped planar scene with its motors replaced by ``actuators`` (files in tmp_path)."""
    src = models_dir()
    arm = (src / "planar_arm.xml").read_text()
    assert MOTORS in arm
    arm = arm.replace(MOTORS, actuators)
    if damping is not None:
        arm = arm.replace('damping="0.5"', f'damping="{damping}"')
    (tmp_path / "planar_arm.xml").write_text(arm)
    (tmp_path / "scene.xml").write_text((src / "planar.xml").read_text())
    toml = (src / "planar.toml").read_text().replace('name = "planar"', 'name = "servo"')
    (tmp_path / "scene.toml").write_text(toml)
    return load_scene_from_files(tmp_path / "scene.xml", tmp_path / "scene.toml")


POSITION = """    <position joint="j1" kp="400" kv="20" forcerange="-20 20" ctrlrange="-2.9 2.9"/>
    <general joint="j2" gainprm="300" biastype="affine" biasprm="0 -300 -15" forcerange="-15 15"/>
    <position joint="j3" kp="100" forcerange="-8 8"/>"""

VELOCITY = """    <velocity joint="j1" kv="40" forcerange="-20 20"/>
    <velocity joint="j2" kv="30" gear="2" forcerange="-15 15"/>
    <velocity joint="j3" kv="10" ctrlrange="-1 1"/>"""


def test_kinds_are_read_from_the_model(tmp_path) -> None:  # type: ignore[no-untyped-def]
    sc = planar_with(tmp_path, POSITION)
    infos = [actuator_info(sc.model, a) for a in sc.actuator_ids]
    assert [i.kind for i in infos] == ["position"] * 3
    assert [(i.kp, i.kv) for i in infos] == [(400.0, 20.0), (300.0, 15.0), (100.0, 0.0)]
    assert [i.force_limit for i in infos] == [20.0, 15.0, 8.0]
    np.testing.assert_array_equal(sc.torque_limit, [20.0, 15.0, 8.0])  # forcerange, not ctrlrange
    vel = planar_with(tmp_path, VELOCITY)
    vinfo = [actuator_info(vel.model, a) for a in vel.actuator_ids]
    assert [i.kind for i in vinfo] == ["velocity"] * 3
    assert [i.gear for i in vinfo] == [1.0, 2.0, 1.0] and vinfo[1].force_limit == 30.0
    panda = load_scene("panda_pole")
    assert {actuator_info(panda.model, a).kind for a in panda.actuator_ids} == {"torque"}


@pytest.mark.parametrize("bad, words", [
    ('<general joint="j1" gainprm="300" biastype="affine" biasprm="0.1 -300 -15"/>', "neither a motor"),
    ('<general joint="j1" gainprm="300" biastype="affine" biasprm="0 -200 0"/>', "neither a motor"),
    ('<intvelocity joint="j1" kp="100" actrange="-2 2"/>', "INTEGRATOR"),
])
def test_unsupported_actuators_are_named(tmp_path, bad, words) -> None:  # type: ignore[no-untyped-def]
    acts = POSITION.replace(POSITION.splitlines()[0].strip(), bad)
    sc = planar_with(tmp_path, acts)
    with pytest.raises(ConfigError, match=words) as exc:
        make_actuation(sc)
    assert "joint 'j1'" in str(exc.value) and "supported:" in str(exc.value)


def test_mixed_motors_and_servos_are_rejected(tmp_path) -> None:  # type: ignore[no-untyped-def]
    acts = MOTORS.replace(MOTORS.splitlines()[2], POSITION.splitlines()[2])
    with pytest.raises(ConfigError, match="mix motors and servos"):
        make_actuation(planar_with(tmp_path, acts))


def test_torque_path_is_the_velocity_tracker_to_the_bit(planar) -> None:  # type: ignore[no-untyped-def]
    a, b = make_actuation(planar), VelocityTracker(planar)
    assert isinstance(a, TorqueTracker) and a.kinds == ("torque",) * 3
    da, db = planar.make_data(), planar.make_data()
    a.reset(da)
    b.reset(db)
    rng = np.random.default_rng(3)
    for k in range(200):
        if k % 2 == 0:
            u = rng.uniform(-1, 1, 3)
            a.set_command(u, 0.002)
            b.set_command(u, 0.002)
        for tr, d in ((a, da), (b, db)):
            mujoco.mj_step1(planar.model, d)
            tr.apply(d)
            mujoco.mj_step2(planar.model, d)
    np.testing.assert_array_equal(da.qpos, db.qpos)
    np.testing.assert_array_equal(da.ctrl, db.ctrl)


def test_a_command_of_the_wrong_length_is_refused(planar) -> None:  # type: ignore[no-untyped-def]
    # (the compiled step reads the command by the tracker's joint count: a short one must not be read past its end)
    tr = VelocityTracker(planar)
    d = planar.make_data()
    tr.reset(d)
    for u in (np.zeros(2), np.zeros(4), [0.0, 0.0]):
        with pytest.raises(ShapeError, match="velocity command of .* joints for a tracker of 3"):
            tr.command(d, u, 0.002)
    tr.command(d, np.zeros(3), 0.002)


def _hold(scene, tracker, u: np.ndarray, seconds: float) -> mujoco.MjData:  # type: ignore[no-untyped-def]
    m = scene.model
    d = scene.make_data()
    tracker.reset(d)
    period = scene.config.control.period
    every = int(round(period / m.opt.timestep))
    for k in range(int(round(seconds / m.opt.timestep))):
        mujoco.mj_step1(m, d)
        if k % every == 0:  # the command is re-sent every control period, as in a run
            tracker.set_command(u, period)
        tracker.apply(d)
        mujoco.mj_step2(m, d)
    return d


def test_position_servo_follows_a_constant_command(tmp_path) -> None:  # type: ignore[no-untyped-def]
    sc = planar_with(tmp_path, POSITION)
    u = np.array([0.3, -0.2, 0.25])
    tr = make_actuation(sc)
    assert isinstance(tr, ServoTracker) and tr.kinds == ("position",) * 3
    d = _hold(sc, tr, u, 1.0)
    np.testing.assert_allclose(d.qvel[sc.dof_adr], u, atol=2e-3)
    # the lead makes up for the damping (servo kv + joint damping 0.5) over kp
    np.testing.assert_allclose(tr.lead, [(20 + 0.5) / 400, (15 + 0.5) / 300, 0.5 / 100])
    # a plain integrated target lags by (kv + b) / kp * u but moves at the same speed
    plain = make_actuation(sc, feedforward=False)
    d2 = _hold(sc, plain, u, 1.0)
    np.testing.assert_allclose(d2.qvel[sc.dof_adr], u, atol=2e-3)
    lag = d.qpos[sc.qpos_adr] - d2.qpos[sc.qpos_adr]
    np.testing.assert_allclose(lag, tr.lead * u, rtol=0.05, atol=2e-4)
    assert not tr.saturated(d).any()


def test_position_target_stays_in_the_joint_range(tmp_path) -> None:  # type: ignore[no-untyped-def]
    sc = planar_with(tmp_path, POSITION)
    tr = make_actuation(sc)
    d = _hold(sc, tr, np.array([3.0, 0.0, 0.0]), 1.0)  # into pole_a: blocked
    assert d.ncon > 0 and abs(d.qvel[sc.dof_adr[0]]) < 0.05
    assert tr.q_ref[0] - d.qpos[sc.qpos_adr[0]] <= tr.max_ref_error + 1e-4  # no wind-up
    sc.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    d = _hold(sc, tr, np.array([3.0, 0.0, 0.0]), 3.0)  # free: into the joint limit (2.9)
    assert d.qpos[sc.qpos_adr[0]] > 2.8
    assert d.ctrl[sc.actuator_ids[0]] <= 2.9


def test_velocity_servo_known_answer(tmp_path) -> None:  # type: ignore[no-untyped-def]
    # one joint moving alone in the horizontal plane: kv (g u - g q_dot) g = b q_dot in steady
    # state, so q_dot = g^2 kv u / (g^2 kv + b); the ctrlrange clips g u
    sc = planar_with(tmp_path, VELOCITY, damping=2.0)
    sc.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)  # free of the poles
    tr = make_actuation(sc)
    for j, (g, kv) in enumerate(((1.0, 40.0), (2.0, 30.0))):
        u = np.zeros(3)
        u[j] = 0.4
        d = _hold(sc, tr, u, 1.5)
        assert d.ctrl[sc.actuator_ids[j]] == pytest.approx(g * 0.4)
        assert d.qvel[sc.dof_adr[j]] == pytest.approx(g * g * kv * 0.4 / (g * g * kv + 2.0), rel=2e-2)
    tr.set_command(np.array([0.0, 0.0, 5.0]))
    d = sc.make_data()
    tr.apply(d)
    assert d.ctrl[sc.actuator_ids[2]] == 1.0


def test_saturation_is_reported_and_calibrated(tmp_path) -> None:  # type: ignore[no-untyped-def]
    weak = POSITION.replace('forcerange="-20 20"', 'forcerange="-0.5 0.5"')
    sc = planar_with(tmp_path, weak)
    tr = make_actuation(sc)
    d = _hold(sc, tr, np.array([1.0, 0.0, 0.0]), 0.2)
    assert tr.saturated(d)[0] and not tr.saturated(d)[1:].any()
    cal = calibrate_d_bar(sc, duration=0.5, use_cache=False)
    assert cal.joint_names == ("j1", "j2", "j3") and len(cal.saturation) == 3
    assert cal.saturation[0] > 0.5 and cal.saturation[2] < 0.5
    strong = calibrate_d_bar(planar_with(tmp_path, POSITION), duration=0.5, use_cache=False)
    assert math.isfinite(strong.d_bar) and strong.d_bar < cal.d_bar


def test_calibration_for_each_kind(tmp_path, planar) -> None:  # type: ignore[no-untyped-def]
    torque = calibrate_d_bar(planar, duration=0.5, use_cache=False)
    assert torque.saturation == pytest.approx((0.0, 0.0, 0.0), abs=0.05)
    for acts in (POSITION, VELOCITY):
        cal = calibrate_d_bar(planar_with(tmp_path, acts), duration=0.5, use_cache=False)
        assert math.isfinite(cal.d_bar) and 0 < cal.d_bar < 2.0


def test_position_servo_feeds_gravity_forward() -> None:
    # the UR5e-like arm held still at home: a plain integrated target sags by gravity / kp
    # (the reference is clipped to the joint, so the sag stays); the feedforward holds it
    sc = load_scene("ur5e_pole")
    d0 = sc.make_data()
    grav = d0.qfrc_bias[sc.dof_adr].copy()
    plain = _hold(sc, make_actuation(sc, feedforward=False), np.zeros(6), 1.0)
    sag = plain.qpos[sc.qpos_adr] - sc.home
    kp = sc.model.actuator_gainprm[sc.actuator_ids[1], 0]
    assert kp == 2000.0  # Menagerie's size3 servo
    np.testing.assert_allclose(sag[1], -grav[1] / kp, rtol=0.05)
    assert abs(sag[1]) > 3e-3
    held = _hold(sc, make_actuation(sc), np.zeros(6), 1.0)
    assert np.max(np.abs(held.qpos[sc.qpos_adr] - sc.home)) < 2e-4


def test_servo_time_constant_is_the_servos_lead() -> None:
    """``tau = (g^2 kv + damping) / (g^2 kp)``: a position servo ``g^2 kp (q* - q) - (g^2 kv + damping) q_dot`` at
    constant speed v lags its target by ``tau v`` (known answers, floats and arrays)."""
    from isf_robot.arm.actuation import servo_time_constant

    assert servo_time_constant(2.0, 100.0, 10.0, 4.0) == pytest.approx((4 * 10 + 4) / (4 * 100))
    np.testing.assert_allclose(servo_time_constant(np.array([1.0, 1.0]), np.array([50.0, 200.0]),
                                                   np.array([5.0, 20.0]), np.array([0.0, 2.0])), [0.1, 0.11])
