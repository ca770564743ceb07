"""Broad phase of the collision barriers: exact candidate sets, sound reach bounds, far obstacles."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, Scene, collision_pairs, list_scenes, load_scene, load_scene_from_files
from isf_robot.arm.broadphase import BroadPhase, reach_bounds
from isf_robot.paths import models_dir

SCENES = [s.name for s in list_scenes()]


def brute_force_candidates(model: mujoco.MjModel, data: mujoco.MjData, g1: np.ndarray, g2: np.ndarray,
                           cutoff: float) -> list[int]:
    """The definition, pair by pair: |c1 - c2| < cutoff + r1 + r2, or a geom is unbounded."""
    out = []
    for i, (a, b) in enumerate(zip(g1.tolist(), g2.tolist())):
        r1, r2 = model.geom_rbound[a], model.geom_rbound[b]
        if r1 == 0 or r2 == 0 or np.linalg.norm(data.geom_xpos[a] - data.geom_xpos[b]) < cutoff + r1 + r2:
            out.append(i)
    return out


def random_qpos(scene: Scene, rng: np.random.Generator, data: mujoco.MjData, wild: bool) -> None:
    """Arm joints inside their range, or (``wild``) anywhere in [-2 pi, 2 pi] beyond it."""
    if wild:
        data.qpos[scene.qpos_adr] = rng.uniform(-2 * math.pi, 2 * math.pi, scene.n_joints)
    else:
        lo = np.where(np.isfinite(scene.joint_range[:, 0]), scene.joint_range[:, 0], -math.pi)
        hi = np.where(np.isfinite(scene.joint_range[:, 1]), scene.joint_range[:, 1], math.pi)
        data.qpos[scene.qpos_adr] = rng.uniform(lo, hi)


def far_scene(tmp_path: Path, n: int = 24, radius: float = 2.5) -> Scene:
    """panda_pole with ``n`` static spheres ``radius`` [m] from the arm's base, all obstacles."""
    for name in ("panda_pole.xml", "panda_arm.xml"):
        shutil.copy(models_dir() / name, tmp_path / name)
    spheres = "\n".join(
        f'<geom name="far{i}" type="sphere" size="0.05" pos="{radius * math.cos(2 * math.pi * i / n):.6f} '
        f'{radius * math.sin(2 * math.pi * i / n):.6f} {0.2 + 0.1 * (i % 5):.2f}"/>' for i in range(n))
    (tmp_path / "far.xml").write_text(
        f'<mujoco><include file="panda_pole.xml"/><worldbody>{spheres}</worldbody></mujoco>')
    toml = (models_dir() / "panda_pole.toml").read_text().replace('model = "panda_pole.xml"', 'model = "far.xml"')
    names = ", ".join(f'"far{i}"' for i in range(n))
    toml = re.sub(r'geoms = \["pole", "ball"\]', f'geoms = ["pole", "ball", {names}]', toml, count=1)
    (tmp_path / "far.toml").write_text(toml)
    return load_scene_from_files(tmp_path / "far.xml", tmp_path / "far.toml")


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("self_collision", [False, True])
def test_candidates_equal_brute_force(name: str, self_collision: bool, rng: np.random.Generator) -> None:
    sc = load_scene(name)
    m, bc = sc.model, sc.config.barrier
    pairs = collision_pairs(m, sc.robot_geom_ids, sc.obstacle_geom_ids, margin=bc.margin,
                            self_collision=self_collision, self_margin=bc.self_margin)
    bp = BroadPhase(m, pairs.geom1, pairs.geom2, bc.cutoff)
    d = mujoco.MjData(m)
    hits = 0
    for it in range(200):
        random_qpos(sc, rng, d, wild=bool(it % 2))
        if m.nmocap:
            d.mocap_pos[:] = m.body_pos[m.body_mocapid >= 0] + rng.normal(0.0, 0.2, (m.nmocap, 3))
        mujoco.mj_kinematics(m, d)
        want = brute_force_candidates(m, d, pairs.geom1, pairs.geom2, bc.cutoff)
        assert bp.candidates(d) == want
        hits += len(want)
    assert hits > 0


@pytest.mark.parametrize("name", SCENES)
def test_pruned_pairs_never_come_within_the_cutoff(name: str, rng: np.random.Generator) -> None:
    """Pairs left out of the per-step test stay beyond the cut-off (true distance) anywhere."""
    sc = load_scene(name)
    m, bc = sc.model, sc.config.barrier
    pairs = collision_pairs(m, sc.robot_geom_ids, sc.obstacle_geom_ids, margin=bc.margin,
                            self_collision=True, self_margin=bc.self_margin)
    bp = BroadPhase(m, pairs.geom1, pairs.geom2, bc.cutoff)
    pruned = np.setdiff1d(np.arange(pairs.k), bp.live).tolist()
    d = mujoco.MjData(m)
    for _ in range(100):
        random_qpos(sc, rng, d, wild=True)
        mujoco.mj_kinematics(m, d)
        for i in pruned:
            dist = mujoco.mj_geomDistance(m, d, int(pairs.geom1[i]), int(pairs.geom2[i]), 10.0, None)
            assert dist >= bc.cutoff


