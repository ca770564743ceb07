"""The torque level's d_bar: the hold error's floor against a measured step, and safety of cbf with the calibrated d_bar."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from isf_robot.arm import load_scene
from isf_robot.arm.dynamics import ArmDynamics, torque_limits
from isf_robot.arm.torque_calibration import calibrate_torque_d_bar, inner_gain, torque_plant
from isf_robot.arm.torque_sim import TorqueSimulation, resolve_torque_params
from isf_robot.core import ConfigError


@pytest.fixture(scope="module")
def ur5e():  # type: ignore[no-untyped-def]
    return load_scene("ur5e_pole")


def test_one_held_step_moves_q_by_T_qdot_plus_T2_qddot(ur5e) -> None:  # type: ignore[no-untyped-def]
    """The derivation's step: one physics step per period, the model exact, ``q1 - q0 - T q_dot = T^2 q_ddot``."""
    model = torque_plant(ur5e.model)
    data = ur5e.make_data(0.0)
    assert model.opt.timestep == ur5e.config.control.period  # (one physics step per control period)
    T, dof, qadr = model.opt.timestep, np.asarray(ur5e.dof_adr), np.asarray(ur5e.qpos_adr)
    dyn = ArmDynamics(ur5e.model, ur5e.dof_adr)
    rng = np.random.default_rng(3)
    tau_max = torque_limits(ur5e)
    for _ in range(5):
        data.qvel[dof] = rng.uniform(-1.0, 1.0, dof.size)
        mujoco.mj_step1(model, data)
        tau = rng.uniform(-0.5, 0.5, dof.size) * tau_max
        q0, v0, a = data.qpos[qadr].copy(), data.qvel[dof].copy(), dyn.terms(data).acceleration(tau)
        data.qfrc_applied[dof] = tau
        mujoco.mj_step2(model, data)
        np.testing.assert_allclose((data.qvel[dof] - v0) / T, a, rtol=1e-7, atol=1e-7)  # the model is exact
        np.testing.assert_allclose(data.qpos[qadr] - q0 - T * v0, T * T * a, rtol=1e-7, atol=1e-12)


def test_hold_error_is_the_floor_of_d_bar(ur5e) -> None:  # type: ignore[no-untyped-def]
    """With an exact model the model error is nil; d_bar is the hold error alpha_1 T |q_ddot|, linear in alpha_1."""
    alpha_1 = inner_gain(ur5e.config.filter.alpha)
    cal = calibrate_torque_d_bar(ur5e, duration=0.6)
    assert cal.alpha_1 == alpha_1 and cal.model_error_q99 < 1e-9
    assert cal.hold_error_q99 > 0.05  # [rad/s^2]: far above the 4e-14 the model error alone gave
    assert cal.d_bar == pytest.approx(cal.factor * cal.hold_error_q99, rel=1e-9)
    double = calibrate_torque_d_bar(ur5e, duration=0.6, alpha_1=2 * alpha_1)
    assert double.hold_error_q99 == pytest.approx(2 * cal.hold_error_q99, rel=1e-9)
    assert calibrate_torque_d_bar(ur5e, duration=0.6, alpha_1=0.0).d_bar < 1e-9  # no hold term: no floor
    with pytest.raises(ConfigError, match="alpha_1"):
        calibrate_torque_d_bar(ur5e, duration=0.6, alpha_1=-1.0)


@pytest.mark.parametrize("name", ["ur5e_pole", "panda_pole"])
def test_cbf_keeps_the_margin_with_the_calibrated_d_bar(name: str) -> None:
    """The two scenes whose torque-level cbf left the margin before (the hold on ur5e_pole, link7 on link5 on
    panda_pole): with the hold term in d_bar and the self-collision rows, no violation."""
    scene = load_scene(name)
    params = resolve_torque_params(scene)
    assert params.d_bar_source == "torque calibration" and params.d_bar > 0.1
    sim = TorqueSimulation(scene, "cbf", seed=1, params=params)
    assert sim.scene.config.robot.self_collision  # on at the torque level whatever the scene says
    r = sim.run(3.0)
    assert r.collisions == 0 and r.min_barrier > 0.0
    assert r.tau_peak_ratio <= 1.0 + 1e-9


def test_isf_with_the_designed_nominal_gain_keeps_its_off_periods_on_a_ur5e_run(ur5e) -> None:  # type: ignore[no-untyped-def]
    """The torque nominal's designed gain (max_joint_acc / max_joint_speed = 20 /s on the UR5e scene, 40 /s before):
    on this run (seed 0, 3 s) every off period lasts at least 0.25 s. Not every episode: over 20 seeds of 8 s the
    shortest is 2 ms, and the Panda scenes chatter (RESULTS.md, "Torque level")."""
    from isf_robot.arm.filter_design import designed_kd
    from isf_robot.core.metrics import CHATTER_OFF_S

    params = resolve_torque_params(ur5e)
    sim = TorqueSimulation(ur5e, "isf", seed=0, params=params)
    assert sim.kd == pytest.approx(designed_kd(ur5e.config)) == pytest.approx(20.0)
    r = sim.run(3.0)
    assert r.on_switches >= 1 and r.min_off_s is not None and r.min_off_s >= CHATTER_OFF_S
    assert r.collisions == 0 and r.min_barrier > 0.0


