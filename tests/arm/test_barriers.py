"""Collision and joint-limit barriers: values, gradients, dh/dt, pair filtering, clearance."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from isf_robot.arm import (
    BarrierBatch,
    CollisionBarriers,
    JointLimitBarriers,
    collision_pairs,
    kernels,
    load_scene,
    min_distance,
    stack_batches,
)
from isf_robot.core import ConfigError, IsfWarning, LieData
from isf_robot.core.exceptions import ShapeError

GEOM = mujoco.mjtObj.mjOBJ_GEOM

# Two-joint arm whose second link carries a geom of type {t}; a fixed obstacle of type {ot}.
PAIR_XML = """
<mujoco>
  <option ccd_tolerance="1e-10"/>
  <asset>
    <mesh name="boxmesh" vertex="-.1 -.08 -.06  .1 -.08 -.06  -.1 .08 -.06  .1 .08 -.06
                                 -.1 -.08  .06  .1 -.08  .06  -.1 .08  .06  .1 .08  .06"/>
  </asset>
  <worldbody>
    <body name="l1">
      <joint name="j1" axis="0 0 1"/>
      <geom name="a1" type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
      <body name="l2" pos="0.4 0 0">
        <joint name="j2" axis="0 1 0"/>
        <geom name="r" type="{t}" size="{s}" pos="0.15 0 0"/>
      </body>
    </body>
    <geom name="o" type="{ot}" {os} pos="0.5 0.05 0.02" euler="0.3 0.2 0.1"/>
  </worldbody>
