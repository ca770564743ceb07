"""Scenes and configs: loading, name resolution, bad input, obstacle paths."""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from isf_robot.arm import (
    CirclePath,
    CollisionBarriers,
    LinearBouncePath,
    list_scenes,
    load_config,
    load_scene,
    load_scene_from_files,
)
from isf_robot.core import ConfigError, UnknownNameError
from isf_robot.paths import models_dir

ALL_SCENES = [s.name for s in list_scenes()]

TINY_XML = """
<mujoco model="tiny">
  <compiler angle="radian"/>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="wall" type="box" size="0.05 0.3 0.3" pos="0.6 0 0"/>
    <body name="stat" pos="0 1 0"><geom name="stat_geom" type="sphere" size="0.1"/></body>
    <body name="ghost" mocap="true" pos="0 -1 0"><geom name="ghost_geom" type="sphere" size="0.1"/></body>
    <body name="link" pos="0 0 0">
      <joint name="hinge" type="hinge" axis="0 0 1" range="-2 2"/>
      <geom name="arm" type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
      <site name="tip" pos="0.4 0 0"/>
      <body name="free_child" pos="0.4 0 0">
        <joint name="loose" type="ball"/>
        <geom name="loose_geom" type="sphere" size="0.02"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="hinge" ctrlrange="-5 5"/></actuator>
</mujoco>
"""

TINY_TOML = """
[scene]
name = "tiny"
description = "one link"
[robot]
joints = ["hinge"]
ee_site = "tip"
geoms = ["arm"]
home = [0.1]
[obstacles]
geoms = ["wall", "stat_geom", "ghost_geom"]
[task]
goals = [{pos = [0.3, 0.3, 0.0], dwell = 0.2}]
[control]
period = 0.004
[[moving]]
body = "ghost"
type = "linear_bounce"
start = [0.0, -1.0, 0.0]
end = [0.0, -0.5, 0.0]
speed = 0.1
"""


def write(tmp_path: Path, xml: str = TINY_XML, toml: str = TINY_TOML) -> tuple[Path, Path]:
    x, t = tmp_path / "tiny.xml", tmp_path / "tiny.toml"
    x.write_text(xml)
    t.write_text(toml)
    return x, t


# ----------------------------------------------------------------------------- shipped scenes


def test_list_scenes_has_the_shipped_scenes() -> None:
    names = ALL_SCENES
    assert {"planar", "planar_moving"} <= set(names)
    assert names == sorted(names)
    assert all(s.description for s in list_scenes())


@pytest.mark.parametrize("name", ALL_SCENES)
def test_every_scene_loads_and_resolves(name: str) -> None:
    sc = load_scene(name)
    m = sc.model
    n = sc.n_joints
    assert sc.name == name
    assert sc.qpos_adr.shape == sc.dof_adr.shape == (n,)
    assert np.all(sc.actuator_ids >= 0), "every arm joint has an actuator"
    assert np.all(np.isfinite(sc.torque_limit))
    for a, j in zip(sc.actuator_ids, sc.joint_ids):
        assert m.actuator_trnid[a, 0] == j
    assert sc.goal_positions.shape == (len(sc.config.task.goals), 3)
    assert np.all(np.isfinite(sc.goal_positions))
    rc = sc.config.robot
    if rc.ee_site is not None:
        assert m.site(sc.ee_site_id).name == rc.ee_site and sc.ee_body_id == m.site_bodyid[sc.ee_site_id]
    else:
        assert sc.ee_site_id == -1 and m.body(sc.ee_body_id).name == rc.ee_body
    if rc.geoms and not (rc.bodies or rc.subtree):
        assert [m.geom(g).name for g in sc.robot_geom_ids] == list(rc.geoms)
    oc = sc.config.obstacles
    if oc.geoms and not (oc.bodies or oc.subtree or oc.geom_group is not None):
        assert [m.geom(g).name for g in sc.obstacle_geom_ids] == list(oc.geoms)
    assert len(sc.moving_mocap_ids) == len(sc.config.moving)


