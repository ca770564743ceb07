"""The intermittent filter's hand-over and predictive off trigger, designed from the scene.

A scene whose ``[filter]`` table does not name ``blend`` or ``horizon`` (and a run that does not pass
them) gets the values below, so that the intermittent filter does not chatter on an arm nobody has
tuned. Both come from numbers the scene already states:

* **Hand-over** ``blend = max(max_joint_speed / max_joint_acc, servo lead)``. The first term is the
  time the nominal controller itself takes to go from rest to its speed cap under its own rate limit
  (``[gains]``): a switch hands the command over no faster than the nominal is allowed to change it,
  so the low-level tracker sees no step it would not see from the nominal, and the tracking error
  stays within what ``d_bar`` was calibrated on. The second
  (:func:`~isf_robot.arm.actuation.servo_lead`) is the time constant of the slowest position servo of
  the arm, ``(gear^2 kv + damping) / (gear^2 kp)``, the lead the servo tracker gives its target
  (:class:`~isf_robot.arm.actuation.ServoTracker`); 0 for torque motors and velocity servos. A
  hand-over shorter than it changes the servo's target faster than the servo follows, and the tracking
  error leaves ``d_bar``: on the vendor-style arm
  ``benchmarks/vendor_arms/vendor_panda_position`` (undamped servos, kv / kp = 0.15 s, max_joint_speed
  0.17), over 20 seeds, a 0.017 s hand-over gave a tracking error q99 of 0.035 rad/s against ``d_bar``
  0.015 in every episode and off periods down to 0.098 s; 0.15 s keeps it within ``d_bar`` in every
  episode (worst 0.013) and every off period at 0.356 s or more (RESULTS.md).
  (Panda scenes: 1.5 / 10 = 0.15 s, panda_servo's lead 0.10 s below it; the UR5e scene: its servos'
  lead 400 / 2000 = 0.2 s above 0.5 / 10 = 0.05 s.)
* **Predictive off trigger** ``horizon = CHATTER_OFF_S + predict_every * period``
  (:func:`isf_robot.core.chatter.horizon_for`, with the scene's ``[control] period``): the filter
  turns off only when the nominal, rolled forward this long on the reduced model, keeps every
  ``Xi_on > 0`` (at the torque level: the torque nominal's closed loop and the ``psi`` rows,
  :class:`~isf_robot.arm.torque_rollout.TorqueRollout`). An off period shorter than the horizon then needs
  the arm to leave the rollout, which is what ``d_bar`` bounds. The horizon covers the shortest off period
  that is not chatter (:data:`~isf_robot.core.metrics.CHATTER_OFF_S`, 0.25 s) and the control steps between two
  rollouts, and no more (a longer one holds the filter on where it pushes far pairs; see
  :func:`~isf_robot.core.chatter.horizon_for`). Every shipped one-arm scene: 0.25 + 5 x 0.002 = 0.26 s.

A scene with several arms (``[[arm]]`` tables) gets the same horizon: its team filters also switch off
only after the off condition held for a while (``off_hold``, 0.1 s, :data:`isf_robot.arm.multi_arm.OFF_HOLD_S`;
one arm: none unless asked for, :class:`isf_robot.core.triggers.OnOffTrigger`), and the rollout
removes most of the short off periods the hold leaves (RESULTS.md, "Arms sharing a workspace").

An explicit value (``blend = 0``, ``--horizon 0``) turns either off. ``isf-robot run`` and ``compare``
report chatter (off periods under 0.25 s) with the change that would fix it
(:func:`isf_robot.core.chatter.chatter_advice`).
"""

from __future__ import annotations

from isf_robot.core import FilterSpec
from isf_robot.core.chatter import horizon_for

from .config_schema import SceneConfig

__all__ = ["designed_blend", "designed_kd", "designed_options", "with_design"]


def designed_blend(config: SceneConfig) -> float:
    """Hand-over time [s]: the nominal's time from rest to its joint-speed cap at its rate limit."""
    g = config.gains
    return g.max_joint_speed / g.max_joint_acc


def designed_kd(config: SceneConfig) -> float:
    """The torque nominal's velocity gain [1/s]: ``max_joint_acc / max_joint_speed`` (``1 / designed_blend``).

    Computed torque asks ``q_ddot = kd (v_ref - q_dot) + a_ref``: with this gain a velocity error up to the
    nominal's speed cap is corrected at no more than the nominal's own acceleration cap, so when the
    intermittent filter lets go the nominal torque pulls no harder than the velocity level's nominal may
    change its command (Panda scenes 10 / 1.5 = 6.7 /s, the UR5e scene 10 / 0.5 = 20 /s; the first pass's
    40 /s made ``Xi_on`` of the nominal fall fast after every off switch).
    """
    return 1.0 / designed_blend(config)


def designed_options(config: SceneConfig, spec: FilterSpec, lead: float = 0.0) -> dict[str, float]:
    """``blend`` and ``horizon`` for each of the two that ``spec`` leaves to the design (``None``).

    ``lead``: the arm's :func:`~isf_robot.arm.actuation.servo_lead` [s] (the hand-over is no shorter).
    """
    out: dict[str, float] = {}
    if spec.blend is None:
        out["blend"] = max(designed_blend(config), float(lead))
    if spec.horizon is None:
        out["horizon"] = horizon_for(spec.predict_every, config.control.period)
    return out


def with_design(config: SceneConfig, spec: FilterSpec | None = None, lead: float = 0.0) -> FilterSpec:
    """``spec`` (default: the scene's ``[filter]``) with what it leaves to the design filled in.

    ``lead``: the arm's :func:`~isf_robot.arm.actuation.servo_lead` [s] (0: no position servos).
    """
    spec = config.filter if spec is None else spec
    return spec.replace(**designed_options(config, spec, lead))