CHAIN_XML = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1"/>
    <geom name="wall" type="box" size=".1 .1 .1" pos="2 0 0"/>
    <body name="b1" pos="0 0 .1">
      <joint name="h1" axis="0 0 1" pos=".05 0 0"/>
      <geom name="g1" type="capsule" fromto="0 0 0 .3 0 0" size=".03"/>
      <body name="b2" pos=".3 0 0">
        <joint name="h2" axis="0 1 0"/>
        <joint name="h3" axis="1 0 0" pos=".1 0 .02"/>
        <geom name="g2" type="sphere" size=".04" pos=".2 .01 0"/>
        <body name="b3" pos=".25 0 0">
          <joint name="ball" type="ball" pos=".02 0 0"/>
          <geom name="g3" type="box" size=".02 .03 .04" pos=".1 0 0"/>
          <body name="b4" pos=".15 0 0">
            <joint name="s" type="slide" axis="1 0 0" range="0 .1"/>
            <geom name="g4" type="sphere" size=".02"/>
          </body>
        </body>
      </body>
    </body>
    <body name="free" pos="1 1 1"><freejoint/><geom name="gf" type="sphere" size=".05"/></body>
    <body name="moc" mocap="true" pos="-1 0 0"><geom name="gm" type="sphere" size=".05"/></body>
  </worldbody>
</mujoco>
"""


def test_reach_bounds_hold_for_hinge_ball_and_multi_joint_bodies(rng: np.random.Generator) -> None:
    m = mujoco.MjModel.from_xml_string(CHAIN_XML)
    geoms = np.arange(m.ngeom)
    reach, end = reach_bounds(m, geoms)
    name = {g: m.geom(g).name for g in range(m.ngeom)}
    unbounded = {name[g] for g in range(m.ngeom) if math.isinf(reach[g])}
    assert unbounded == {"g4", "gf", "gm"}  # slide joint, free joint, mocap body
    assert reach[m.geom("wall").id] == 0.0 and reach[m.geom("floor").id] == 0.0
    d = mujoco.MjData(m)
    worst = 0.0
    for _ in range(500):
        d.qpos[:] = rng.normal(0.0, 3.0, m.nq)
        mujoco.mj_normalizeQuat(m, d.qpos)
        mujoco.mj_kinematics(m, d)
        for g in np.flatnonzero(np.isfinite(reach)).tolist():
            slack = reach[g] - np.linalg.norm(d.geom_xpos[g] - end[g])
            assert slack >= -1e-12
            worst = max(worst, np.linalg.norm(d.geom_xpos[g] - end[g]) / max(reach[g], 1e-12))
    assert worst > 0.5  # the bounds are not vacuous


def test_unbounded_geoms_keep_their_pairs_live() -> None:
    m = mujoco.MjModel.from_xml_string(CHAIN_XML)
    robot = [m.geom(n).id for n in ("g1", "g2", "g3", "g4")]
    obstacles = [m.geom(n).id for n in ("floor", "wall", "gf", "gm")]
    pairs = collision_pairs(m, robot, obstacles, margin=0.01)
    bp = BroadPhase(m, pairs.geom1, pairs.geom2, 0.2)
    live = {pairs.names[i] for i in bp.live.tolist()}
    dead = set(pairs.names) - live
    # The wall (2 m away, arm reach < 1 m) is pruned for the bounded links only; the floor is
    # unbounded (plane), g4 rides a slide joint, gf and gm move freely.
    assert dead == {"g1|wall", "g2|wall", "g3|wall"}


def test_far_obstacles_leave_the_arms_rows_identical(tmp_path: Path, rng: np.random.Generator) -> None:
    base = load_scene("panda_pole")
    far = far_scene(tmp_path)
    cb0, cb1 = CollisionBarriers.from_scene(base), CollisionBarriers.from_scene(far)
    rows = [cb1.names.index(nm) for nm in cb0.names]
    far_rows = np.setdiff1d(np.arange(cb1.pairs.k), rows)
    assert far_rows.size == 14 * 24
    assert cb1.broadphase.live.size == cb0.broadphase.live.size  # far pairs are never tested
    d0, d1 = mujoco.MjData(base.model), mujoco.MjData(far.model)
    n_active = 0
    for it in range(100):
        random_qpos(base, rng, d0, wild=bool(it % 2))
        d1.qpos[:] = d0.qpos
        mujoco.mj_forward(base.model, d0)
        mujoco.mj_forward(far.model, d1)
        a, b = cb0.evaluate(d0), cb1.evaluate(d1)
        for f in ("h", "grad", "dhdt", "active", "witness"):
            np.testing.assert_array_equal(getattr(b, f)[rows], getattr(a, f))
        np.testing.assert_array_equal(b.h[far_rows], cb1.cutoff - cb1.pairs.margin[far_rows])
        assert not b.active[far_rows].any() and not b.grad[far_rows].any()
        assert np.isnan(b.witness[far_rows]).all()
        n_active += int(a.active.sum())
    assert n_active > 0