@pytest.mark.parametrize("name", ALL_SCENES)
def test_home_is_clear_of_obstacles_and_limits(name: str) -> None:
    sc = load_scene(name)
    data = sc.make_data()
    clearance = CollisionBarriers.from_scene(sc).min_distance(data)
    assert clearance.distance > sc.config.barrier.margin, clearance
    lo, hi = sc.joint_range[:, 0], sc.joint_range[:, 1]
    jm = sc.config.barrier.joint_margin
    assert np.all(sc.home > lo + jm) and np.all(sc.home < hi - jm)


@pytest.mark.parametrize("name", ALL_SCENES)
def test_nominal_reaching_would_collide(name: str, nominal_rollout) -> None:  # type: ignore[no-untyped-def]
    sc = load_scene(name)
    if sc.arms:
        pytest.skip("several arms: tests/arm/test_multi_arm.py rolls out every arm's task")
    assert nominal_rollout(sc, sc.config.task.duration) < 0.0


def test_goal_sites_resolve_to_site_positions(planar) -> None:  # type: ignore[no-untyped-def]
    data = planar.make_data()
    for goal, pos in zip(planar.config.task.goals, planar.goal_positions):
        assert goal.site is not None
        np.testing.assert_allclose(pos, data.site(goal.site).xpos)


def test_make_data_places_home_and_mocap(planar_moving) -> None:  # type: ignore[no-untyped-def]
    data = planar_moving.make_data(t=1.3)
    np.testing.assert_allclose(data.qpos[planar_moving.qpos_adr], planar_moving.home)
    path = planar_moving.config.moving[0].path
    body = planar_moving.moving_body_ids[0]
    np.testing.assert_allclose(data.xpos[body], path.position(1.3), atol=1e-12)
    lin, ang = planar_moving.mocap_velocities(1.3)
    np.testing.assert_allclose(lin[planar_moving.moving_mocap_ids[0]], path.velocity(1.3))
    assert not ang.any()


def test_config_fields_parsed(planar) -> None:  # type: ignore[no-untyped-def]
    cfg = planar.config
    assert cfg.robot.joints == ("j1", "j2", "j3")
    assert cfg.control.period == pytest.approx(0.002)
    assert cfg.barrier.margin > 0 and cfg.barrier.cutoff > cfg.barrier.margin
    assert len(cfg.gains.tracking_kp) == 3
    assert cfg.source is not None and cfg.source.name == "planar.toml"


# ----------------------------------------------------------------------------- paths


def _fd_velocity(path, t: float, eps: float = 1e-6) -> np.ndarray:  # type: ignore[no-untyped-def]
    return (path.position(t + eps) - path.position(t - eps)) / (2 * eps)


def test_circle_path_velocity_matches_position() -> None:
    p = CirclePath(center=(0.1, 0.2, 0.3), radius=0.25, period=3.0, normal=(0.0, 0.6, 0.8),
                   phase=0.1)
    for t in np.linspace(0.0, 5.0, 23):
        np.testing.assert_allclose(p.velocity(t), _fd_velocity(p, t), atol=1e-7)
        r = p.position(t) - np.array(p.center)
        assert np.linalg.norm(r) == pytest.approx(0.25)
        assert r @ np.array(p.normal) == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(p.position(0.0), p.position(3.0), atol=1e-12)


def test_linear_bounce_path_velocity_and_bounds() -> None:
    p = LinearBouncePath(start=(0.0, 0.0, 0.0), end=(0.3, 0.4, 0.0), speed=0.5, phase=0.25)
    for t in np.linspace(0.013, 5.0, 41):
        np.testing.assert_allclose(p.velocity(t), _fd_velocity(p, t), atol=1e-7)
        s = np.linalg.norm(p.position(t))
        assert -1e-12 <= s <= 0.5 + 1e-12
    # phase 0.25 of the round trip: halfway out, moving towards `end`
    np.testing.assert_allclose(p.position(0.0), [0.15, 0.2, 0.0])
    assert p.velocity(0.0) @ np.array([0.3, 0.4, 0.0]) > 0


