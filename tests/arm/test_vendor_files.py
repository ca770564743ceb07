"""Vendor arm files as vendors write them (inline MJCF): what `init`, `check` and the low-level
tracker make of them.

The arms here are written the way Menagerie and other robot-learning suites write theirs:
``<default>`` classes, ``<general>`` position servos with ``gainprm``/``biasprm`` (Menagerie's UR5e
way), torque motors, joint ``frictionloss`` and ``armature``, a tool site ``attachment_site`` next to
axis-marker sites, a colliding floor plane, ``goal_*`` sites, and a ``qpos0`` outside a joint range.
"""

from __future__ import annotations

import re
from pathlib import Path

import mujoco
import numpy as np
import pytest
import tomllib

from isf_robot.arm import build_scene, calibrate_d_bar, load_scene_from_files
from isf_robot.arm.diagnostics import check_calibration, check_scene
from isf_robot.arm.lowlevel import FRICTION_SMOOTHING, friction_feedforward
from isf_robot.arm.starter import starter_toml
from isf_robot.cli import main

# A 4-joint servo arm written like Menagerie's UR5e: <general> servos from default classes, a tool site
# and three axis markers on the flange, a colliding floor, goal sites, and no keyframe: qpos0 (all zeros)
# puts the elbow outside its range [0.3, 2.6].
SERVO_ARM = """
<mujoco model="vendor_servo">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="implicitfast"/>
  <default>
    <default class="arm">
      <joint axis="0 1 0" range="-3 3" armature="0.1"/>
      <general gaintype="fixed" biastype="affine" gainprm="2000" biasprm="0 -2000 -400" forcerange="-150 150"/>
      <default class="elbow"><joint range="0.3 2.6"/></default>
      <default class="small"><general gainprm="500" biasprm="0 -500 -100" forcerange="-28 28"/></default>
      <default class="collision"><geom type="capsule" group="3" size="0.045"/></default>
      <site size="0.005" group="4"/>
    </default>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="base" childclass="arm">
      <geom class="collision" fromto="0 0 0.02 0 0 0.1" size="0.07"/>
      <body name="l1" pos="0 0 0.12">
        <joint name="pan" axis="0 0 1"/>
        <inertial pos="0 0 0.05" mass="3" diaginertia="0.02 0.02 0.01"/>
        <geom class="collision" fromto="0 0 0 0 0 0.12"/>
        <body name="l2" pos="0 0 0.16">
          <joint name="lift"/>
          <inertial pos="0 0 0.2" mass="4" diaginertia="0.06 0.06 0.01"/>
          <geom class="collision" fromto="0 0 0.05 0 0 0.38"/>
          <body name="l3" pos="0 0 0.42">
            <joint name="elbow" class="elbow"/>
            <inertial pos="0 0 0.17" mass="2" diaginertia="0.02 0.02 0.004"/>
            <geom class="collision" fromto="0 0 0.05 0 0 0.33" size="0.035"/>
            <body name="l4" pos="0 0 0.36">
              <joint name="wrist" class="small"/>
              <inertial pos="0 0 0.05" mass="0.8" diaginertia="0.002 0.002 0.001"/>
              <geom class="collision" fromto="0 0 0.02 0 0 0.09" size="0.03"/>
              <site name="ee_x" pos="0.05 0 0.1"/>
              <site name="ee_y" pos="0 0.05 0.1"/>
              <site name="attachment_site" pos="0 0 0.1"/>
              <site name="ee_z" pos="0 0 0.15"/>
            </body>
          </body>
        </body>
      </body>
    </body>
    <body name="obstacles"><geom name="pole" type="capsule" fromto="0.45 0.3 0 0.45 0.3 0.5" size="0.03"/></body>
    <site name="goal_10" pos="0.2 -0.3 0.6"/>
    <site name="goal_2" pos="0.4 -0.1 0.5"/>
    <site name="goal_1" pos="0.35 0.25 0.7"/>
  </worldbody>
  <actuator>
    <general class="arm" name="a_pan" joint="pan"/>
    <general class="arm" name="a_lift" joint="lift"/>
    <general class="elbow" name="a_elbow" joint="elbow" ctrlrange="0.3 2.6"/>
    <general class="small" name="a_wrist" joint="wrist"/>
  </actuator>
</mujoco>
"""


