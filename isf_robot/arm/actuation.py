"""Turning the filter's joint-velocity command into what the model's actuators take.

The safety filter commands a joint velocity ``u`` for ``q_dot = u + d``; the robot's actuators
take torques, position targets or velocity targets. The kind is read from the compiled model,
per actuator (``actuator_gaintype``/``biastype``/``gainprm``/``biasprm``); the user's MJCF is
never edited:

* **torque** (``<motor>``: fixed gain, no bias): computed-torque tracking of ``u``
  (:class:`~isf_robot.arm.lowlevel.VelocityTracker`, unchanged);
* **position** servo (``<position kp kv>``, or ``<general>`` with ``gainprm[0] = kp`` and
  ``biasprm = [0, -kp, -kv]``, Menagerie's way of writing the same servo): the velocity
  command is integrated into the position target at every physics step, as arm controllers
  and IK libraries do (:class:`ServoTracker`);
* **velocity** servo (``<velocity kv>``: ``gainprm[0] = kv``, ``biasprm = [0, 0, -kv]``):
  ``ctrl = u`` (times the gear).

The joint must be driven through a joint transmission (``joint="..."``); activation dynamics
``filter``/``filterexact`` (a first-order lag on ``ctrl``, MuJoCo's ``timeconst``) are allowed.
:func:`make_actuation` picks the adapter; every adapter has ``u``, ``reset``, ``set_command``,
``apply`` (between ``mj_step1`` and ``mj_step2``) and ``saturated`` (which arm actuators are
at their force or torque limit).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Protocol

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError

from .lowlevel import VelocityTracker, friction_feedforward
from .scene import Scene
from .tracking_law import tracking_error

__all__ = ["ActuatorInfo", "actuator_info", "Actuation", "ServoTracker", "make_actuation", "tracking_step", "KINDS",
           "speed_bound", "servo_lead"]

KINDS = ("torque", "position", "velocity")
"""Actuator kinds the adapters support."""

_REL = 1e-9


class Actuation(Protocol):
    """What the simulation loop and the calibration need of a low-level controller."""

    u: np.ndarray
    kinds: tuple[str, ...]

    def reset(self, data: mujoco.MjData) -> None: ...
    def set_command(self, u: np.ndarray, period: float | None = None) -> None: ...
    def apply(self, data: mujoco.MjData) -> None: ...
    def saturated(self, data: mujoco.MjData) -> np.ndarray: ...


class ActuatorInfo:
    """What one arm actuator is, read from the compiled model.

    Attributes:
        actuator: Actuator id.
        kind: ``"torque"``, ``"position"`` or ``"velocity"``.
        gear: Transmission gear (joint torque = gear * actuator force).
        kp: Position gain [N m/rad] (position servos), else 0.
        kv: Velocity gain [N m s/rad] of the servo's bias (position and velocity servos), else 0.
        force_limit: Largest joint torque the actuator can give [N m] (``forcerange`` times the
            gear; for a motor also ``ctrlrange`` times gain and gear); ``inf`` when unlimited.

    """

    __slots__ = ("actuator", "kind", "gear", "kp", "kv", "force_limit")

    def __init__(self, actuator: int, kind: str, gear: float, kp: float, kv: float,
                 force_limit: float) -> None:
        self.actuator, self.kind, self.gear = actuator, kind, gear
        self.kp, self.kv, self.force_limit = kp, kv, force_limit

    def __repr__(self) -> str:
        return (f"ActuatorInfo(actuator={self.actuator}, kind={self.kind!r}, gear={self.gear:g}, "
                f"kp={self.kp:g}, kv={self.kv:g}, force_limit={self.force_limit:g})")


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= _REL * max(1.0, abs(a), abs(b))


def actuator_info(model: mujoco.MjModel, actuator: int, joint_name: str = "") -> ActuatorInfo:
    """Classify one actuator (see the module docstring).

    Raises:
        ConfigError: The actuator is none of the supported kinds; the message says what the
            supported ones look like in MJCF.

    """
    a = int(actuator)
    label = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"actuator #{a}")
    where = f"actuator {label!r}" + (f" of joint {joint_name!r}" if joint_name else "")
    supported = ("supported: <motor> (torque), <position> or <general> with gainprm=\"kp\" "
                 "biasprm=\"0 -kp -kv\" (position servo), <velocity> (velocity servo)")
    if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT):
        raise ConfigError(f"{where} does not drive a joint directly (transmission type "
                          f"{mujoco.mjtTrn(int(model.actuator_trntype[a])).name}); {supported}")
    dyn = int(model.actuator_dyntype[a])
    if dyn not in (int(mujoco.mjtDyn.mjDYN_NONE), int(mujoco.mjtDyn.mjDYN_FILTER),
                   int(mujoco.mjtDyn.mjDYN_FILTEREXACT)):
        raise ConfigError(f"{where} has activation dynamics {mujoco.mjtDyn(dyn).name} "
                          f"(integrator, muscle and user dynamics are not supported); {supported}")
    if int(model.actuator_gaintype[a]) != int(mujoco.mjtGain.mjGAIN_FIXED):
        raise ConfigError(f"{where} has a non-fixed gain; {supported}")
    gear = float(model.actuator_gear[a, 0])
    g = float(model.actuator_gainprm[a, 0])
    if gear == 0.0 or g == 0.0:
        raise ConfigError(f"{where} has zero gain or gear; it cannot move the joint")
    b0, b1, b2 = (float(x) for x in model.actuator_biasprm[a, :3])
    bias = int(model.actuator_biastype[a])
    if bias == int(mujoco.mjtBias.mjBIAS_NONE):
        kind, kp, kv = "torque", 0.0, 0.0
    elif bias == int(mujoco.mjtBias.mjBIAS_AFFINE) and b0 == 0.0 and _close(b1, -g) and b2 <= 0:
        kind, kp, kv = "position", g, -b2 + 0.0  # + 0.0: no "-0" for a servo without kv
    elif bias == int(mujoco.mjtBias.mjBIAS_AFFINE) and b0 == 0.0 and b1 == 0.0 and _close(b2, -g):
        kind, kp, kv = "velocity", 0.0, g
    else:
        raise ConfigError(f"{where} has gainprm[0] = {g:g} and biasprm = [{b0:g}, {b1:g}, {b2:g}]: "
                          f"neither a motor nor a position or velocity servo; {supported}")
    limit = np.inf
    if model.actuator_forcelimited[a]:
        limit = float(np.max(np.abs(model.actuator_forcerange[a]))) * abs(gear)
    if kind == "torque" and model.actuator_ctrllimited[a]:
        limit = min(limit, float(np.max(np.abs(model.actuator_ctrlrange[a]))) * abs(g * gear))
    return ActuatorInfo(a, kind, gear, kp, kv, limit)


def speed_bound(info: ActuatorInfo | None, force_limit: float, damping: float, gravity: float) -> tuple[float, str]:
    """The joint speed an actuator allows [rad/s or m/s], and the rule that gave it.

    * joint damping ``b > 0``: the steady speed ``(F - |g|) / b`` at which the damping takes the
      force ``F`` the actuator has left after gravity ``|g|`` at home (rule ``"damping"``);
    * a position or velocity servo on a joint without damping: nothing in the model bounds the
      steady speed (the tracker's velocity lead cancels the servo's own damping ``kv``), so the
      bound is the largest velocity step the servo answers within its force range,
      ``(F - |g|) / (gear^2 kv)``: a start or a stop from a faster command (a safety filter brakes
      in one control step) saturates it (rule ``"servo kv"``);
    * otherwise ``inf`` (rule ``"none"``).

    ``F = inf`` gives ``inf``; an actuator that cannot hold gravity gives 0.
    """
    left = max(force_limit - abs(gravity), 0.0)
    if not math.isfinite(force_limit):
        return math.inf, "none"
    if damping > 0:
        return left / damping, "damping"
    if info is not None and info.kind in ("position", "velocity") and info.kv > 0:
        return left / (info.gear ** 2 * info.kv), "servo kv"
    return math.inf, "none"


def arm_actuators(scene: Scene) -> list[ActuatorInfo]:
    """The actuator of every arm joint, classified, in joint order.

    Raises:
        ConfigError: An arm joint has no actuator, or one is of an unsupported kind.

    """
    missing = [scene.joint_names[i] for i, a in enumerate(scene.actuator_ids) if a < 0]
    if missing:
        raise ConfigError(f"arm joints {missing} have no actuator (a <motor>, <position>, "
                          "<velocity> or <general> with joint=\"...\")")
    return [actuator_info(scene.model, int(a), scene.joint_names[i])
            for i, a in enumerate(scene.actuator_ids)]


class ServoTracker:
    """Velocity command to position and velocity servos, one per arm joint.

    Position servo of joint i (gear g, gain kp, servo damping kv, joint damping b)::

        q_ref  <- q + clip(q_ref + u dt - q, +-max_ref_error)     every physics step
        tau_ff =  M_ii a_ff + c_i(q, q_dot)                        (feedforward torque [N m])
        target =  clip(q_ref + lead u + tau_ff / (g^2 kp), joint range)
        ctrl   =  clip(g target, ctrlrange)                        lead = (g^2 kv + b) / (g^2 kp)

    ``tau_ff`` also carries the model's known joint friction, ``f tanh(u / v_s)``
    (:func:`~isf_robot.arm.lowlevel.friction_feedforward`, ``f`` = ``dof_frictionloss``). The lead is
    a velocity feedforward through the target: at ``q = q_ref`` and
    ``q_dot = u`` the servo's torque ``g kp (ctrl - g q) - g^2 kv q_dot`` then equals the joint
    damping ``b u``, so a constant command is followed without the lag ``lead u`` a plain
    integrated target would have. ``tau_ff`` feeds the torque the motion needs through the
    target as well: the acceleration ``a_ff = (u_k - u_{k-1}) / T`` after a change of the
    command (held for one control period T, as in
    :class:`~isf_robot.arm.lowlevel.VelocityTracker`) times the joint's diagonal mass-matrix
    entry, and the bias forces ``c = qfrc_bias`` (gravity, Coriolis). The joint then behaves as a
    PD loop on the remaining velocity error (stiffness ``g^2 kp``, damping ``g^2 kv + b``).
    The clip keeps a blocked arm from winding the target up.

    Velocity servo: ``ctrl = clip(g (u + tau_f / (g^2 kv)), ctrlrange)``, ``tau_f`` the friction
    feed-forward (0 without friction).

    Args:
        scene: The scene.
        infos: The arm actuators (:func:`arm_actuators`), position or velocity servos only.
        max_ref_error: Clip on ``q_ref - q`` [rad].
        feedforward: Use the lead and ``tau_ff`` (``False``: a plain integrated target).
        friction: Feed the model's joint friction forward (independent of ``feedforward``).

    """

    def __init__(self, scene: Scene, infos: Sequence[ActuatorInfo], *, max_ref_error: float = 0.05,
                 feedforward: bool = True, friction: bool = True) -> None:
        model = scene.model
        if any(i.kind not in ("position", "velocity") for i in infos):
            raise ConfigError("ServoTracker drives position and velocity servos only")
        if not max_ref_error > 0:
            raise ConfigError(f"max_ref_error must be > 0 [rad], got {max_ref_error}")
        self.n = scene.n_joints
        self.kinds = tuple(i.kind for i in infos)
        self.max_ref_error = float(max_ref_error)
        self.feedforward = bool(feedforward)
        self._act = np.array([i.actuator for i in infos], dtype=np.int64)
        self._qadr = np.asarray(scene.qpos_adr)
        self._dof = np.asarray(scene.dof_adr)
        self._pos = np.array([k == "position" for k in self.kinds])
        gear = np.array([i.gear for i in infos])
        self._gear = gear
        damping = model.dof_damping[self._dof]
        kp = np.array([i.kp for i in infos])
        kv = np.array([i.kv for i in infos])
        with np.errstate(divide="ignore", invalid="ignore"):
            lead = np.where(self._pos, servo_time_constant(gear, kp, kv, damping), 0.0)
        self.lead = lead if self.feedforward else np.zeros(self.n)
        with np.errstate(divide="ignore"):
            self._inv_k = np.where(self._pos & self.feedforward, 1.0 / (gear ** 2 * kp), 0.0)
            # friction enters the position target through 1 / (g^2 kp), the velocity target through 1 / (g^2 kv)
            self._inv_f = np.where(self._pos, 1.0 / (gear ** 2 * kp), 1.0 / (gear ** 2 * kv))
        fric = model.dof_frictionloss[self._dof].astype(float)
        self.friction = fric if friction else np.zeros(self.n)
        self._fric = bool(friction and np.any(fric > 0))
        self._mdiag = (model.M_rowadr + model.M_rownnz - 1)[self._dof]
        self.a_ff = np.zeros(self.n)
        rng = scene.joint_range
        self._qlo, self._qhi = rng[:, 0], rng[:, 1]
        limited = model.actuator_ctrllimited[self._act].astype(bool)
        crng = model.actuator_ctrlrange[self._act]
        self._clo = np.where(limited, crng[:, 0], -np.inf)
        self._chi = np.where(limited, crng[:, 1], np.inf)
        flimited = model.actuator_forcelimited[self._act].astype(bool)
        frng = model.actuator_forcerange[self._act]
        self._flo = np.where(flimited, frng[:, 0], -np.inf)
        self._fhi = np.where(flimited, frng[:, 1], np.inf)
        self._dt = float(model.opt.timestep)
        self.q_ref = np.zeros(self.n)
        self.u = np.zeros(self.n)

    def reset(self, data: mujoco.MjData) -> None:
        """Set the target to the current joint positions and the command to the current velocity."""
        self.q_ref[:] = data.qpos[self._qadr]
        self.u[:] = data.qvel[self._dof]
        self.a_ff[:] = 0.0

    def set_command(self, u: np.ndarray, period: float | None = None) -> None:
        """Hold the commanded joint velocity ``u`` [rad/s], shape (n,), until the next call.

        With ``period`` (the time to the next call [s]) the acceleration ``(u - u_previous) /
        period`` is fed forward until then.
        """
        if self.feedforward and period is not None and period > 0:
            self.a_ff[:] = (np.asarray(u) - self.u) / period
        else:
            self.a_ff[:] = 0.0
        self.u[:] = u

    def apply(self, data: mujoco.MjData) -> None:
        """Write ``data.ctrl`` for the current state; call between ``mj_step1`` and ``mj_step2``."""
        q = data.qpos[self._qadr]
        err = np.clip(self.q_ref + self.u * self._dt - q, -self.max_ref_error, self.max_ref_error)
        self.q_ref[:] = q + err
        tau = data.M[self._mdiag] * self.a_ff + data.qfrc_bias[self._dof]
        shift = tau * self._inv_k
        if self._fric:
            shift += friction_feedforward(self.friction, self.u) * self._inv_f
        target = np.clip(self.q_ref + self.lead * self.u + np.where(self._pos, shift, 0.0), self._qlo, self._qhi)
        vel = self.u + np.where(self._pos, 0.0, shift) if self._fric else self.u
        ctrl = np.where(self._pos, target, vel) * self._gear
        data.ctrl[self._act] = np.clip(ctrl, self._clo, self._chi)

    def saturated(self, data: mujoco.MjData) -> np.ndarray:
        """Which arm actuators are at their force limit (after ``mj_step2``), shape (n,)."""
        f = data.actuator_force[self._act]
        tol = 1e-9 * np.maximum(1.0, np.abs(f))
        return (f >= self._fhi - tol) | (f <= self._flo + tol)


def _torque_saturated(tracker: VelocityTracker, data: mujoco.MjData) -> np.ndarray:
    c = data.ctrl[tracker._act]
    tol = 1e-9 * np.maximum(1.0, np.abs(c))
    return np.asarray((c >= tracker._hi - tol) | (c <= tracker._lo + tol))


class TorqueTracker(VelocityTracker):
    """:class:`VelocityTracker` (computed torque) with the adapter's ``kinds`` and ``saturated``.

    Its control law is the parent's, unchanged (the same numbers to the bit).
    """

    def __init__(self, scene: Scene, *args: object, **kwargs: object) -> None:
        super().__init__(scene, *args, **kwargs)  # type: ignore[arg-type]
        self.kinds = ("torque",) * self.n

    def saturated(self, data: mujoco.MjData) -> np.ndarray:
        """Which arm motors are at their ``ctrlrange`` limit, shape (n,)."""
        return _torque_saturated(self, data)


def make_actuation(scene: Scene, **kwargs: object) -> TorqueTracker | ServoTracker:
    """The low-level controller for the scene's actuators (see the module docstring).

    Keyword arguments go to :class:`TorqueTracker` (all motors) or :class:`ServoTracker` (all
    servos).

    Raises:
        ConfigError: An arm joint has no actuator, an actuator is of an unsupported kind, or
            motors and servos are mixed (computed torque needs every arm joint).

    """
    infos = arm_actuators(scene)
    kinds = {i.kind for i in infos}
    if kinds == {"torque"}:
        return TorqueTracker(scene, **kwargs)
    if "torque" in kinds:
        mixed = {scene.joint_names[k]: i.kind for k, i in enumerate(infos)}
        raise ConfigError(f"arm actuators mix motors and servos ({mixed}); use one kind for "
                          "every arm joint (computed torque needs all of them)")
    return ServoTracker(scene, infos, **kwargs)  # type: ignore[arg-type]


def tracking_step(tracker: Actuation, dof_adr: np.ndarray) -> Callable[[mujoco.MjData, np.ndarray, float], float]:
    """``(data, u, period) -> |q_dot - u_held|``: the tracking error, then ``set_command`` and ``apply``.

    The tracker's own ``command`` where it has one (:meth:`VelocityTracker.command`: one compiled call),
    else the three calls in that order (``dof_adr``: the arm's dofs, for ``q_dot``).
    """
    command = getattr(tracker, "command", None)
    if command is not None:
        return command  # type: ignore[no-any-return]

    def step(data: mujoco.MjData, u: np.ndarray, period: float) -> float:
        err = float(tracking_error(data.qvel[dof_adr].tolist(), tracker.u.tolist()))
        tracker.set_command(u, period)
        tracker.apply(data)
        return err

    return step


def servo_time_constant(gear, kp, kv, damping):  # noqa: ANN001, ANN201 (floats or arrays)
    """A position servo's time constant ``(gear^2 kv + damping) / (gear^2 kp)`` [s]: the lead its target needs."""
    g2 = gear ** 2
    return (g2 * kv + damping) / (g2 * kp)


def servo_lead(scene: Scene) -> float:
    """The time constant of the arm's slowest position servo [s]: ``(gear^2 kv + damping) / (gear^2 kp)``.

    The largest over the arm joints driven by a position servo (``<position>``, or ``<general>`` with
    ``biasprm = "0 -kp -kv"``) of the lead :class:`~isf_robot.arm.actuation.ServoTracker` gives the servo's
    target; 0 when no joint has one (torque motors, velocity servos, an actuator of no supported kind).
    """
    m, out = scene.model, 0.0
    for i, a in enumerate(scene.actuator_ids):
        if a < 0:
            continue
        try:
            info = actuator_info(m, int(a))
        except ConfigError:
            continue
        if info.kind == "position" and info.kp > 0:
            out = max(out, float(servo_time_constant(info.gear, info.kp, info.kv, m.dof_damping[scene.dof_adr[i]])))
    return out