</mujoco>
"""
ROBOT_TYPES = [("sphere", "0.05"), ("capsule", "0.04 0.1")]
OBSTACLE_TYPES = [("sphere", 'size="0.08"'), ("capsule", 'size="0.05 0.12"'),
                  ("mesh", 'mesh="boxmesh"'), ("box", 'size="0.1 0.08 0.06"')]


def pair_model(t: str, s: str, ot: str, os: str) -> tuple[mujoco.MjModel, CollisionBarriers]:
    m = mujoco.MjModel.from_xml_string(PAIR_XML.format(t=t, s=s, ot=ot, os=os))
    r, o = m.geom("r").id, m.geom("o").id
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IsfWarning)
        cb = CollisionBarriers(m, collision_pairs(m, [r], [o], margin=0.01), [0, 1], cutoff=0.5)
    return m, cb


# ----------------------------------------------------------------------------- gradients


@pytest.mark.parametrize(("t", "s"), ROBOT_TYPES)
@pytest.mark.parametrize(("ot", "os"), OBSTACLE_TYPES)
def test_pair_gradient_matches_finite_differences(t, s, ot, os, rng, fd_grad) -> None:  # type: ignore[no-untyped-def]
    m, cb = pair_model(t, s, ot, os)
    d = mujoco.MjData(m)
    seen = {"apart": 0, "overlap": 0}
    for _ in range(150):
        d.qpos[:] = rng.uniform(-0.6, 0.6, 2)
        mujoco.mj_forward(m, d)
        b = cb.evaluate(d)
        dist = b.h[0] + 0.01
        if dist > 0.05:
            continue
        if dist < 0 and t == "capsule" and ot == "box":
            continue  # MuJoCo's capsule-box collider: not a signed distance when overlapping
        seen["overlap" if dist < 0 else "apart"] += 1
        fd = fd_grad(m, d, lambda dd: cb.evaluate(dd).h, np.arange(2), eps=1e-5)
        np.testing.assert_allclose(b.grad, fd, atol=2e-4, rtol=1e-3)
    assert seen["apart"] >= 5
    if not (t == "capsule" and ot == "box"):
        assert seen["overlap"] >= 5


def test_overlap_gradient_points_out_of_the_obstacle() -> None:
    """Sphere deep inside a sphere: moving along +dh/dq must separate them."""
    m, cb = pair_model("sphere", "0.05", "sphere", 'size="0.08"')
    d = mujoco.MjData(m)
    d.qpos[:] = [0.1, 0.0]
    mujoco.mj_forward(m, d)
    b = cb.evaluate(d)
    dist0 = mujoco.mj_geomDistance(m, d, m.geom("r").id, m.geom("o").id, 1.0, None)
    assert dist0 < -0.05  # well inside
    assert b.h[0] == pytest.approx(dist0 - 0.01)
    d.qpos[:] += 1e-3 * b.grad[0] / np.linalg.norm(b.grad[0])
    mujoco.mj_forward(m, d)
    assert cb.evaluate(d).h[0] > b.h[0]


@pytest.mark.parametrize("name", ["planar", "planar_moving", "panda_pole", "panda_shelf",
                                  "panda_moving"])
def test_scene_gradients_match_finite_differences(name, rng, fd_grad) -> None:  # type: ignore[no-untyped-def]
    sc = load_scene(name)
    m, cb = sc.model, CollisionBarriers.from_scene(sc)
    d = sc.make_data(t=0.7)
    overlaps = 0
    for _ in range(60):
        d.qpos[sc.qpos_adr] = rng.uniform(sc.joint_range[:, 0], sc.joint_range[:, 1])
        mujoco.mj_forward(m, d)
        b = cb.evaluate(d)
        overlaps += int(np.any(b.h < -sc.config.barrier.margin))
        fd = fd_grad(m, d, lambda dd: cb.evaluate(dd).h, sc.dof_adr)
        np.testing.assert_allclose(b.grad, fd, atol=1e-6)
    assert overlaps >= 1, "random configurations should include overlapping geoms"


@pytest.mark.parametrize(
    ("name", "pair"),
    [("planar", "hand_geom|pole_a"), ("panda_pole", "fingers_geom|pole"),
     ("panda_shelf", "fingers_geom|shelf_top"), ("panda_moving", "fingers_geom|ball_geom")],
)
def test_arm_placed_inside_an_obstacle(name, pair, rng, fd_grad) -> None:  # type: ignore[no-untyped-def]
    """Drive the ee site to the obstacle's centre: deep penetration, gradient still exact.

    The start is perturbed off the symmetric home pose: at symmetric poses (capsule axes
    crossing, a capsule parallel to a face) the distance has a kink and finite differences
    average the two one-sided slopes.
    """
    sc = load_scene(name)
    m, cb = sc.model, CollisionBarriers.from_scene(sc)
    d = sc.make_data()
    d.qpos[sc.qpos_adr] += rng.normal(0.0, 0.1, sc.n_joints)
    obstacle = m.geom(pair.split("|")[1]).id
    target = d.geom_xpos[obstacle].copy()
    jac = np.zeros((3, m.nv))
    for _ in range(100):  # Newton steps on the site position
        mujoco.mj_forward(m, d)
        err = target - d.site_xpos[sc.ee_site_id]
        mujoco.mj_jacSite(m, d, jac, None, sc.ee_site_id)
        step = np.linalg.lstsq(jac[:, sc.dof_adr], err, rcond=None)[0]
        q = d.qpos[sc.qpos_adr] + np.clip(step, -0.2, 0.2)
        d.qpos[sc.qpos_adr] = np.clip(q, sc.joint_range[:, 0], sc.joint_range[:, 1])
    mujoco.mj_forward(m, d)
    b = cb.evaluate(d)
    i = b.names.index(pair)
    assert b.h[i] < -0.03
    fd = fd_grad(m, d, lambda dd: cb.evaluate(dd).h[i : i + 1], sc.dof_adr)
    np.testing.assert_allclose(b.grad[i : i + 1], fd, atol=1e-6)


def test_self_collision_pair_gradient(rng, fd_grad) -> None:  # type: ignore[no-untyped-def]
    xml = """
    <mujoco><compiler angle="radian"/><worldbody>
      <body name="a"><joint name="q1" axis="0 0 1"/>
        <geom name="ga" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <body name="b" pos="0.3 0 0"><joint name="q2" axis="0 0 1"/>
          <geom name="gb" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
          <body name="c" pos="0.3 0 0"><joint name="q3" axis="0 0 1"/>
            <geom name="gc" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
          </body></body></body>
    </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    g = [m.geom(n).id for n in ("ga", "gb", "gc")]
    pairs = collision_pairs(m, g, [], margin=0.0, self_collision=True, self_margin=0.01)
    assert pairs.names == ("ga|gc",)  # ga|gb and gb|gc are parent-child
    assert {n for n, _ in pairs.excluded} == {"ga|gb", "gb|gc"}
    cb = CollisionBarriers(m, pairs, [0, 1, 2], cutoff=1.0)
    d = mujoco.MjData(m)
    for _ in range(20):
        d.qpos[:] = [rng.uniform(-1, 1), rng.uniform(2.0, 2.6), rng.uniform(1.5, 2.6)]
        mujoco.mj_forward(m, d)
        b = cb.evaluate(d)
        fd = fd_grad(m, d, lambda dd: cb.evaluate(dd).h, np.arange(3))
        np.testing.assert_allclose(b.grad, fd, atol=1e-6)
        assert b.grad[0, 0] == pytest.approx(0.0, abs=1e-9)  # q1 moves both links rigidly