# ----------------------------------------------------------------------------- files and names


def test_load_scene_from_files(tmp_path: Path) -> None:
    sc = load_scene_from_files(*write(tmp_path))
    assert sc.name == "tiny"
    assert sc.n_joints == 1
    assert sc.torque_limit[0] == 5.0
    np.testing.assert_allclose(sc.goal_positions, [[0.3, 0.3, 0.0]])
    data = sc.make_data()
    assert data.qpos[sc.qpos_adr[0]] == pytest.approx(0.1)


def test_load_scene_from_files_with_include(tmp_path: Path) -> None:
    for f in ("planar.xml", "planar_arm.xml", "planar.toml"):
        shutil.copy(models_dir() / f, tmp_path / f)
    sc = load_scene_from_files(tmp_path / "planar.xml", tmp_path / "planar.toml")
    assert sc.n_joints == 3


def test_unknown_scene_lists_valid_names() -> None:
    with pytest.raises(UnknownNameError) as err:
        load_scene("no_such_scene")
    msg = str(err.value)
    assert "no_such_scene" in msg and "planar" in msg and "planar_moving" in msg
    assert isinstance(err.value, KeyError) and isinstance(err.value, ValueError)


def test_malformed_mjcf_names_the_file(tmp_path: Path) -> None:
    x, t = write(tmp_path, xml="<mujoco><worldbody><bodyy/></worldbody></mujoco>")
    with pytest.raises(ConfigError, match="tiny.xml") as err:
        load_scene_from_files(x, t)
    assert "malformed MJCF" in str(err.value)
    assert isinstance(err.value.__cause__, ValueError)


def test_missing_mjcf_file(tmp_path: Path) -> None:
    _, t = write(tmp_path)
    with pytest.raises(ConfigError, match="not found"):
        load_scene_from_files(tmp_path / "absent.xml", t)


def test_malformed_toml_names_the_file(tmp_path: Path) -> None:
    x, t = write(tmp_path, toml="[scene\nname = 1")
    with pytest.raises(ConfigError, match="tiny.toml") as err:
        load_scene_from_files(x, t)
    assert "malformed TOML" in str(err.value)