def _write(tmp_path: Path, xml: str, name: str = "vendor.xml") -> Path:
    p = tmp_path / name
    p.write_text(xml)
    return p


def test_init_reads_a_vendor_servo_arm(tmp_path: Path) -> None:
    xml = _write(tmp_path, SERVO_ARM)
    text = starter_toml(xml)
    cfg = tomllib.loads(text)
    rob = cfg["robot"]
    # the tool site, not an axis marker (ee_y and ee_z come after it in the file, ee_x before)
    assert rob["ee_site"] == "attachment_site"
    assert "other sites on the last links: ee_x, ee_y, ee_z" in text
    # qpos0 puts the elbow at 0, outside [0.3, 2.6]: flagged, and the nearest pose in range written
    assert "has arm joints outside their range (elbow 0 outside [0.3, 2.6])" in text
    assert rob["home"] == [0.0, 0.0, 0.3, 0.0]
    # the colliding floor is named, not selected; the pole is
    assert re.search(r"# Left out: the colliding plane\(s\) \"floor\"", text)
    assert cfg["obstacles"]["geoms"] == ["pole"]
    # goal_* sites as goals, in natural order
    assert [g["site"] for g in cfg["task"]["goals"]] == ["goal_1", "goal_2", "goal_10"]
    # a speed bound for kp/kv servos on undamped joints: (F - |gravity at home|) / kv
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    data.qpos[:] = [0.0, 0.0, 0.3, 0.0]
    mujoco.mj_forward(model, data)
    grav = np.abs(data.qfrc_bias)
    bound = (np.array([150.0, 150, 150, 28]) - grav) / np.array([400.0, 400, 400, 100])
    assert "inf" not in text
    for j, v in zip(("pan", "lift", "elbow", "wrist"), bound):
        assert f"#   {j}: position servo kp {500 if j == 'wrist' else 2000:g} kv {100 if j == 'wrist' else 400:g}" in text
        assert f"max speed {v:.6g} rad/s ((limit - gravity) / kv)" in text
    assert cfg["gains"]["max_joint_speed"] == float(f"{0.8 * bound.min():.2g}")
    # the starter loads as it is, and check has nothing to say about the home pose
    (tmp_path / "vendor.toml").write_text(text)
    sc = load_scene_from_files(xml, tmp_path / "vendor.toml")
    np.testing.assert_allclose(sc.home, [0.0, 0.0, 0.3, 0.0])
    assert [g for g in cfg["task"]["goals"]] and sc.ee_site_id >= 0


def test_init_without_a_tool_site_never_takes_an_axis_marker(tmp_path: Path) -> None:
    xml = _write(tmp_path, SERVO_ARM.replace('<site name="attachment_site" pos="0 0 0.1"/>', ""))
    cfg = tomllib.loads(starter_toml(xml))
    assert "ee_site" not in cfg["robot"] and cfg["robot"]["ee_body"] == "l4"
    # a site named for a tool is preferred over other non-marker sites, whatever the file order
    xml = _write(tmp_path, SERVO_ARM.replace('<site name="attachment_site" pos="0 0 0.1"/>',
                                             '<site name="tcp" pos="0 0 0.12"/><site name="camera_mount" pos="0 0 0"/>'))
    assert tomllib.loads(starter_toml(xml))["robot"]["ee_site"] == "tcp"


