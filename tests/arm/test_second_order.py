"""The torque level's second-order barrier rows against MuJoCo's own integration.

Oracle: from a state ``(q, q_dot)`` and a held torque, MuJoCo integrates the arm (RK4, 10 us steps);
a polynomial fitted to the barrier values ``h(t)`` along that motion gives ``h_dot(0)`` and ``h_ddot(0)``,
so ``psi = h_dot + alpha_1 h`` and ``psi_dot = h_ddot + alpha_1 h_dot`` without any Jacobian. The rows'
``psi`` and ``Lf psi + Lg psi tau`` must match them, for every geom type the velocity level supports,
for a moving obstacle and for the joint limits.
"""

from __future__ import annotations

import copy
import dataclasses
import warnings
import zlib

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, JointLimitBarriers, collision_pairs, load_scene
from isf_robot.arm.dynamics import ArmDynamics, torque_limits
from isf_robot.arm.second_order import SecondOrderRows
from isf_robot.core import ConfigError, IsfWarning

ALPHA_1 = 5.0
PAIR_XML = """
<mujoco>
  <compiler angle="radian"/>
  <option ccd_tolerance="1e-10" integrator="RK4" timestep="1e-5"><flag contact="disable"/></option>
  <asset>
    <mesh name="boxmesh" vertex="-.1 -.08 -.06  .1 -.08 -.06  -.1 .08 -.06  .1 .08 -.06
                                 -.1 -.08  .06  .1 -.08  .06  -.1 .08  .06  .1 .08  .06"/>
  </asset>
  <worldbody>
    <body name="l1">
      <joint name="j1" axis="0 0 1" damping="0.3" range="-2 2"/>
      <geom name="a1" type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
      <body name="l2" pos="0.4 0 0">
        <joint name="j2" axis="0 1 0" range="-2 2"/>
        <geom name="r" type="{t}" size="{s}" pos="0.15 0 0" euler="0.2 0.4 0"/>
      </body>
    </body>
    <geom name="o" type="{ot}" {os} pos="0.5 0.05 0.02" euler="0.3 0.2 0.1"/>
  </worldbody>
</mujoco>
"""
ROBOT_TYPES = [("sphere", "0.05"), ("capsule", "0.04 0.1"), ("cylinder", "0.04 0.08")]
OBSTACLE_TYPES = [("sphere", 'size="0.08"'), ("capsule", 'size="0.05 0.12"'), ("mesh", 'mesh="boxmesh"'),
                  ("box", 'size="0.1 0.08 0.06"'), ("cylinder", 'size="0.06 0.1"'),
                  ("ellipsoid", 'size="0.1 0.06 0.05"')]
SPAN, SAMPLES = 1e-3, 11  # the fitted stretch of the motion [s] and its samples


def motion_fit(model, data, h_of, tau, dof, clock=None):  # type: ignore[no-untyped-def]
    """``(h, h_dot, h_ddot)`` at the state in ``data`` (restored after) under the held torque ``tau``."""
    q0, v0, t0 = data.qpos.copy(), data.qvel.copy(), data.time
    every = int(round(SPAN / (SAMPLES - 1) / model.opt.timestep))
    ts, hs = [], []
    for i in range(SAMPLES):
        if i:
            for _ in range(every):
                data.qfrc_applied[dof] = tau
                mujoco.mj_step(model, data)
                if clock is not None:
                    clock(data, data.time)
        mujoco.mj_forward(model, data)
        ts.append(data.time - t0)
        hs.append(h_of(data))
    c = np.polynomial.polynomial.polyfit(np.array(ts), np.array(hs), 5)
    data.qpos[:], data.qvel[:], data.time = q0, v0, t0
    data.qfrc_applied[:] = 0.0
    if clock is not None:
        clock(data, t0)
    mujoco.mj_forward(model, data)
    return c[0], c[1], 2.0 * c[2]