def test_panda_self_collision_pairs(rng, fd_grad) -> None:  # type: ignore[no-untyped-def]
    sc = load_scene("panda_pole")
    m = sc.model
    pairs = collision_pairs(m, sc.robot_geom_ids, [], margin=0.0, self_collision=True,
                            self_margin=0.01)
    assert pairs.k > 30 and pairs.is_self.all()
    reasons = {why for _, why in pairs.excluded}
    assert reasons == {"same body", "parent-child"}
    cb = CollisionBarriers(m, pairs, sc.dof_adr, cutoff=0.2)
    d = sc.make_data()
    assert np.all(cb.evaluate(d).h > 0.0), "home pose is free of self-collision"
    for _ in range(15):
        d.qpos[sc.qpos_adr] = rng.uniform(sc.joint_range[:, 0], sc.joint_range[:, 1])
        mujoco.mj_forward(m, d)
        b = cb.evaluate(d)
        fd = fd_grad(m, d, lambda dd: cb.evaluate(dd).h, sc.dof_adr)
        np.testing.assert_allclose(b.grad, fd, atol=1e-6)


# ----------------------------------------------------------------------------- values, cut-off


def test_values_match_brute_force_and_saturate_at_cutoff(planar, rng) -> None:  # type: ignore[no-untyped-def]
    m, cb = planar.model, CollisionBarriers.from_scene(planar)
    d = planar.make_data()
    cutoff, margin = cb.cutoff, planar.config.barrier.margin
    n_inactive = 0
    for _ in range(30):
        d.qpos[planar.qpos_adr] = rng.uniform(planar.joint_range[:, 0], planar.joint_range[:, 1])
        mujoco.mj_forward(m, d)
        b = cb.evaluate(d)
        for i in range(b.k):
            g1, g2 = b.pair_geoms[i]
            true = mujoco.mj_geomDistance(m, d, int(g1), int(g2), 10.0, None)
            assert b.h[i] == pytest.approx(min(true, cutoff) - margin, abs=1e-9)
            assert b.active[i] == (true < cutoff)
            if not b.active[i]:
                n_inactive += 1
                assert not b.grad[i].any() and b.dhdt[i] == 0.0
                assert np.isnan(b.witness[i]).all()
            else:
                np.testing.assert_allclose(np.linalg.norm(b.witness[i, 0] - b.witness[i, 1]),
                                           abs(true), atol=1e-9)
    assert n_inactive > 0


def test_results_are_not_overwritten_by_the_next_call(planar) -> None:  # type: ignore[no-untyped-def]
    m, cb = planar.model, CollisionBarriers.from_scene(planar)
    d = planar.make_data()
    first = cb.evaluate(d)
    h, grad, w = first.h.copy(), first.grad.copy(), first.witness.copy()
    d.qpos[planar.qpos_adr] += 0.3
    mujoco.mj_forward(m, d)
    second = cb.evaluate(d)
    assert not np.allclose(second.h, h)
    np.testing.assert_array_equal(first.h, h)
    np.testing.assert_array_equal(first.grad, grad)
    np.testing.assert_array_equal(first.witness, w)


def test_min_distance_matches_brute_force(planar, rng) -> None:  # type: ignore[no-untyped-def]
    m, cb = planar.model, CollisionBarriers.from_scene(planar)
    d = planar.make_data()
    for _ in range(30):
        d.qpos[planar.qpos_adr] = rng.uniform(planar.joint_range[:, 0], planar.joint_range[:, 1])
        mujoco.mj_kinematics(m, d)
        c = min_distance(m, d, cb.pairs)
        brute = [mujoco.mj_geomDistance(m, d, int(a), int(b), 10.0, None)
                 for a, b in zip(cb.pairs.geom1, cb.pairs.geom2)]
        assert c.distance == pytest.approx(min(brute), abs=1e-12)
        assert c.name == cb.pairs.names[int(np.argmin(brute))]