def test_init_with_a_home_keyframe_out_of_range(tmp_path: Path) -> None:
    xml = _write(tmp_path, SERVO_ARM.replace("</actuator>", '</actuator>\n  <keyframe><key name="home" qpos="0.1 0.2 2.9 0"/></keyframe>'))
    text = starter_toml(xml)
    assert "home from keyframe 'home' has arm joints outside their range (elbow 2.9 outside [0.3, 2.6])" in text
    assert tomllib.loads(text)["robot"]["home"] == [0.1, 0.2, 2.6, 0.0]


def test_goal_messages_name_goals_from_one_and_the_closest_approach(tmp_path: Path) -> None:
    xml = _write(tmp_path, SERVO_ARM)
    toml = starter_toml(xml)
    # goal 2 (site goal_2) moved inside the arm's reach sphere but below the floor-level base: IK cannot reach it
    toml = toml.replace('site = "goal_2"', 'pos = [0.05, 0.0, -0.25]')
    (tmp_path / "vendor.toml").write_text(toml)
    sc = load_scene_from_files(xml, tmp_path / "vendor.toml")
    found = [f.message for f in check_scene(sc) if f.code == "goal-reach" and f.message.startswith("goal 2 ")]
    assert len(found) == 1
    msg = found[0]
    m = re.search(r"^goal 2 at \[0\.05, 0\.0, -0\.25\] .* came no closer than ([0-9.]+) m \(it starts ([0-9.]+) m "
                  r"away at home", msg)
    assert m, msg
    closest, at_home = float(m.group(1)), float(m.group(2))
    data = sc.make_data(0.0)
    mujoco.mj_forward(sc.model, data)
    assert at_home == pytest.approx(np.linalg.norm(np.array([0.05, 0.0, -0.25]) - sc.ee_position(data)), abs=1e-3)
    assert closest <= at_home and closest > sc.config.task.tolerance
    # a goal named by its site says which
    toml2 = toml.replace('site = "goal_10"', 'site = "far"')
    (tmp_path / "v2.xml").write_text(SERVO_ARM.replace("</worldbody>", '<site name="far" pos="3 0 0.5"/></worldbody>'))
    (tmp_path / "v2.toml").write_text(toml2.replace('model = "vendor.xml"', 'model = "v2.xml"'))
    found = check_scene(load_scene_from_files(tmp_path / "v2.xml", tmp_path / "v2.toml"))
    assert any(f.message.startswith("goal 3 ('far') at [3.0, 0.0, 0.5]") for f in found)


# A 4-joint torque-motor arm with joint friction, as other robot-learning suites write theirs.
FRICTION_ARM = """
<mujoco model="friction_arm">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="implicitfast"/>
  <default>
    <default class="arm">
      <joint axis="0 1 0" range="-2.9 2.9" armature="0.05" frictionloss="FRIC" damping="0.5"/>
      <motor ctrlrange="-60 60"/>
      <default class="wrist"><joint frictionloss="FRICW"/><motor ctrlrange="-15 15"/></default>
      <default class="collision"><geom type="capsule" group="3" size="0.04"/></default>
    </default>
  </default>
  <worldbody>
    <body name="base" childclass="arm">
      <geom class="collision" fromto="0 0 0 0 0 0.1" size="0.07"/>
      <body name="l1" pos="0 0 0.12">
        <joint name="j1" axis="0 0 1"/>
        <inertial pos="0 0 0.05" mass="2" diaginertia="0.01 0.01 0.01"/>
        <geom class="collision" fromto="0 0 0 0 0 0.15"/>
        <body name="l2" pos="0 0 0.18">
          <joint name="j2"/>
          <inertial pos="0 0 0.18" mass="2" diaginertia="0.03 0.03 0.005"/>
          <geom class="collision" fromto="0 0 0 0 0 0.35"/>
          <body name="l3" pos="0 0 0.38">
            <joint name="j3"/>
            <inertial pos="0 0 0.15" mass="1.2" diaginertia="0.015 0.015 0.003"/>
            <geom class="collision" fromto="0 0 0 0 0 0.3" size="0.035"/>
            <body name="l4" pos="0 0 0.32">
              <joint name="j4" class="wrist"/>
              <inertial pos="0 0 0.05" mass="0.5" diaginertia="0.002 0.002 0.001"/>
              <geom class="collision" fromto="0 0 0 0 0 0.1" size="0.03"/>
              <site name="attachment_site" pos="0 0 0.12"/>
            </body>
          </body>
        </body>
      </body>
    </body>
    <body name="obstacles"><geom name="ball" type="sphere" size="0.05" pos="0.8 0.8 0.3"/></body>
    <site name="goal_a" pos="0.35 0.2 0.6"/>
    <site name="goal_b" pos="0.3 -0.25 0.45"/>
  </worldbody>
  <actuator>
    <motor class="arm" joint="j1"/><motor class="arm" joint="j2"/><motor class="arm" joint="j3"/>
    <motor class="wrist" joint="j4"/>
  </actuator>
  <keyframe><key name="home" qpos="0 0.5 0.9 0.4"/></keyframe>
</mujoco>
"""
FRICTION_CFG = {"robot": {"subtree": "base", "ee_site": "attachment_site", "home": "home"},
                "obstacles": {"bodies": ["obstacles"]},
                "task": {"goals": [{"site": "goal_a", "dwell": 0.3}, {"site": "goal_b", "dwell": 0.3}]},
                "gains": {"max_joint_speed": 1.0, "tracking_kp": 400.0, "tracking_kd": 40.0}}