def check_rows(model, data, rows, rng, clock=None, lin_of=None, tol=2e-3):  # type: ignore[no-untyped-def]
    """The tick's psi rows against the motion fit, under a random torque; returns the rows checked."""
    dyn = ArmDynamics(model, rows.coll.dof_adr)
    mujoco.mj_forward(model, data)
    lin = lin_of(data.time) if lin_of is not None else None
    psi, tick = rows.tick(data, data.time, dyn.terms(data), lin)
    tau = rng.uniform(-2.0, 2.0, rows.coll.dof_adr.size)
    idx, nc = tick[1], tick[1].size

    def h_of(d):  # type: ignore[no-untyped-def]
        return np.concatenate((rows.coll.evaluate(d, lin_of(d.time) if lin_of else None).h[idx],
                               rows.joints.values(d)))

    h, hd, hdd = motion_fit(model, data, h_of, tau, rows.coll.dof_adr, clock)
    np.testing.assert_allclose(tick[0].h, h, atol=1e-9)
    np.testing.assert_allclose(psi.h, hd + ALPHA_1 * h, atol=tol, rtol=tol)
    np.testing.assert_allclose(psi.lf + psi.lg @ tau, hdd + ALPHA_1 * hd, atol=10 * tol, rtol=tol)
    np.testing.assert_allclose(psi.grad_norm, np.linalg.norm(tick[0].lg, axis=1))
    return nc


@pytest.mark.parametrize(("t", "s"), ROBOT_TYPES)
@pytest.mark.parametrize(("ot", "os"), OBSTACLE_TYPES)
def test_psi_and_its_lie_derivatives_match_the_integrated_motion(t, s, ot, os) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(zlib.crc32(f"{t}|{ot}".encode()))
    m = mujoco.MjModel.from_xml_string(PAIR_XML.format(t=t, s=s, ot=ot, os=os))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IsfWarning)
        coll = CollisionBarriers(m, collision_pairs(m, [m.geom("r").id], [m.geom("o").id], margin=0.01), [0, 1],
                                 cutoff=0.3)
    joints = JointLimitBarriers([0, 1], m.jnt_range.copy(), 0.05, ("j1", "j2"))
    rows = SecondOrderRows(coll, joints, [0, 1], ALPHA_1)
    d = mujoco.MjData(m)
    checked = 0
    for _ in range(60):
        d.qpos[:] = rng.uniform(-0.6, 0.6, 2)
        d.qvel[:] = rng.uniform(-1.5, 1.5, 2)
        mujoco.mj_forward(m, d)
        dist = coll.evaluate(d).h[0] + 0.01
        if not 0.01 < dist < 0.2:
            continue
        checked += check_rows(m, d, rows, rng)
        if checked >= 3:
            break
    assert checked >= 3


def integration_scene(name: str):  # type: ignore[no-untyped-def]
    """A shipped scene on a copy of its model for the oracle: RK4 at 10 us, no contacts, no actuator forces."""
    scene = load_scene(name)
    model = copy.deepcopy(scene.model)
    model.opt.timestep, model.opt.integrator = 1e-5, int(mujoco.mjtIntegrator.mjINT_RK4)
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION) | int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    return dataclasses.replace(scene, model=model)


def moving_clock(sc):  # type: ignore[no-untyped-def]
    """The scene's moving obstacles at time ``t`` in ``d`` and their velocities (an ObstacleClock)."""

    def clock(d, t):  # type: ignore[no-untyped-def]
        sc.set_moving_obstacles(d, t)
        return sc.mocap_velocities(t)[0]

    return clock


def test_moving_obstacle_rows_match_the_integrated_motion() -> None:
    """dh/dt and its rate along the obstacle's path (panda_moving: a mocap ball on a linear bouncing path)."""
    sc = integration_scene("panda_moving")
    model = sc.model
    coll, joints = CollisionBarriers.from_scene(sc), JointLimitBarriers.from_scene(sc)
    clock = moving_clock(sc)

    rows = SecondOrderRows(coll, joints, sc.qpos_adr, ALPHA_1, clock)
    rng = np.random.default_rng(7)
    d = mujoco.MjData(model)
    checked = 0
    for _ in range(400):
        d.qpos[sc.qpos_adr] = sc.home + rng.uniform(-0.4, 0.4, sc.n_joints)
        d.qvel[sc.dof_adr] = rng.uniform(-0.8, 0.8, sc.n_joints)
        d.time = float(rng.uniform(0.0, 6.0))
        sc.set_moving_obstacles(d, d.time)
        mujoco.mj_forward(model, d)
        b = coll.evaluate(d, sc.mocap_velocities(d.time)[0])
        moving = [i for i in np.flatnonzero(b.active) if coll._mocap[i] >= 0 and b.h[i] > 0.01]
        if not moving:
            continue
        checked += check_rows(model, d, rows, rng, clock=lambda dd, t: sc.set_moving_obstacles(dd, t),
                              lin_of=lambda t: sc.mocap_velocities(t)[0], tol=5e-3)
        if checked >= 3:
            break
    assert checked >= 3


