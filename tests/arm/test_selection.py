"""Configs that fit how models are written: geoms by body/subtree/group, unnamed geoms as
body[index], keyframe homes, an end effector on a body, joints from the actuators."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, load_scene_from_files
from isf_robot.arm.selection import geom_label, subtree_bodies
from isf_robot.core import ConfigError, UnknownNameError

# Menagerie style: visual geoms (group 2, no contact) and unnamed collision geoms (group 3);
# the actuators are listed in a different order than the bodies.
ARM = """
<mujoco model="mini">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002"/>
  <default>
    <joint axis="0 0 1" range="-2.5 2.5" damping="1" armature="0.05"/>
    <position kp="200" kv="10" forcerange="-30 30"/>
    <default class="visual"><geom type="sphere" size="0.02" contype="0" conaffinity="0" group="2"/></default>
    <default class="collision"><geom type="capsule" group="3"/></default>
  </default>
  <worldbody>
    <body name="base">
      <geom class="visual"/>
      <geom class="collision" fromto="0 0 0 0 0 0.05" size="0.05"/>
      <body name="upper" pos="0 0 0.2">
        <joint name="shoulder"/>
        <geom class="visual"/>
        <geom class="collision" fromto="0 0 0 0.4 0 0" size="0.03"/>
        <body name="lower" pos="0.4 0 0">
          <joint name="elbow"/>
          <geom class="visual"/>
          <geom class="collision" fromto="0 0 0 0.3 0 0" size="0.025"/>
          <geom name="tip_ball" class="collision" type="sphere" pos="0.3 0 0" size="0.03" group="4"/>
        </body>
      </body>
    </body>
    <body name="props">
      <geom name="post" type="capsule" fromto="0.45 0.45 0 0.45 0.45 0.4" size="0.04" group="1"/>
      <geom type="sphere" pos="-0.5 0.3 0.2" size="0.05" group="1"/>
    </body>
  </worldbody>
  <actuator>
    <position name="a_elbow" joint="elbow"/>
    <position name="a_shoulder" joint="shoulder"/>
  </actuator>
  <keyframe>
    <key name="home" qpos="0.3 0.6"/>
    <key name="folded" qpos="0.1 2.0"/>
  </keyframe>