@pytest.mark.parametrize(
    ("old", "new", "kind", "valid"),
    [
        ('geoms = ["arm"]', 'geoms = ["arm", "armm"]', "geom", "loose_geom"),
        ('joints = ["hinge"]', 'joints = ["hing"]', "joint", "loose"),
        ('ee_site = "tip"', 'ee_site = "top"', "site", "tip"),
        ('body = "ghost"', 'body = "ghosts"', "body", "ghost"),
    ],
)
def test_unknown_names_list_the_valid_ones(tmp_path: Path, old: str, new: str, kind: str,
                                           valid: str) -> None:
    assert old in TINY_TOML
    toml = TINY_TOML.replace(old, new).replace("home = [0.1]", "")
    with pytest.raises(UnknownNameError) as err:
        load_scene_from_files(*write(tmp_path, toml=toml))
    assert err.value.kind == kind
    assert valid in err.value.valid and valid in str(err.value)


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("[robot]", "[robot]\ncolour = 'red'", r"unknown key.*colour.*valid keys"),
        ("speed = 0.1", "speed = -0.1", "must be > 0"),
        ('type = "linear_bounce"', 'type = "zigzag"', "valid types"),
        ('joints = ["hinge"]', 'joints = ["loose"]', "hinge or slide"),
        ('geoms = ["wall", "stat_geom", "ghost_geom"]', 'geoms = ["loose_geom"]', "degrees of freedom"),
        ('body = "ghost"', 'body = "stat"', "not a mocap body"),
        ("period = 0.004", "period = 0.003", "integer multiple"),
        ("home = [0.1]", "home = [3.0]", "outside the joint range"),
        ("home = [0.1]", "home = [0.1, 0.2]", "expected 1 numbers"),
        ('geoms = ["arm"]', 'geoms = ["arm", "wall"]', "robot and as obstacle"),
        ("goals = [{pos = [0.3, 0.3, 0.0], dwell = 0.2}]", "goals = []", "non-empty"),
        ("dwell = 0.2", "dwell = 0.2, site = 'tip'", "exactly one"),
        ("[scene]", "[scenery]\n[scene]", r"unknown table \[scenery\]; valid: \[scene\], .*did you mean \[scene\]\?"),
        ("[control]", "[gains]\nmax_joint_sped = 0.5\n[control]",
         r"unknown key 'max_joint_sped' in \[gains\]; valid keys: task_kp, .*; did you mean 'max_joint_speed'\?"),
        ("[obstacles]", "[obstacle]",
         r"unknown table \[obstacle\]; valid: .*\[obstacles\].*; did you mean \[obstacles\]\?$"),
        ("[control]", "[gains]\nnull_kp = 0.5\n[control]", r"unknown key 'null_kp' in \[gains\]; valid keys: .*extra$"),
        ("[task]", "[task]\nduraton = 3.0", r"unknown key 'duraton' in \[task\].*did you mean 'duration'"),
        ("dwell = 0.2", "dwel = 0.2", r"unknown key 'dwel' in \[\[task.goals\]\] goal 1; valid keys: site, pos, dwell"),
        ("speed = 0.1", "sped = 0.1", r"unknown key 'sped' in \[\[moving\]\] entry 1; valid keys: body, type, start, end"),
        ("period = 0.004", "period = 0.004\nperiod_s = 1", r"unknown key 'period_s' in \[control\]"),
        ("[scene]", "colour = 'red'\n[scene]", r"'colour' = 'red' outside any table"),
    ],
)
def test_bad_config_values(tmp_path: Path, old: str, new: str, match: str) -> None:
    assert old in TINY_TOML
    with pytest.raises(ConfigError, match=match):
        load_scene_from_files(*write(tmp_path, toml=TINY_TOML.replace(old, new, 1)))


def test_missing_required_section(tmp_path: Path) -> None:
    toml = TINY_TOML.replace('[obstacles]\ngeoms = ["wall", "stat_geom", "ghost_geom"]\n', "")
    with pytest.raises(ConfigError, match=r"table \[obstacles\]: missing \(required\)"):
        load_config(write(tmp_path, toml=toml)[1])


def test_config_without_scene_name_uses_file_stem(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path, toml=TINY_TOML.replace('name = "tiny"\n', ""))[1])
    assert cfg.name == "tiny"


def test_extra_gains_are_kept(tmp_path: Path) -> None:
    toml = TINY_TOML.replace("[control]", "[gains]\ntask_kp = 3.0\nmax_joint_acc = 4.0\ngoal_timeout = 2.5\n"
                                          "[gains.extra]\nnull_kp = 0.5\nw = [1.0]\n[control]")
    cfg = load_config(write(tmp_path, toml=toml)[1])
    assert (cfg.gains.task_kp, cfg.gains.max_joint_acc, cfg.gains.goal_timeout) == (3.0, 4.0, 2.5)
    assert cfg.gains.extra == {"null_kp": 0.5, "w": (1.0,)}
    bad = toml.replace("null_kp = 0.5", "null_kp = 'high'")
    with pytest.raises(ConfigError, match=r"\[gains.extra\] null_kp: expected a finite number"):
        load_config(write(tmp_path, toml=bad)[1])


