"""The intermittent filter's designed hand-over and predictive horizon (isf_robot.arm.filter_design).

A scene that does not name ``blend``/``horizon`` gets them from its ``[gains]`` and ``[control]``; one
that names them (0 included) keeps its own; a run's arguments win over both. ``check`` prints the
values and flags a chatter risk.
"""

from __future__ import annotations

import mujoco
import pytest

from isf_robot.arm import build_scene
from isf_robot.arm.actuation import servo_lead
from isf_robot.arm.diagnostics import filter_findings
from isf_robot.arm.filter_design import designed_blend, designed_options
from isf_robot.arm.params import resolve_params
from isf_robot.cli import main
from isf_robot.core import FilterSpec
from isf_robot.core.metrics import CHATTER_OFF_S

# Two joints, a wall in reach and one goal: the smallest scene the design reads.
ARM = """
<mujoco>
  <option timestep="0.001"/>
  <worldbody>
    <body name="base">
      <body name="l1">
        <joint name="j1" axis="0 0 1" range="-3 3"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <body name="l2" pos="0.3 0 0">
          <joint name="j2" axis="0 0 1" range="-3 3"/>
          <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.03"/>
          <site name="tip" pos="0.25 0 0"/>
        </body>
      </body>
    </body>
    <body name="obstacles"><geom name="wall" type="box" pos="0.35 0.35 0" size="0.05 0.05 0.1"/></body>
    <site name="goal_a" pos="0.4 -0.2 0"/>
  </worldbody>
  <actuator>
    <velocity joint="j1" kv="20"/><velocity joint="j2" kv="20"/>
  </actuator>
</mujoco>
"""


def _scene(gains: dict | None = None, filt: dict | None = None, period: float = 0.004):  # type: ignore[no-untyped-def]
    cfg = {"robot": {"subtree": "base", "ee_site": "tip"}, "obstacles": {"bodies": ["obstacles"]},
           "task": {"goals": [{"site": "goal_a"}]}, "gains": gains or {}, "control": {"period": period},
           "filter": {"d_bar": 0.05, **(filt or {})}}
    return build_scene(mujoco.MjModel.from_xml_string(ARM), cfg)


def test_blend_and_horizon_come_from_the_gains_and_the_period() -> None:
    sc = _scene({"max_joint_speed": 1.2, "max_joint_acc": 8.0}, period=0.004)
    p = resolve_params(sc)
    assert p.blend == pytest.approx(1.2 / 8.0)
    # the chatter threshold and the five control steps between two rollouts
    assert p.horizon == pytest.approx(CHATTER_OFF_S + 5 * 0.004)
    assert designed_blend(sc.config) == pytest.approx(0.15)
    # predict_every enters the horizon
    assert resolve_params(sc, predict_every=20).horizon == pytest.approx(CHATTER_OFF_S + 20 * 0.004)
    # the run records what it used
    info = p.as_info()
    assert info["blend"] == pytest.approx(0.15) and info["horizon"] == pytest.approx(0.27)


def test_a_scene_or_a_run_that_names_them_keeps_its_own() -> None:
    sc = _scene({"max_joint_speed": 1.2, "max_joint_acc": 8.0}, {"blend": 0.0})
    p = resolve_params(sc)
    assert p.blend == 0.0  # explicit 0: no hand-over
    assert p.horizon == pytest.approx(CHATTER_OFF_S + 5 * 0.004)
    assert resolve_params(sc, horizon=0.0).horizon == 0.0
    assert resolve_params(sc, blend=0.3, horizon=0.7).blend == 0.3
    sc2 = _scene({"max_joint_speed": 1.2, "max_joint_acc": 8.0}, {"horizon": 0.5})
    assert resolve_params(sc2).horizon == 0.5 and resolve_params(sc2).blend == pytest.approx(0.15)
    # the core's own default leaves both to the adapter; alone, the core filter takes no hand-over
    assert FilterSpec().blend is None and FilterSpec().horizon is None
    assert FilterSpec().intermittent_kwargs()["blend"] == 0.0
    assert designed_options(sc.config, FilterSpec(blend=0.1, horizon=0.2)) == {}


def test_check_prints_the_design_and_flags_an_unguarded_scene(capsys, tmp_path) -> None:  # type: ignore[no-untyped-def]
    assert filter_findings(_scene()) == []  # the design guards itself
    risky = filter_findings(_scene(filt={"horizon": 0.1}))
    assert [f.code for f in risky] == ["chatter-risk"]
    # 0.25 + 5 x 0.004 = 0.27, rounded up to 0.05
    assert "horizon = 0.3 (--horizon 0.3)" in risky[0].message
    assert filter_findings(_scene(filt={"horizon": 0.0, "min_off": 0.3})) == []  # a designed margin guards too
    assert main(["check", "--scene", "panda_pole", "--no-calibration"]) == 0
    out = capsys.readouterr().out
    assert "hand-over blend = 0.15 s, predictive horizon = 0.26 s" in out and "designed from [gains]" in out


def test_run_and_compare_report_chatter_with_the_fix(capsys) -> None:  # type: ignore[no-untyped-def]
    plain = ["--scene", "planar", "--duration", "3", "--d-bar", "0.05", "--blend", "0", "--horizon", "0"]
    assert main(["run", "--filter", "isf", *plain]) == 0
    err = capsys.readouterr().err
    line = next(x for x in err.splitlines() if x.startswith("warning: chatter:"))
    assert "off periods under 0.25 s" in line and "turn on the predictive off trigger: horizon = 0.3" in line
    assert main(["compare", "--filters", "isf", "cbf", "--episodes", "1", "--quiet", *plain]) == 0
    out = capsys.readouterr().out
    assert "offs < 0.25 s" in out and "chatter: isf in 1 of 1 episodes" in out
    assert "chatter: cbf" not in out  # the standard filter has no off periods to guard


