"""Diagnostics of a user's arm: the crippling cases get a warning that names the cause, and the
commands init / check / run say so."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import tomllib

from isf_robot.arm import ArmSimulation, build_scene, calibrate_d_bar, load_scene, load_scene_from_files
from isf_robot.arm.diagnostics import check_calibration, check_scene, joint_speed_limits
from isf_robot.cli import main
from isf_robot.paths import models_dir

ARMS = {"panda_servo": "panda_servo_arm.xml", "ur5e_pole": "ur5e_arm.xml"}
BASE = '<geom class="collision" fromto="-0.05 0 0.06 0 0 0.06" size="0.07"/>'
# Menagerie's earlier UR5e revision: <position> servos without kv and joint damping 200 (shoulder, elbow) / 15 (wrists)
DAMPED = ('armature="0.1"/>', 'armature="0.1" damping="200"/>')
DAMPED_WRISTS = ('<default class="size1">\n', '<default class="size1">\n        <joint damping="15"/>\n')
TALL_BASE = '<geom class="collision" fromto="-0.04 0 0.05 -0.04 0 0.16" size="0.1"/>'


def variant(tmp_path: Path, scene: str, arm: tuple[str, str] | None = None,
            toml: tuple[str, str] | None = None, xml: tuple[str, str] | None = None) -> tuple[Path, Path]:
    """Copies of a shipped Menagerie-style scene (arm file, wrapper, TOML) with replacements."""
    src = models_dir()
    texts = {ARMS[scene]: (src / ARMS[scene]).read_text(), f"{scene}.xml": (src / f"{scene}.xml").read_text(),
             f"{scene}.toml": (src / f"{scene}.toml").read_text()}
    for name, rep in ((ARMS[scene], arm), (f"{scene}.xml", xml), (f"{scene}.toml", toml)):
        if rep is not None:
            assert rep[0] in texts[name]
            texts[name] = texts[name].replace(*rep)
    for name, text in texts.items():
        (tmp_path / name).write_text(text)
    return tmp_path / f"{scene}.xml", tmp_path / f"{scene}.toml"


def codes(findings) -> list[str]:  # type: ignore[no-untyped-def]
    return [f.code for f in findings]


def test_shipped_scenes_have_no_findings() -> None:
    for name in ("panda_pole", "planar", "panda_servo", "ur5e_pole"):
        assert check_scene(load_scene(name)) == [], name


def test_base_overlapping_link1_at_home_is_named(tmp_path) -> None:  # type: ignore[no-untyped-def]
    # crippling case 1: a base capsule on the world-fixed link0 overlaps link 1 at home
    xml, toml = variant(tmp_path, "panda_servo", arm=(BASE, TALL_BASE))
    sc = load_scene_from_files(xml, toml)
    found = check_scene(sc)
    assert codes(found) == ["self-contact"]
    msg = found[0].message
    assert "'link0[0]' (body 'link0') and 'link1[0]' (body 'link1')" in msg
    assert "fixed to the world" in msg and '<exclude body1="link0" body2="link1"/>' in msg
    # the calibration sees the contact: joint 1 saturated, d_bar several times the clean arm's
    cal = calibrate_d_bar(sc, duration=1.0, use_cache=False)
    later = check_calibration(sc, cal)
    assert codes(later) == ["saturation", "d-bar"] and "joint1" in later[0].message
    clean = calibrate_d_bar(load_scene("panda_servo"), duration=1.0, use_cache=False)
    assert cal.d_bar > 3 * clean.d_bar and check_calibration(sc, clean) == []
    # the suggested fix, in the wrapper (the arm file untouched), removes the finding
    (tmp_path / "fixed").mkdir()
    fixed = variant(tmp_path / "fixed", "panda_servo", arm=(BASE, TALL_BASE),
                    xml=("</worldbody>", '</worldbody>\n  <contact><exclude body1="link0" body2="link1"/></contact>'))
    assert check_scene(load_scene_from_files(*fixed)) == []


def test_ur5e_damping_against_the_default_joint_speed(tmp_path) -> None:  # type: ignore[no-untyped-def]
    # crippling case 2: damping 200 N m s/rad and 150 N m, but the default max_joint_speed 2.0
    xml, toml = variant(tmp_path, "ur5e_pole", toml=("max_joint_speed = 0.5\n", ""), arm=DAMPED)
    arm = tmp_path / ARMS["ur5e_pole"]
    assert DAMPED_WRISTS[0] in arm.read_text()
    arm.write_text(arm.read_text().replace(*DAMPED_WRISTS))
    sc = load_scene_from_files(xml, toml)
    assert sc.config.gains.max_joint_speed == 2.0
    v, grav = joint_speed_limits(sc)
    np.testing.assert_allclose(v[0], 150.0 / 200.0)  # the pan joint carries no gravity
    np.testing.assert_allclose(v[1], (150.0 - grav[1]) / 200.0)
    assert grav[1] > 10  # the shoulder lifts the arm
    np.testing.assert_allclose(v[3:], (28.0 - grav[3:]) / 15.0)
    found = check_scene(sc)
    assert codes(found) == ["joint-speed"]
    msg = found[0].message
    assert "max_joint_speed = 2 rad/s" in msg and "shoulder_pan_joint: 0.75 rad/s" in msg
    assert f"max_joint_speed = {0.8 * v.min():.2g}" in msg
    assert check_scene(load_scene("ur5e_pole")) == []  # the shipped arm has no joint damping and sets 0.5


def test_pair_accuracy_servo_chatter_and_reach(tmp_path) -> None:  # type: ignore[no-untyped-def]
    xml, toml = variant(
        tmp_path, "ur5e_pole",
        xml=('ccd_tolerance="1e-10"', 'ccd_tolerance="1e-6"'),
        toml=('bodies = ["obstacles"]', 'bodies = ["obstacles", "boxes"]'))
    text = xml.read_text().replace("</worldbody>", '<body name="boxes"><geom type="box" size="0.05 0.05 0.05" '
                                   'pos="0.6 0.6 0.1"/></body>\n    <site name="far" pos="2 0 0.3"/>\n  </worldbody>')
    xml.write_text(text)
    toml.write_text(toml.read_text().replace('site = "goal_c"', 'site = "far"'))
    found = check_scene(load_scene_from_files(xml, toml))
    assert codes(found) == ["capsule-box", "ccd-tolerance", "goal-reach"]
    assert "upper_arm_link[1]|boxes[0]" in found[0].message
    assert "wrist_3_link[1]" in found[1].message and 'ccd_tolerance="1e-10"' in found[1].message
    assert "goal 3 ('far') at [2.0, 0.0, 0.3]" in found[2].message and "reaches at most" in found[2].message
    # a stiff force-limited servo at a coarse timestep
    (tmp_path / "coarse").mkdir()
    xml2, toml2 = variant(tmp_path / "coarse", "panda_servo", xml=('timestep="0.001"', 'timestep="0.002"'))
    found = check_scene(load_scene_from_files(xml2, toml2))
    assert codes(found) == ["servo-chatter"] and "joint7" in found[0].message
    assert '<option timestep="0.001"/>' in found[0].message


def test_build_scene_from_model_and_dict() -> None:
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(models_dir() / "ur5e_pole.xml"))
    with (models_dir() / "ur5e_pole.toml").open("rb") as fh:
        cfg = tomllib.load(fh)
    cfg.pop("scene")
    sc = build_scene(model, cfg)
    ref = load_scene("ur5e_pole")
    assert sc.model is model and sc.xml_path is None and sc.name == "scene"
    assert sc.joint_names == ref.joint_names
    np.testing.assert_array_equal(sc.robot_geom_ids, ref.robot_geom_ids)
    np.testing.assert_array_equal(sc.goal_positions, ref.goal_positions)
    info = ArmSimulation(sc, "cbf", d_bar=0.05).start_info(1.0)
    assert info["model_path"] is None and info["config_path"] is None  # no file: None, not "None"
    again = build_scene(models_dir() / "ur5e_pole.xml", sc.config)
    assert again.xml_path is not None and again.config is sc.config
    with pytest.raises(ValueError, match="mapping"):
        build_scene(model, ["robot"])  # type: ignore[arg-type]


def test_init_writes_a_loadable_starter(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["init", "--model", str(models_dir() / "ur5e_arm.xml")]) == 0
    text = capsys.readouterr().out
    cfg = tomllib.loads(text)
    rob = cfg["robot"]
    assert rob["subtree"] == "base" and rob["geom_group"] == 3 and rob["home"] == "home"
    assert rob["ee_site"] == "attachment_site" and len(rob["joints"]) == 6
    assert "shoulder_pan_joint: position servo kp 2000 kv 400, limit 150 N m, damping 0" in text
    assert "max speed 0.375 rad/s ((limit - gravity) / kv)" in text  # 150 N m / 400 N m s/rad
    sc = load_scene("ur5e_pole")
    v, grav = joint_speed_limits(sc)
    assert np.all(np.isinf(v))  # no joint damping: nothing bounds the steady speed
    kv = np.array([400.0] * 3 + [100.0] * 3)
    F = np.array([150.0] * 3 + [28.0] * 3)
    assert cfg["gains"]["max_joint_speed"] == float(f"{0.8 * np.min((F - grav) / kv):.2g}") == 0.21
    # with the obstacles of a wrapper, the starter loads as it is
    out = tmp_path / "start.toml"
    (tmp_path / "ur5e_arm.xml").write_text((models_dir() / "ur5e_arm.xml").read_text())
    wrapper = (models_dir() / "ur5e_pole.xml").read_text()
    (tmp_path / "mine.xml").write_text(wrapper)
    assert main(["init", "--model", str(tmp_path / "mine.xml"), "--output", str(out)]) == 0
    sc = load_scene_from_files(tmp_path / "mine.xml", out)
    assert len(sc.robot_geom_ids) == 9 and len(sc.obstacle_geom_ids) == 2
    # bad input: one line naming the problem, exit 2, nothing written
    capsys.readouterr()
    assert main(["init", "--model", str(tmp_path / "mine.xml"), "--output", str(tmp_path / "no" / "x.toml")]) == 2
    assert "folder" in capsys.readouterr().err and not (tmp_path / "no").exists()
    assert main(["init", "--model", str(tmp_path / "missing.xml")]) == 2
    assert "MJCF file not found" in capsys.readouterr().err


def test_check_and_run_warn(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    xml, toml = variant(tmp_path, "ur5e_pole", toml=("max_joint_speed = 0.5\n", ""), arm=DAMPED)
    rc = main(["check", "--model", str(xml), "--config", str(toml), "--no-calibration", "--strict"])
    out = capsys.readouterr().out
    assert rc == 1 and "warning [joint-speed]" in out and "shoulder_pan_joint position" in out
    rc = main(["run", "--model", str(xml), "--config", str(toml), "--duration", "0.2", "--d-bar", "0.9",
               "--json"])
    err = capsys.readouterr().err
    assert rc == 0 and "warning [joint-speed]" in err and "warning [d-bar]" in err
    assert main(["check", "--scene", "ur5e_pole", "--no-calibration"]) == 0
    assert "no findings" in capsys.readouterr().out


FINGERS = '''
  <body name="left_finger" pos="0 0 0.0584">
    <inertial mass="0.015" pos="0 0 0" diaginertia="2.4e-06 2.4e-06 2.4e-06"/>
    <joint name="finger_joint1" type="slide" axis="0 1 0" range="0 0.04" damping="100"/>
    <geom class="collision" type="box" size="0.0085 0.004 0.0085" pos="0 0.0055 0.0445"/>
  </body>
  <body name="right_finger" pos="0 0 0.0584" quat="0 0 0 1">
    <inertial mass="0.015" pos="0 0 0" diaginertia="2.4e-06 2.4e-06 2.4e-06"/>
    <joint name="finger_joint2" type="slide" axis="0 1 0" range="0 0.04" damping="100"/>
    <geom class="collision" type="box" size="0.0085 0.004 0.0085" pos="0 0.0055 0.0445"/>
  </body>
</body>'''
GRIPPER_ACTUATION = '''<tendon><fixed name="split"><joint joint="finger_joint1" coef="0.5"/>
  <joint joint="finger_joint2" coef="0.5"/></fixed></tendon>
<equality><joint joint1="finger_joint1" joint2="finger_joint2"/></equality>
<actuator>
  <general name="actuator8" tendon="split" forcerange="-100 100" ctrlrange="0 255"
           gainprm="0.01568627451 0 0" biasprm="0 -100 -10"/>
</actuator>
<keyframe>'''


@pytest.mark.filterwarnings("ignore:capsule-box")  # CollisionBarriers says so too
def test_a_gripper_in_the_arm_file_is_left_alone(tmp_path) -> None:  # type: ignore[no-untyped-def]
    # Menagerie's Panda: finger slide joints driven by one tendon actuator, fingertip pads as boxes
    xml, toml = variant(tmp_path, "panda_servo")
    arm = tmp_path / ARMS["panda_servo"]
    text = arm.read_text()
    hand_end = 'size="0.02"/>\n                      </body>'
    assert text.count(hand_end) == 1 and text.count("<keyframe>") == 1
    text = text.replace(hand_end, 'size="0.02"/>' + FINGERS).replace("<keyframe>", GRIPPER_ACTUATION)
    text = text.replace('-0.7853"\n', '-0.7853 0.04 0.04"\n', 1).replace('-0.7853"/>', '-0.7853 255"/>')
    arm.write_text(text)
    sc = load_scene_from_files(xml, toml)
    assert sc.joint_names == tuple(f"joint{i}" for i in range(1, 8))  # the fingers are not arm joints
    found = check_scene(sc)
    assert codes(found) == ["capsule-box"]
    assert "left_finger[0]|pole" in found[0].message and "the box is the arm's" in found[0].message
    assert "leave those geoms out of [robot]" in found[0].message
    from isf_robot.arm import run_episode

    res = run_episode(sc, "isf", duration=2.5, d_bar=0.1)  # the first goal is past the pole
    assert res.goals_reached >= 1 and res.duty_cycle > 0 and res.min_barrier > 0