def test_every_documented_key_is_accepted_and_only_those() -> None:
    """The schema block of models/README.md and the reader's key lists say the same."""
    import re

    from isf_robot.arm.config_toml import SECTION_KEYS, TABLES

    text = (models_dir() / "README.md").read_text()
    block = text.split("## Config schema")[1].split("```toml")[1].split("```")[0]
    documented: dict[str, set[str]] = {}
    table = ""
    for line in block.splitlines():
        m = re.match(r"^\[\[?([a-z_.]+)\]\]?", line)
        if m:
            table = m.group(1)
            continue
        k = re.match(r"^#? ?([a-z_]+) = ", line)
        if k and table:
            documented.setdefault(table, set()).add(k.group(1))
    assert set(documented) == {*TABLES, "task.goals", "gains.extra"}
    for t in TABLES:
        valid = set(SECTION_KEYS[t]) if t != "moving" else set(SECTION_KEYS["moving.circle"]) | set(
            SECTION_KEYS["moving.linear_bounce"])
        if t == "task":
            valid -= {"goals"}  # written as [[task.goals]] tables
        if t == "gains":
            valid -= {"extra"}  # written as the [gains.extra] table
        assert documented[t] == valid, t
    assert documented["task.goals"] == set(SECTION_KEYS["task.goals"])


def test_unlimited_joint_and_no_actuator(tmp_path: Path) -> None:
    xml = TINY_XML.replace(' range="-2 2"', "").replace(
        '<actuator><motor joint="hinge" ctrlrange="-5 5"/></actuator>', "")
    sc = load_scene_from_files(*write(tmp_path, xml=xml))
    assert np.all(np.isinf(sc.joint_range))
    assert sc.actuator_ids[0] == -1 and np.isinf(sc.torque_limit[0])
    assert isinstance(sc.model, mujoco.MjModel)


def test_load_scene_uses_the_models_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import isf_robot.arm.scene as scene_mod

    write(tmp_path)
    (tmp_path / "broken.toml").write_text("[scene\n")
    monkeypatch.setattr(scene_mod, "models_dir", lambda: tmp_path)
    infos = {s.name: s.description for s in list_scenes()}
    assert infos == {"broken": "(unreadable config)", "tiny": "one link"}
    assert load_scene("tiny").n_joints == 1
    (tmp_path / "tiny.toml").write_text(TINY_TOML.replace('name = "tiny"', 'name = "other"'))
    with pytest.raises(ConfigError, match="differs from the file name"):
        load_scene("tiny")


@pytest.mark.parametrize("name", ALL_SCENES)
def test_every_goal_has_a_collision_free_pose(name: str) -> None:
    """The filter can only finish the task if each goal is reachable with clearance > margin."""
    sc = load_scene(name)
    m, d = sc.model, sc.make_data()
    cb = CollisionBarriers.from_scene(sc)
    rng = np.random.default_rng(7)
    jm = sc.config.barrier.joint_margin + 0.01
    lo, hi = sc.joint_range[:, 0] + jm, sc.joint_range[:, 1] - jm
    jac = np.zeros((3, m.nv))
    for goal in sc.goal_positions:
        found = False
        for trial in range(40):
            q = np.clip(sc.home + (rng.normal(0.0, 0.6, sc.n_joints) if trial else 0.0), lo, hi)
            for _ in range(100):  # damped least-squares IK on the ee position
                d.qpos[sc.qpos_adr] = q
                mujoco.mj_kinematics(m, d)
                mujoco.mj_comPos(m, d)
                err = goal - sc.ee_position(d)
                if np.linalg.norm(err) < 1e-4:
                    break
                sc.ee_jacobian(d, jac)
                J = jac[:, sc.dof_adr]
                q = np.clip(q + J.T @ np.linalg.solve(J @ J.T + 1e-4 * np.eye(3), err), lo, hi)
            if np.linalg.norm(err) < 1e-3 and cb.min_distance(d).distance > sc.config.barrier.margin:
                found = True
                break
        assert found, f"goal {goal} of {name} has no collision-free pose"