# ----------------------------------------------------------------------------- dh/dt


def test_dhdt_matches_time_finite_difference(planar_moving, rng) -> None:  # type: ignore[no-untyped-def]
    sc = planar_moving
    m, cb = sc.model, CollisionBarriers.from_scene(sc)
    d = sc.make_data()
    checked = 0
    for _ in range(60):
        q = rng.uniform(sc.joint_range[:, 0], sc.joint_range[:, 1])
        t = float(rng.uniform(0.0, 6.0))

        def h_at(tt: float) -> np.ndarray:
            d.qpos[sc.qpos_adr] = q
            sc.set_moving_obstacles(d, tt)
            mujoco.mj_forward(m, d)
            return cb.evaluate(d).h

        eps = 1e-6
        fd = (h_at(t + eps) - h_at(t - eps)) / (2 * eps)
        h_at(t)
        b = cb.evaluate(d, *sc.mocap_velocities(t))
        np.testing.assert_allclose(b.dhdt, fd, atol=1e-6)
        checked += int(np.any(b.active & (np.abs(b.dhdt) > 1e-3)))
    assert checked >= 5
    assert not cb.evaluate(d).dhdt.any()  # no velocities given: dh/dt = 0


def test_mocap_velocity_shape_is_checked(planar_moving) -> None:  # type: ignore[no-untyped-def]
    sc = planar_moving
    d = sc.make_data()
    d.qpos[sc.qpos_adr] = [0.0, 0.0, 0.0]  # stretched along x, through the ball's circle
    sc.set_moving_obstacles(d, 0.0)
    mujoco.mj_forward(sc.model, d)
    cb = CollisionBarriers.from_scene(sc)
    lin, _ = sc.mocap_velocities(0.0)
    assert cb.evaluate(d, lin).active.any()
    with pytest.raises(ShapeError, match="mocap velocities"):
        cb.evaluate(d, lin[0])


def test_dhdt_with_rotating_mocap_obstacle(rng) -> None:  # type: ignore[no-untyped-def]
    xml = """
    <mujoco><compiler angle="radian"/><option ccd_tolerance="1e-10"/>
      <asset><mesh name="slab" vertex="-.2 -.05 -.1 .2 -.05 -.1 -.2 .05 -.1 .2 .05 -.1
                                       -.2 -.05 .1 .2 -.05 .1 -.2 .05 .1 .2 .05 .1"/></asset>
      <worldbody>
        <body name="link"><joint name="j" axis="0 0 1"/>
          <geom name="arm" type="capsule" fromto="0 0 0 0.5 0 0" size="0.03"/></body>
        <body name="rot" mocap="true" pos="0.35 0.2 0.0">
          <geom name="slab_geom" type="mesh" mesh="slab" pos="0.05 0.0 0.0"/></body>
      </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    cb = CollisionBarriers(m, collision_pairs(m, [m.geom("arm").id], [m.geom("slab_geom").id],
                                              margin=0.0), [0], cutoff=1.0)
    d = mujoco.MjData(m)
    lin = np.array([[0.1, -0.2, 0.05]])
    ang = np.array([[0.3, -0.2, 1.5]])
    for _ in range(10):
        d.qpos[0] = rng.uniform(-0.3, 0.3)
        p0 = d.mocap_pos[0].copy()
        q0 = np.array([1.0, 0.0, 0.0, 0.0])

        def h_at(tt: float) -> float:
            d.mocap_pos[0] = p0 + lin[0] * tt
            quat = q0.copy()
            mujoco.mju_quatIntegrate(quat, ang[0], tt)
            d.mocap_quat[0] = quat
            mujoco.mj_forward(m, d)
            return float(cb.evaluate(d).h[0])

        eps = 1e-6
        fd = (h_at(eps) - h_at(-eps)) / (2 * eps)
        h_at(0.0)
        b = cb.evaluate(d, lin, ang)
        assert b.active[0]
        assert b.dhdt[0] == pytest.approx(fd, abs=1e-6)
        d.mocap_pos[0] = p0


# ----------------------------------------------------------------------------- pair filtering


FILTER_XML = """
<mujoco><worldbody>
  <geom name="world_box" type="box" size="0.1 0.1 0.1" pos="2 0 0"/>
  <geom name="ghost" type="sphere" size="0.1" pos="0 2 0" contype="0" conaffinity="0"/>
  <body name="base">
    <geom name="base_geom" type="cylinder" size="0.1 0.1"/>
    <body name="l1"><joint name="j1" axis="0 0 1"/>
      <geom name="l1a" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      <geom name="l1b" type="sphere" size="0.05" pos="0.3 0 0"/>
      <body name="l2" pos="0.3 0 0"><joint name="j2" axis="0 0 1"/>
        <geom name="l2a" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <body name="hand" pos="0.3 0 0">
          <geom name="hand_geom" type="sphere" size="0.04"/>
          <body name="l3"><joint name="j3" axis="0 1 0"/>
            <geom name="l3a" type="sphere" size="0.02" pos="0.1 0 0"/>
            <body name="l4" pos="0.2 0 0"><joint name="j4" axis="0 1 0"/>
              <geom name="l4a" type="sphere" size="0.02" pos="0.1 0 0"/></body></body>
        </body></body></body></body>