def test_joint_limit_rows_on_a_shipped_arm() -> None:
    """The joint-limit rows (psi = +-q_dot + alpha_1 h, Lf psi = +-a0 + alpha_1 (+-q_dot)) and the near pairs at home."""
    sc = integration_scene("ur5e_pole")
    model = sc.model
    rows = SecondOrderRows(CollisionBarriers.from_scene(sc), JointLimitBarriers.from_scene(sc), sc.qpos_adr, ALPHA_1)
    rng = np.random.default_rng(3)
    d = mujoco.MjData(model)
    d.qpos[sc.qpos_adr] = sc.home
    d.qvel[sc.dof_adr] = rng.uniform(-1.0, 1.0, sc.n_joints)
    check_rows(model, d, rows, rng)


def test_rows_validate_their_gains() -> None:
    scene = load_scene("panda_pole")
    coll, joints = CollisionBarriers.from_scene(scene), JointLimitBarriers.from_scene(scene)
    with pytest.raises(ConfigError, match="alpha_1"):
        SecondOrderRows(coll, joints, scene.qpos_adr, 0.0)
    with pytest.raises(ConfigError, match="eps"):
        SecondOrderRows(coll, joints, scene.qpos_adr, 1.0, eps=-1.0)


def test_torque_limits_of_the_shipped_arms() -> None:
    assert torque_limits(load_scene("panda_pole")).tolist() == [87.0] * 4 + [12.0] * 3
    assert torque_limits(load_scene("ur5e_pole")).tolist() == [150.0] * 3 + [28.0] * 3


def test_approaching_rows_take_the_obstacles_part_as_approaching() -> None:
    """``approaching=True`` (the torque level's rows): ``phi = J q_dot - |dh/dt|``.

    panda_moving's ball reverses at once at the ends of its bounce. The exact rows' ``psi`` moves by ``2 |dh/dt|``
    when the ball's velocity is reversed; the approaching rows' does not, is never above the exact one, equals it
    (and its ``Lf``) where the ball approaches, and static rows are the same in both.
    """
    sc = integration_scene("panda_moving")
    model = sc.model
    coll, joints = CollisionBarriers.from_scene(sc), JointLimitBarriers.from_scene(sc)
    clock = moving_clock(sc)

    exact = SecondOrderRows(coll, joints, sc.qpos_adr, ALPHA_1, clock)
    worst = SecondOrderRows(coll, joints, sc.qpos_adr, ALPHA_1, clock, approaching=True)
    dyn = ArmDynamics(model, sc.dof_adr)
    rng = np.random.default_rng(11)
    d = mujoco.MjData(model)
    seen = {"approaching": 0, "receding": 0}
    for _ in range(400):
        d.qpos[sc.qpos_adr] = sc.home + rng.uniform(-0.4, 0.4, sc.n_joints)
        d.qvel[sc.dof_adr] = rng.uniform(-0.8, 0.8, sc.n_joints)
        d.time = float(rng.uniform(0.0, 6.0))
        lin = clock(d, d.time)
        mujoco.mj_forward(model, d)
        terms = dyn.terms(d)
        pe, tick = exact.tick(d, d.time, terms, lin)
        pw, _ = worst.tick(d, d.time, terms, lin)
        pe_rev, _ = exact.tick(d, d.time, terms, -lin)
        pw_rev, _ = worst.tick(d, d.time, terms, -lin)
        x = tick[0].lf  # the rows' dh/dt (the ball's part of h_dot; 0 for the static rows and the joint limits)
        np.testing.assert_allclose(pw.h, pe.h - (x + np.abs(x)), atol=1e-12)
        assert np.all(pw.h <= pe.h + 1e-12)
        np.testing.assert_allclose(pw_rev.h, pw.h, atol=1e-12)  # (the reversal leaves them as they are)
        np.testing.assert_allclose(pe_rev.h - pe.h, -2.0 * x, atol=1e-12)
        static = x == 0.0
        np.testing.assert_array_equal(pw.h[static], pe.h[static])
        came = x < -1e-3
        np.testing.assert_allclose(pw.lf[came], pe.lf[came], rtol=1e-6, atol=1e-6)
        seen["approaching"] += int(came.sum())
        seen["receding"] += int((x > 1e-3).sum())
        if min(seen.values()) >= 2:
            break
    assert min(seen.values()) >= 2
