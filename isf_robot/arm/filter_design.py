"""The intermittent filter's hand-over and predictive off trigger, designed from the scene.

A scene whose ``[filter]`` table does not name ``blend`` or ``horizon`` (and a run that does not pass
them) gets the values below, so that the intermittent filter does not chatter on an arm nobody has
tuned. Both come from numbers the scene already states:

* **Hand-over** ``blend = max_joint_speed / max_joint_acc``: the time the nominal controller itself
  takes to go from rest to its speed cap under its own rate limit (``[gains]``). A switch hands the
  command over no faster than the nominal is allowed to change it, so the low-level tracker sees no
  step it would not see from the nominal, and the tracking error stays within what ``d_bar`` was
  calibrated on. (Panda scenes: 1.5 / 10 = 0.15 s; the UR5e scene: 0.5 / 10 = 0.05 s.)
* **Predictive off trigger** ``horizon = CHATTER_OFF_S + predict_every * period``
  (:func:`isf_robot.core.chatter.horizon_for`, with the scene's ``[control] period``): the filter
  turns off only when the nominal, rolled forward this long on the reduced model, keeps every
  ``Xi_on > 0`` (at the torque level: the torque nominal's closed loop and the ``psi`` rows,
  :class:`~isf_robot.arm.torque_rollout.TorqueRollout`). An off period shorter than the horizon then needs
  the arm to leave the rollout, which is what ``d_bar`` bounds. The horizon covers the shortest off period
  that is not chatter (:data:`~isf_robot.core.metrics.CHATTER_OFF_S`, 0.25 s) and the control steps between two
  rollouts, and no more (a longer one holds the filter on where it pushes far pairs; see
  :func:`~isf_robot.core.chatter.horizon_for`). Every shipped one-arm scene: 0.25 + 5 x 0.002 = 0.26 s.

A scene with several arms (``[[arm]]`` tables) gets no predictive off trigger by design: its team filters
switch off only after the off condition held for a while (:class:`isf_robot.core.team.OffHold`), and the
two together made the command jump between control steps, far beyond ``d_bar`` (RESULTS.md, "Arms sharing
a workspace"). An explicit horizon still applies.

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


def designed_options(config: SceneConfig, spec: FilterSpec) -> dict[str, float]:
    """``blend`` and ``horizon`` for each of the two that ``spec`` leaves to the design (``None``)."""
    out: dict[str, float] = {}
    if spec.blend is None:
        out["blend"] = designed_blend(config)
    if spec.horizon is None:  # (a team of arms: none; its filters are held on by the team's off hold instead)
        out["horizon"] = 0.0 if config.arms else horizon_for(spec.predict_every, config.control.period)
    return out


def with_design(config: SceneConfig, spec: FilterSpec | None = None) -> FilterSpec:
    """``spec`` (default: the scene's ``[filter]``) with what it leaves to the design filled in."""
    spec = config.filter if spec is None else spec
    return spec.replace(**designed_options(config, spec))