def _friction_scene(fric: float, wrist: float):  # type: ignore[no-untyped-def]
    xml = FRICTION_ARM.replace("FRICW", f"{wrist:g}").replace("FRIC", f"{fric:g}")
    return build_scene(mujoco.MjModel.from_xml_string(xml), FRICTION_CFG)


def test_friction_feedforward_is_smooth_and_signed() -> None:
    f = np.array([3.0, 3.0, 3.0, 1.0])
    u = np.array([0.0, FRICTION_SMOOTHING, -1.0, 1e-4])
    out = friction_feedforward(f, u)
    assert out[0] == 0.0 and out[1] == pytest.approx(3.0 * np.tanh(1.0)) and out[2] == pytest.approx(-3.0)
    assert 0 < out[3] < 0.01  # smooth through zero: a tiny command asks for a tiny torque


def test_joint_friction_is_compensated_and_named() -> None:
    clean = calibrate_d_bar(_friction_scene(0.0, 0.0))
    sc = _friction_scene(3.0, 1.0)
    comp = calibrate_d_bar(sc)
    off = calibrate_d_bar(sc, friction=False)
    # measured: 0.040 (no friction), 0.083 (friction fed forward), 1.02 rad/s (not fed forward)
    assert comp.friction_fed_forward and not off.friction_fed_forward
    assert comp.d_bar < 2.5 * clean.d_bar and off.d_bar > 10 * comp.d_bar
    assert check_calibration(sc, comp) == []
    found = check_calibration(sc, off)
    assert [f.code for f in found] == ["d-bar"]
    msg = found[0].message
    assert "joint friction (dof_frictionloss: j1 3, j2 3, j3 3, j4 1 N m)" in msg and "not fed forward" in msg
    assert "armature (dof_armature: j1 0.05, j2 0.05, j3 0.05, j4 0.05 kg m^2)" in msg
    # a run uses the same compensation (the numpy tracker: the compiled one has no friction term)
    from isf_robot.arm import run_episode

    res = run_episode(sc, "nominal", duration=3.0, d_bar=comp.d_bar)
    assert res.goals_reached == 2 and res.tracking_error_q99 < comp.d_bar