</worldbody>
<contact><exclude body1="l1" body2="l3"/></contact>
</mujoco>
"""


def test_pair_filtering_reasons() -> None:
    m = mujoco.MjModel.from_xml_string(FILTER_XML)
    gid = {m.geom(i).name: i for i in range(m.ngeom)}
    robot = [gid[n] for n in ("l1a", "l1b", "l2a", "hand_geom", "l3a", "l4a")]
    obst = [gid[n] for n in ("world_box", "ghost", "base_geom")]
    pairs = collision_pairs(m, robot, obst, margin=0.01, self_collision=True, self_margin=0.0)
    why = dict(pairs.excluded)
    assert why["l1a|l1b"] == "same body"
    assert why["l1a|l2a"] == "parent-child"
    assert why["l2a|hand_geom"] == "same body"  # hand is welded to l2
    assert why["hand_geom|l3a"] == "parent-child"
    assert why["l2a|l3a"] == "parent-child"  # l3's parent is welded to l2
    assert why["l1a|ghost"] == "contype/conaffinity"
    assert why["l1a|l3a"] == "excluded in MJCF"
    assert "l1a|world_box" in pairs.names  # the world is never a "parent"
    assert "l1a|base_geom" in pairs.names  # base is welded to the world
    assert why["l1b|hand_geom"] == "parent-child"  # hand is welded to l2, l1's child
    assert "l2a|l4a" in pairs.names  # non-adjacent self pair
    assert pairs.is_self[pairs.names.index("l2a|l4a")]
    assert pairs.margin[pairs.names.index("l2a|l4a")] == 0.0
    assert pairs.margin[pairs.names.index("l1a|world_box")] == 0.01
    no_self = collision_pairs(m, robot, obst, margin=0.01)
    assert not no_self.is_self.any()


def test_scene_pairs_exclude_nothing_needed(planar) -> None:  # type: ignore[no-untyped-def]
    cb = CollisionBarriers.from_scene(planar)
    assert cb.pairs.k == len(planar.robot_geom_ids) * len(planar.obstacle_geom_ids)


def test_capsule_box_pairs_warn() -> None:
    m = mujoco.MjModel.from_xml_string(PAIR_XML.format(t="capsule", s="0.04 0.1", ot="box",
                                                       os='size="0.1 0.08 0.06"'))
    with pytest.warns(IsfWarning, match="capsule-box"):
        CollisionBarriers(m, collision_pairs(m, [m.geom("r").id], [m.geom("o").id], margin=0.0),
                          [0, 1], cutoff=0.3)


def test_no_pairs_left_is_an_error() -> None:
    m = mujoco.MjModel.from_xml_string(FILTER_XML)
    pairs = collision_pairs(m, [m.geom("l1a").id], [m.geom("ghost").id], margin=0.0)
    with pytest.raises(ConfigError, match="contype"):
        CollisionBarriers(m, pairs, [0, 1, 2, 3], cutoff=0.3)


# ----------------------------------------------------------------------------- joint limits


def test_joint_limit_barriers(planar, rng, fd_grad) -> None:  # type: ignore[no-untyped-def]
    jl = JointLimitBarriers.from_scene(planar)
    m, d = planar.model, planar.make_data()
    jm = planar.config.barrier.joint_margin
    assert jl.names[:2] == ("j1:min", "j1:max")
    for _ in range(10):
        q = rng.uniform(planar.joint_range[:, 0] - 0.1, planar.joint_range[:, 1] + 0.1)
        d.qpos[planar.qpos_adr] = q
        b = jl.evaluate(d)
        lo, hi = planar.joint_range[:, 0], planar.joint_range[:, 1]
        expect = np.stack([q - lo - jm, hi - jm - q], axis=1).ravel()
        np.testing.assert_allclose(b.h, expect)
        mujoco.mj_forward(m, d)
        np.testing.assert_allclose(b.grad, fd_grad(m, d, lambda dd: jl.evaluate(dd).h,
                                                   planar.dof_adr), atol=1e-8)
        assert not b.dhdt.any()


def test_joint_limit_barriers_skip_unlimited_and_validate() -> None:
    jl = JointLimitBarriers([0, 1], np.array([[-1.0, 1.0], [-np.inf, np.inf]]), 0.1, ["a", "b"])
    assert jl.names == ("a:min", "a:max")
    with pytest.raises(ShapeError):
        JointLimitBarriers([0, 1], np.zeros((3, 2)), 0.1, ["a", "b"])
    with pytest.raises(ConfigError, match="no room"):
        JointLimitBarriers([0], np.array([[-0.1, 0.1]]), 0.1, ["a"])


# ----------------------------------------------------------------------------- batches


def test_stack_and_lie_data(planar) -> None:  # type: ignore[no-untyped-def]
    d = planar.make_data()
    cb = CollisionBarriers.from_scene(planar).evaluate(d)
    jl = JointLimitBarriers.from_scene(planar).evaluate(d)
    both = stack_batches(cb, jl)
    assert isinstance(both, BarrierBatch)
    assert both.k == cb.k + jl.k and both.names == cb.names + jl.names
    lie = both.to_lie_data()
    assert isinstance(lie, LieData)
    lie.validate()
    np.testing.assert_array_equal(lie.lg, both.grad)
    np.testing.assert_array_equal(lie.lf, both.dhdt)
    np.testing.assert_allclose(lie.grad_norm, np.linalg.norm(both.grad, axis=1))
    with pytest.raises(ConfigError):
        stack_batches()


_NO_KERNELS = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off or numba not importable")


@pytest.mark.parametrize("jit", [pytest.param(True, marks=_NO_KERNELS), False])
def test_rows_follow_h_along_random_directions(random_states, rng, jit) -> None:  # type: ignore[no-untyped-def]
    """``dh/dq . w`` equals the central difference of ``h`` along a random joint direction ``w`` (both paths)."""
    scene = load_scene("panda_shelf")
    coll = CollisionBarriers(scene.model, CollisionBarriers.from_scene(scene).pairs, scene.dof_adr,
                             CollisionBarriers.from_scene(scene).cutoff, jit=jit)
    assert (coll._kernel is not None) == jit
    m, eps, checked = scene.model, 1e-6, 0
    for d in random_states(scene, rng, 30):
        near = coll.near(d)
        if not near.row_list:
            continue
        w = rng.normal(size=scene.n_joints)
        w /= np.linalg.norm(w)
        q0 = d.qpos[scene.qpos_adr].copy()
        hs = []
        for s in (eps, -eps):
            e = mujoco.MjData(m)
            e.qpos[:] = d.qpos
            e.qpos[scene.qpos_adr] = q0 + s * w
            mujoco.mj_forward(m, e)
            dist = [mujoco.mj_geomDistance(m, e, int(coll.pairs.geom1[i]), int(coll.pairs.geom2[i]), 10.0, None)
                    for i in near.row_list]
            hs.append(np.array(dist) - coll.pairs.margin[near.rows])
        fd = (hs[0] - hs[1]) / (2 * eps)
        np.testing.assert_allclose(near.grad @ w, fd, rtol=1e-4, atol=1e-6)
        checked += len(near.row_list)
    assert checked > 20