def test_the_calibration_cache_keeps_each_plant_its_own(ur5e) -> None:  # type: ignore[no-untyped-def]
    """A cached calibration is handed back only for the very plant it ran on: a plant with a payload made after
    another was freed (whose id() Python may reuse) is calibrated afresh; clear_calibration_cache forgets them."""
    import copy

    from isf_robot.arm.calibration import clear_calibration_cache

    light = copy.deepcopy(ur5e.model)
    first = calibrate_torque_d_bar(ur5e, light, duration=0.4)
    assert calibrate_torque_d_bar(ur5e, light, duration=0.4) is first  # (the same plant: the cached one)
    del light
    heavy = copy.deepcopy(ur5e.model)
    hand = int(heavy.site_bodyid[ur5e.ee_site_id]) if ur5e.ee_site_id >= 0 else int(ur5e.ee_body_id)
    heavy.body_mass[hand] += 3.0  # (a payload on the hand: the filter's model no longer matches the plant)
    loaded = calibrate_torque_d_bar(ur5e, heavy, duration=0.4)
    assert loaded is not first and loaded.model_error_q99 > 10 * first.model_error_q99 + 1e-6
    clear_calibration_cache()
    assert calibrate_torque_d_bar(ur5e, heavy, duration=0.4) is not loaded


def test_the_torque_parameters_calibrate_with_the_runs_own_gain(ur5e) -> None:  # type: ignore[no-untyped-def]
    """resolve_torque_params(kd=) calibrates d_bar for that nominal gain, not the designed one."""
    from isf_robot.arm.filter_design import designed_kd

    designed = resolve_torque_params(ur5e)
    same = resolve_torque_params(ur5e, kd=designed_kd(ur5e.config))
    other = resolve_torque_params(ur5e, kd=3.0 * designed_kd(ur5e.config))
    assert same.d_bar == designed.d_bar
    assert other.d_bar == calibrate_torque_d_bar(ur5e, alpha_1=inner_gain(ur5e.config.filter.alpha),
                                                 kd=3.0 * designed_kd(ur5e.config)).d_bar != designed.d_bar


def test_a_control_period_set_in_memory_is_calibrated_for(ur5e) -> None:  # type: ignore[no-untyped-def]
    """A scene whose ``[control] period`` was changed in memory (``--control-period``) gets a calibration of its own
    period, not the cached one of the file's: the hold error (and so ``d_bar``) grows with the period."""
    import dataclasses

    from isf_robot.cli.arm import _with_period

    slow = _with_period(ur5e, 4 * ur5e.config.control.period)
    assert slow.config.control.period == pytest.approx(0.008) and ur5e.config.control.period == pytest.approx(0.002)
    base, held = calibrate_torque_d_bar(ur5e, duration=0.4), calibrate_torque_d_bar(slow, duration=0.4)
    assert held is not base and held.d_bar > 1.5 * base.d_bar
    assert calibrate_torque_d_bar(dataclasses.replace(slow), duration=0.4) is held  # (the same config: cached)
    with pytest.raises(ConfigError, match="whole multiple"):
        _with_period(ur5e, 0.0013)


def test_a_plant_with_other_joints_is_refused_in_one_line() -> None:
    """The plant's states are copied to and from the filter's model: another joint layout is a ConfigError naming
    both, for the simulation and for the calibration (it was a raw ValueError from the copy)."""
    planar = load_scene("planar")
    spec = mujoco.MjSpec.from_file(str(planar.xml_path))
    body = spec.worldbody.add_body(name="extra_body", pos=[5.0, 5.0, 0.0])  # (far away, a joint of its own)
    body.add_joint(name="extra_hinge", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0.0, 0.0, 1.0])
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.01, 0.0, 0.0], contype=0, conaffinity=0)
    other = spec.compile()
    assert other.nq == planar.model.nq + 1
    with pytest.raises(ConfigError, match=r"\(nq, nv, nmocap\)"):
        TorqueSimulation(planar, "cbf", plant=other, d_bar=0.1)
    with pytest.raises(ConfigError, match=r"\(nq, nv, nmocap\)"):
        calibrate_torque_d_bar(planar, other, duration=0.1)


def test_a_calibration_shorter_than_a_control_period_is_refused(ur5e) -> None:  # type: ignore[no-untyped-def]
    """(Both levels' calibrations ended in an IndexError of an empty quantile.)"""
    from isf_robot.arm.calibration import calibrate_d_bar

    for calibrate in (calibrate_torque_d_bar, calibrate_d_bar):
        with pytest.raises(ConfigError, match="must cover a control period"):
            calibrate(ur5e, duration=0.0005)