def test_servo_friction_is_compensated(tmp_path: Path) -> None:
    xml = SERVO_ARM.replace('armature="0.1"/>', 'armature="0.1" frictionloss="12"/>')
    cfg = {"robot": {"subtree": "base", "ee_site": "attachment_site", "home": [0.0, 0.3, 1.2, 0.3]},
           "obstacles": {"bodies": ["obstacles"]},
           "task": {"goals": [{"site": "goal_1", "dwell": 0.3}, {"site": "goal_2", "dwell": 0.3}]},
           "gains": {"max_joint_speed": 0.5}}
    clean = calibrate_d_bar(build_scene(mujoco.MjModel.from_xml_string(SERVO_ARM), cfg))
    sc = build_scene(mujoco.MjModel.from_xml_string(xml), cfg)
    comp, off = calibrate_d_bar(sc), calibrate_d_bar(sc, friction=False)
    # measured: 0.037 (no friction), 0.075 (fed forward), 0.138 rad/s (not): the servo's kv resists friction already
    assert comp.d_bar < 2.5 * clean.d_bar and off.d_bar > 1.5 * comp.d_bar


def test_init_and_check_from_the_command_line(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    xml = _write(tmp_path, SERVO_ARM)
    assert main(["init", "--model", str(xml), "--output", str(tmp_path / "vendor.toml")]) == 0
    capsys.readouterr()
    assert main(["check", "--model", str(xml), "--config", str(tmp_path / "vendor.toml"), "--no-calibration"]) == 0
    out = capsys.readouterr().out
    assert "pan 0.375 (servo kv)" in out


def test_the_guides_ur5e_figures_are_the_models() -> None:
    """Every UR5e figure of the five-minute guide (models/README.md), checked against the model it names."""
    from isf_robot.arm import load_scene
    from isf_robot.arm.diagnostics import speed_bounds
    from isf_robot.paths import models_dir

    guide = " ".join((models_dir() / "README.md").read_text().split())
    sc = load_scene("ur5e_pole")
    model = sc.model
    # the Menagerie facts, as the shipped arm has them
    assert 'the base turned by `quat="0 0 0 -1"` (at home the arm points to +y)' in guide
    np.testing.assert_allclose(model.body("base").quat, [0, 0, 0, -1])
    m = re.search(r"servos kp (\d+) / kv (\d+) with `forcerange` \+-(\d+) N m on the shoulder and elbow \(class `size3`\) "
                  r"and kp (\d+) / kv (\d+) with \+-(\d+) N m on the wrists \(`size1`\), armature ([0-9.]+), no joint damping",
                  guide)
    assert m, "the guide's servo sentence changed: update this test with it"
    kp3, kv3, f3, kp1, kv1, f1, arm = (float(x) for x in m.groups())
    assert (kp3, kv3, f3, kp1, kv1, f1, arm) == (2000, 400, 150, 500, 100, 28, 0.1)  # Menagerie's ur5e.xml
    for a, (kp, kv, f) in enumerate([(kp3, kv3, f3)] * 3 + [(kp1, kv1, f1)] * 3):
        assert model.actuator_gainprm[a, 0] == kp and list(model.actuator_biasprm[a, :3]) == [0, -kp, -kv]
        assert list(model.actuator_forcerange[a]) == [-f, f]
    np.testing.assert_array_equal(model.dof_damping[sc.dof_adr], 0.0)
    np.testing.assert_array_equal(model.dof_armature[sc.dof_adr], arm)
    assert sc.config.robot.ee_site == "attachment_site"
    assert model.site_bodyid[model.site("attachment_site").id] == model.body("wrist_3_link").id
    data = sc.make_data(0.0)
    mujoco.mj_forward(model, data)
    ee = sc.ee_position(data)
    m = re.search(r"`attachment_site` is at \((-?[0-9.]+), (-?[0-9.]+), (-?[0-9.]+)\) m", guide)
    assert m and np.allclose([float(x) for x in m.groups()], ee, atol=0.005)
    # the wrapper's obstacles and goals (the guide's example and ur5e_pole.xml) are in front of the arm
    block = guide.split("Wrap, do not edit.")[1].split("```")[1]
    points = [np.array([float(x) for x in p.split()]) for p in re.findall(r'(?:pos|fromto)="([^"]+)"', block)]
    assert len(points) == 4
    front = ee[:2] / np.linalg.norm(ee[:2])
    for p in points:
        assert float(p[:2] @ front) > 0.2, p
    for g in sc.obstacle_geom_ids:
        assert float(data.geom_xpos[g][:2] @ front) > 0.2
    assert all(float(p[:2] @ front) > 0.2 for p in sc.goal_positions)
    # init's speed bounds and the max_joint_speed it writes
    m = re.search(r"that is ([0-9.]+) rad/s for the shoulder pan \((\d+) / (\d+)\), ([0-9.]+) for the shoulder lift and "
                  r"elbow, ([0-9.]+) for wrist 1 and ([0-9.]+) for wrists 2-3 \((\d+) / (\d+)\), so `init` writes "
                  r"`max_joint_speed = ([0-9.]+)`", guide)
    assert m, "the guide's speed sentence changed: update this test with it"
    v, rules = speed_bounds(sc)
    assert rules == ["servo kv"] * 6
    quoted = [float(m.group(i)) for i in (1, 4, 4, 5, 6, 6)]
    np.testing.assert_allclose(v, quoted, atol=0.0005)
    assert float(m.group(2)) / float(m.group(3)) == pytest.approx(v[0])
    assert float(m.group(7)) / float(m.group(8)) == pytest.approx(v[4])
    assert tomllib.loads(starter_toml(models_dir() / "ur5e_pole.xml"))["gains"]["max_joint_speed"] == float(m.group(9))
    # the shipped scene's speed and its calibration
    m = re.search(r"`ur5e_pole` runs at `max_joint_speed = ([0-9.]+)` with no actuator saturation in the calibration "
                  r"and `d_bar` = ([0-9.]+) rad/s \((\d+)% of it\)", guide)
    assert m
    assert sc.config.gains.max_joint_speed == float(m.group(1))
    cal = calibrate_d_bar(sc)
    assert max(cal.saturation) == 0.0
    assert round(cal.d_bar, 3) == float(m.group(2))
    assert round(100 * cal.d_bar / sc.config.gains.max_joint_speed) == int(m.group(3))


@pytest.mark.parametrize("name", ["vendor_panda_servo", "vendor_panda_position", "vendor_ur5e_torque"])
def test_the_benchmarks_vendor_arms_are_inits_configs(name: str) -> None:
    """benchmarks/vendor_arms: collision meshes, servos or motors, friction, armature; the config is init's."""
    folder = Path(__file__).resolve().parents[2] / "benchmarks" / "vendor_arms"
    xml, toml = folder / f"{name}.xml", folder / f"{name}.toml"
    text = toml.read_text()
    cfg = tomllib.loads(text)
    assert "filter" not in cfg  # the library's defaults
    # init's output, with only the header comment and the scene description filled in
    body = text.split("\n", 4)[4]
    desc = f'description = "{cfg["scene"]["description"]}"'
    assert body.replace(desc, f'description = "{name}: starter config (edit me)"') == starter_toml(xml)
    sc = load_scene_from_files(xml, toml)
    model = sc.model
    robot_types = {int(model.geom_type[g]) for g in sc.robot_geom_ids}
    assert robot_types == {int(mujoco.mjtGeom.mjGEOM_MESH)}
    assert model.nmesh == len(sc.robot_geom_ids)
    assert np.all(model.dof_frictionloss[sc.dof_adr] > 0) and np.all(model.dof_armature[sc.dof_adr] > 0)
    kinds = {int(model.actuator_biastype[a]) for a in sc.actuator_ids}
    servo = "panda" in name
    assert kinds == {int(mujoco.mjtBias.mjBIAS_AFFINE if servo else mujoco.mjtBias.mjBIAS_NONE)}
    assert [model.geom(g).name for g in sc.obstacle_geom_ids] == ["pole", "ball"] and len(sc.goal_positions) == 3
    assert check_scene(sc) == []  # no contact at home, speeds within the actuators, ccd_tolerance tight