</mujoco>
"""

CFG = """
[scene]
name = "mini"
[robot]
subtree = "base"
geom_group = 3
home = "home"
ee_body = "lower"
ee_offset = [0.3, 0.0, 0.0]
[obstacles]
bodies = ["props"]
[task]
goals = [{pos = [0.2, 0.5, 0.2]}]
"""


def load(tmp_path: Path, cfg: str = CFG, arm: str = ARM):  # type: ignore[no-untyped-def]
    (tmp_path / "mini.xml").write_text(arm)
    (tmp_path / "mini.toml").write_text(cfg)
    return load_scene_from_files(tmp_path / "mini.xml", tmp_path / "mini.toml")


def test_menagerie_style_selection(tmp_path) -> None:  # type: ignore[no-untyped-def]
    sc = load(tmp_path)
    m = sc.model
    labels = [geom_label(m, g) for g in sc.robot_geom_ids]
    assert labels == ["base[1]", "upper[1]", "lower[1]"]  # group 3 only: no visuals, no tip_ball
    assert [geom_label(m, g) for g in sc.obstacle_geom_ids] == ["post", "props[1]"]
    # joints from the actuators, in actuator order; home from the keyframe
    assert sc.joint_names == ("elbow", "shoulder")
    np.testing.assert_array_equal(sc.home, [0.6, 0.3])
    np.testing.assert_array_equal(sc.make_data().qpos, [0.3, 0.6])
    # pair names use the labels
    assert "upper[1]|props[1]" in CollisionBarriers.from_scene(sc).names


def test_selection_by_bodies_labels_and_group_alone(tmp_path) -> None:  # type: ignore[no-untyped-def]
    cfg = CFG.replace('subtree = "base"\ngeom_group = 3', 'bodies = ["upper"]\ngeoms = ["lower[1]", "tip_ball"]')
    cfg = cfg.replace('bodies = ["props"]', "geom_group = 1")
    sc = load(tmp_path, cfg)
    assert [geom_label(sc.model, g) for g in sc.robot_geom_ids] == ["lower[1]", "tip_ball", "upper[1]"]
    assert [geom_label(sc.model, g) for g in sc.obstacle_geom_ids] == ["post", "props[1]"]
    assert subtree_bodies(sc.model, sc.model.body("upper").id) == [2, 3]


def test_ee_body_point_and_jacobian(tmp_path) -> None:  # type: ignore[no-untyped-def]
    sc = load(tmp_path)
    m, d = sc.model, sc.make_data()
    assert sc.ee_site_id == -1
    q1, q2 = 0.3, 0.6  # shoulder, elbow: planar two-link, lengths 0.4 and 0.3
    expect = [0.4 * np.cos(q1) + 0.3 * np.cos(q1 + q2), 0.4 * np.sin(q1) + 0.3 * np.sin(q1 + q2), 0.2]
    np.testing.assert_allclose(sc.ee_position(d), expect, atol=1e-12)
    jac = np.zeros((3, m.nv))
    sc.ee_jacobian(d, jac)
    eps = 1e-6
    for dof in range(m.nv):
        cols = []
        for s in (1, -1):
            d2 = sc.make_data()
            d2.qpos[dof] += s * eps
            mujoco.mj_kinematics(m, d2)
            cols.append(sc.ee_position(d2).copy())
        np.testing.assert_allclose(jac[:, dof], (cols[0] - cols[1]) / (2 * eps), atol=1e-8)


@pytest.mark.parametrize("change, error, words", [
    (('ee_body = "lower"', 'ee_site = "nowhere"\nee_body = "lower"'), ConfigError, "exactly one of 'ee_site' or 'ee_body'"),
    (('ee_body = "lower"\nee_offset = [0.3, 0.0, 0.0]', 'ee_site = "s"\nee_offset = [0.3, 0.0, 0.0]'), ConfigError,
     "ee_offset needs ee_body"),
    (('home = "home"', 'home = "ready"'), UnknownNameError, "valid keyframe names: folded, home"),
    (('home = "home"', "home = [0.1, 0.2, 0.3]"), ConfigError, "3 numbers for 2 joints"),
    (('geom_group = 3', 'geom_group = 5'), ConfigError, "colliding geoms there are in groups \\[3, 4\\]"),
    (('geom_group = 3', 'geom_group = 9'), ConfigError, "0..5"),
    (('subtree = "base"', 'subtree = "bse"'), UnknownNameError, "valid body names: base, lower, props, upper"),
    (('subtree = "base"', 'geoms = ["lower[7]"]'), UnknownNameError, "base\\[1\\], lower\\[1\\]"),
    (('bodies = ["props"]', 'geoms = ["upper[1]"]'), ConfigError, "\\['upper\\[1\\]'\\] are listed as robot and as obstacle"),
    (('bodies = ["props"]', 'bodies = ["upper"]'), ConfigError, "\\['upper\\[1\\]'\\] there are already robot geoms"),
    (('bodies = ["props"]', 'bodies = ["lower"]\ngeom_group = 4'), ConfigError, "'tip_ball' must be on the world"),
    (('subtree = "base"\ngeom_group = 3\n', ''), ConfigError, "give the robot's geoms"),
])
def test_bad_selections_say_what_is_valid(tmp_path, change, error, words) -> None:  # type: ignore[no-untyped-def]
    old, new = change
    assert old in CFG
    with pytest.raises(error, match=words):
        load(tmp_path, CFG.replace(old, new))


def test_explicit_joints_and_numeric_home_still_work(tmp_path) -> None:  # type: ignore[no-untyped-def]
    cfg = CFG.replace('home = "home"', 'joints = ["shoulder", "elbow"]\nhome = [0.2, -0.4]')
    sc = load(tmp_path, cfg)
    assert sc.joint_names == ("shoulder", "elbow")
    np.testing.assert_array_equal(sc.home, [0.2, -0.4])
    assert list(sc.actuator_ids) == [1, 0]