# The same two joints written the way vendors ship servo arms: <position> servos (kp, kv, forcerange from a
# default class), joint armature and friction, a convex-mesh obstacle.
SERVO_ARM = """
<mujoco>
  <compiler angle="radian"/>
  <option timestep="0.001"/>
  <default><joint armature="0.05" frictionloss="0.2" DAMPING/><position kp="300" kv="45" forcerange="-40 40" GEAR/></default>
  <asset><mesh name="wall" vertex="0.3 0.3 -0.1 0.4 0.3 -0.1 0.3 0.4 -0.1 0.4 0.4 -0.1 0.3 0.3 0.1 0.4 0.3 0.1
                                    0.3 0.4 0.1 0.4 0.4 0.1"/></asset>
  <worldbody>
    <body name="base">
      <body name="l1">
        <joint name="j1" axis="0 0 1" range="-3 3"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <body name="l2" pos="0.3 0 0">
          <joint name="j2" axis="0 0 1" range="-3 3"/>
          <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.03"/>
          <site name="tip" pos="0.25 0 0"/>
        </body>
      </body>
    </body>
    <body name="obstacles"><geom name="wall" type="mesh" mesh="wall"/></body>
    <site name="goal_a" pos="0.2 0.45 0"/>
  </worldbody>
  <actuator><position joint="j1"/><ACT2/></actuator>
</mujoco>
"""


def _servo_scene(damping: float = 0.0, gear: float = 1.0, act2: str = '<position joint="j2" kp="300" kv="30"/>',
                 gains: dict | None = None, filt: dict | None = None):  # type: ignore[no-untyped-def]
    xml = (SERVO_ARM.replace("DAMPING", f'damping="{damping:g}"').replace("GEAR", f'gear="{gear:g}"')
           .replace("<ACT2/>", act2))
    cfg = {"robot": {"subtree": "base", "ee_site": "tip", "home": [0.0, 0.3]}, "obstacles": {"bodies": ["obstacles"]},
           "task": {"goals": [{"site": "goal_a"}]}, "gains": gains or {"max_joint_speed": 0.3},
           "control": {"period": 0.002}, "filter": {"d_bar": 0.01, **(filt or {})}}
    return build_scene(mujoco.MjModel.from_xml_string(xml), cfg)


def test_the_hand_over_is_no_shorter_than_the_slowest_position_servo() -> None:
    # undamped servos: the lead is kv / kp, the slowest joint's (45 / 300 = 0.15 s against 30 / 300 = 0.1 s),
    # above the nominal's ramp time 0.3 / 10 = 0.03 s
    sc = _servo_scene()
    assert servo_lead(sc) == pytest.approx(0.15)
    assert resolve_params(sc).blend == pytest.approx(0.15)
    # the tracker's lead is the same number: (gear^2 kv + damping) / (gear^2 kp) per joint
    from isf_robot.arm.actuation import ServoTracker, arm_actuators

    tr = ServoTracker(sc, arm_actuators(sc))
    assert servo_lead(sc) == pytest.approx(float(tr.lead.max()))
    # the torque level drives the joints by torque with the actuators off: the nominal's ramp time alone
    from isf_robot.arm.torque_sim import resolve_torque_params

    assert resolve_torque_params(sc, d_bar=1.0).blend == pytest.approx(0.3 / 10.0)
    # joint damping adds to kv; a gear enters squared in both
    assert servo_lead(_servo_scene(damping=3.0)) == pytest.approx((45 + 3) / 300)
    assert servo_lead(_servo_scene(damping=3.0, gear=2.0)) == pytest.approx((4 * 45 + 3) / (4 * 300))
    # a nominal that ramps slower than the servos: its own ramp time stays the hand-over
    slow = _servo_scene(gains={"max_joint_speed": 2.0})
    assert resolve_params(slow).blend == pytest.approx(2.0 / 10.0)
    # a torque motor or a velocity servo has no lead (only the position servo on j1 counts)
    for act2 in ('<motor joint="j2" ctrlrange="-10 10"/>', '<velocity joint="j2" kv="20"/>'):
        assert servo_lead(_servo_scene(act2=act2)) == pytest.approx(0.15)
    assert servo_lead(_scene()) == 0.0  # velocity servos only
    # a scene or a run that names blend keeps its own
    assert resolve_params(_servo_scene(filt={"blend": 0.05})).blend == 0.05
    assert resolve_params(sc, blend=0.0).blend == 0.0


def test_check_says_when_the_servos_set_the_hand_over(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    xml = SERVO_ARM.replace(" DAMPING", "").replace(" GEAR", "").replace("<ACT2/>", '<position joint="j2"/>')
    (tmp_path / "arm.xml").write_text(xml)
    (tmp_path / "arm.toml").write_text(
        '[scene]\nname = "servo_arm"\nmodel = "arm.xml"\n[robot]\nsubtree = "base"\nee_site = "tip"\n'
        'home = [0.0, 0.3]\n[obstacles]\nbodies = ["obstacles"]\n[[task.goals]]\nsite = "goal_a"\n'
        '[gains]\nmax_joint_speed = 0.3\n[control]\nperiod = 0.002\n')
    assert main(["check", "--model", str(tmp_path / "arm.xml"), "--config", str(tmp_path / "arm.toml"),
                 "--no-calibration"]) == 0
    out = capsys.readouterr().out
    assert "hand-over blend = 0.15 s" in out and "the position servos' time constant" in out
