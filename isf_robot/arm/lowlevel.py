"""Low-level joint-velocity tracking at the physics rate.

The safety filter commands a joint velocity ``u`` for the reduced-order model
``q_dot = u + d``; MuJoCo simulates the full dynamics, and this controller turns ``u`` into
actuator torques at every physics step (computed torque on a velocity reference)::

    q_ref <- q_ref + u dt                                  (integrated reference [rad])
    a     =  a_ff + kd (u - q_dot) + kp clip(q_ref - q, +-e_max)   (desired acc. [rad/s^2])
    tau   =  M(q) a + c(q, q_dot) - f_passive(q, q_dot) + f_fric tanh(u / v_s)   (torque [Nm])
    ctrl  =  clip(tau / gear, ctrlrange)

``M a`` uses the mass matrix through ``mj_mulM``; ``c`` is ``qfrc_bias`` (Coriolis,
centrifugal, gravity) and ``f_passive`` ``qfrc_passive`` (joint damping, springs), all
computed by ``mj_step1`` for the current state. With ``kp = w^2`` and ``kd = 2 zeta w`` the
velocity error decays like a critically damped (zeta = 1) second-order system of natural
frequency w [rad/s]. The feedforward ``a_ff = (u_k - u_{k-1}) / T`` (T the control period) is applied during the
control period that follows a change of the command, so a ramping command is tracked with
one period of lag instead of a lag of ``u_dot / kd``. The integrated reference removes the
steady-state drift of a pure velocity loop; its error is clipped so that a blocked arm (in contact) does not wind it up.
The remaining velocity error ``q_dot - u`` is the disturbance ``d`` of the reduced-order
model (its bound is measured by :mod:`isf_robot.arm.calibration`).

Joint friction: MuJoCo's ``frictionloss`` (``dof_frictionloss``, a dry friction torque up to
``f_fric`` against the motion, solved as a constraint, so absent from ``qfrc_passive``) is
known from the model and fed forward in the direction of the commanded velocity,
``f_fric tanh(u / v_s)`` (:func:`friction_feedforward`; ``v_s`` = :data:`FRICTION_SMOOTHING`):
the full friction torque once ``|u| >> v_s``, smoothly through zero, so a command at rest asks
for no torque and the friction holds the joint. Without it a joint with friction lags every
command by the friction torque over the tracking gain, and the calibrated ``d_bar`` measures
the friction instead of the tracking.

The formulas are the plain functions of :mod:`isf_robot.arm.tracking_law`; the compiled
:meth:`VelocityTracker.apply` (``_kernels_step``) calls the same ones.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, ShapeError
from isf_robot.core.jit import direct

from . import kernels
from .scene import Scene
from .tracking_law import command_feedforward, desired_acceleration, motor_ctrl, reference_error, tracking_error

_F64 = np.dtype(np.float64)

__all__ = ["VelocityTracker", "friction_feedforward", "FRICTION_SMOOTHING"]

FRICTION_SMOOTHING = 0.02
"""``v_s`` [rad/s or m/s]: the joint friction feed-forward is ``f tanh(u / v_s)`` (76% of ``f`` at ``|u| = v_s``)."""


def friction_feedforward(frictionloss: np.ndarray, u: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``frictionloss * tanh(u / FRICTION_SMOOTHING)``: the known joint friction in the direction of ``u``."""
    out = np.multiply(u, 1.0 / FRICTION_SMOOTHING, out=out)
    np.tanh(out, out=out)
    out *= frictionloss
    return out


def _per_joint(v: Sequence[float] | np.ndarray | float, n: int, label: str) -> np.ndarray:
    a = np.atleast_1d(np.asarray(v, dtype=float))
    if a.shape == (1,):
        a = np.full(n, float(a[0]))
    if a.shape != (n,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ConfigError(f"{label} must be one non-negative number or {n}, got {v!r}")
    return a


def as_slice(idx: np.ndarray) -> slice | np.ndarray:
    """A slice when the indices are contiguous and increasing (views are cheaper)."""
    if idx.size and np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size)):
        return slice(int(idx[0]), int(idx[0]) + int(idx.size))
    return idx


class VelocityTracker:
    """Computed-torque tracking of a commanded joint velocity.

    Args:
        scene: The scene (arm joints, their motor actuators).
        kp: Reference-position gain [1/s^2], one number or shape (n,); default
            ``[gains] tracking_kp``.
        kd: Velocity gain [1/s], one number or shape (n,); default ``[gains] tracking_kd``.
        max_ref_error: Clip on ``q_ref - q`` [rad].
        feedforward: Use the acceleration feedforward (needs the control period in
            :meth:`set_command`).
        jit: Use the compiled :meth:`apply` of :mod:`isf_robot.arm.kernels` when it is available
            (the same formulas, compiled; ``False``: always numpy).
        friction: Feed the model's joint friction (``dof_frictionloss``) forward (module
            docstring); an arm without friction is unaffected. With friction it is compensated
            on the numpy path (the compiled kernel has no friction term).

    Raises:
        ConfigError: An arm joint has no actuator, or its actuator is not a plain motor
            (fixed gain, no bias).

    """

    def __init__(
        self,
        scene: Scene,
        kp: Sequence[float] | np.ndarray | float | None = None,
        kd: Sequence[float] | np.ndarray | float | None = None,
        *,
        max_ref_error: float = 0.05,
        feedforward: bool = True,
        jit: bool = True,
        friction: bool = True,
    ) -> None:
        model = scene.model
        n = scene.n_joints
        gains = scene.config.gains
        self.n = n
        kp_v = _per_joint(gains.tracking_kp if kp is None else kp, n, "tracking kp")
        kd_v = _per_joint(gains.tracking_kd if kd is None else kd, n, "tracking kd")
        if not max_ref_error > 0:
            raise ConfigError(f"max_ref_error must be > 0 [rad], got {max_ref_error}")
        act = scene.actuator_ids
        missing = [scene.joint_names[i] for i in range(n) if act[i] < 0]
        if missing:
            raise ConfigError(f"arm joints {missing} have no actuator; the velocity tracker "
                              "needs one motor per arm joint")
        for i, a in enumerate(act):
            if (int(model.actuator_gaintype[a]) != int(mujoco.mjtGain.mjGAIN_FIXED)
                    or int(model.actuator_biastype[a]) != int(mujoco.mjtBias.mjBIAS_NONE)):
                raise ConfigError(f"actuator of joint {scene.joint_names[i]!r} is not a motor "
                                  "(fixed gain, no bias); the velocity tracker commands torques")
        self.model = model
        nv = int(model.nv)
        # One buffer holds the tracker's state and constants (rows of n: see _kernels_step), the
        # full-size acceleration/torque scratch and two scalars: the compiled apply reads it whole.
        self._buf = buf = np.zeros(8 * n + 2 * nv + 2)
        rows = buf[: 8 * n].reshape(8, n)
        self.u, self.q_ref, self.a_ff, self._kd, self._kp, self._inv_gain, self._lo, self._hi = rows
        self._kp[:], self._kd[:] = kp_v, kd_v
        self._gain = (model.actuator_gear[act, 0] * model.actuator_gainprm[act, 0]).copy()
        limited = model.actuator_ctrllimited[act].astype(bool)
        rng = model.actuator_ctrlrange[act]
        self._lo[:] = np.where(limited, rng[:, 0], -np.inf)
        self._hi[:] = np.where(limited, rng[:, 1], np.inf)
        self._act = as_slice(np.asarray(act))
        self._dof = as_slice(np.asarray(scene.dof_adr))
        self._qadr = as_slice(np.asarray(scene.qpos_adr))
        self._acc_full = buf[8 * n: 8 * n + nv]
        self._tau_full = buf[8 * n + nv: 8 * n + 2 * nv]
        self.feedforward = bool(feedforward)
        fric = model.dof_frictionloss[np.asarray(scene.dof_adr)].astype(float)
        self.friction = fric if friction else np.zeros(n)
        self._fric = bool(friction and np.any(fric > 0))
        self._ftmp = np.zeros(n)
        self._inv_gain[:] = 1.0 / self._gain
        self._dt = float(model.opt.timestep)
        buf[8 * n + 2 * nv] = self._dt
        self.max_ref_error = float(max_ref_error)
        self._data: mujoco.MjData | None = None
        self._views: tuple[np.ndarray, ...] | None = None
        # The compiled apply (isf_robot.arm.kernels), for contiguous joints and actuators and this
        # class's own control law (a subclass that overrides apply or set_command keeps its own).
        contiguous = all(type(x) is slice for x in (self._act, self._dof, self._qadr))
        own = type(self).apply is VelocityTracker.apply and type(self).set_command is VelocityTracker.set_command
        jit = jit and not self._fric
        k = kernels.step_kernels(n) if jit and contiguous and own and getattr(model, "_address", 0) else None
        self._kernels = k
        self._step = k["track_step"] if k is not None else None
        self._step_direct: tuple = (None, None)  # (the kernel, its code for float64 commands: command)
        self._maddr = int(getattr(model, "_address", 0))
        self._daddr = 0
        self._ptrs = np.zeros(6, dtype=np.int64)

    @property
    def kp(self) -> np.ndarray:
        """Reference-position gains [1/s^2], shape (n,) (a view of the tracker's buffer; setting copies)."""
        return self._kp

    @kp.setter
    def kp(self, value: Sequence[float] | np.ndarray | float) -> None:
        self._kp[:] = _per_joint(value, self.n, "tracking kp")

    @property
    def kd(self) -> np.ndarray:
        """Velocity gains [1/s], shape (n,) (a view of the tracker's buffer; setting copies)."""
        return self._kd

    @kd.setter
    def kd(self, value: Sequence[float] | np.ndarray | float) -> None:
        self._kd[:] = _per_joint(value, self.n, "tracking kd")

    @property
    def max_ref_error(self) -> float:
        """Clip on ``q_ref - q`` [rad]."""
        return float(self._buf[-1])

    @max_ref_error.setter
    def max_ref_error(self, value: float) -> None:
        if not value > 0:
            raise ConfigError(f"max_ref_error must be > 0 [rad], got {value}")
        self._buf[-1] = float(value)

    def reset(self, data: mujoco.MjData) -> None:
        """Set the reference to the current joint positions and the command to zero."""
        self.q_ref[:] = data.qpos[self._qadr]
        self.u[:] = data.qvel[self._dof]
        self.a_ff[:] = 0.0

    def set_command(self, u: np.ndarray, period: float | None = None) -> None:
        """Hold the commanded joint velocity ``u`` [rad/s], shape (n,), until the next call.

        Args:
            u: The command, shape (n,).
            period: Time until the next call [s]; with ``feedforward`` the acceleration
                ``(u - u_previous) / period`` is fed forward until then. ``None``: no
                feedforward.

        """
        if self.feedforward and period is not None and period > 0:
            self.a_ff[:] = command_feedforward(u, self.u, 1.0 / period)
        else:
            self.a_ff[:] = 0.0
        self.u[:] = u

    def _bind(self, data: mujoco.MjData) -> None:
        """Views into ``data`` that :meth:`apply` works on, and their addresses (the arrays never move)."""
        self._data = data
        dof, view = self._dof, type(self._dof) is slice and type(self._qadr) is slice and type(self._act) is slice
        self._views = ((data.qpos[self._qadr], data.qvel[dof], self._acc_full[dof], self._tau_full[dof],
                        data.ctrl[self._act], data.qfrc_bias, data.qfrc_passive) if view else None)
        if self._views is not None:
            q, qd, _, _, ctrl, bias, passive = self._views
            d0 = int(dof.start)  # type: ignore[union-attr]
            self._ptrs[:] = (q.ctypes.data, qd.ctypes.data, ctrl.ctypes.data, bias[d0:].ctypes.data,
                             passive[d0:].ctypes.data, d0)
            self._daddr = int(data._address) if self._kernels is not None else 0

    def compiled_apply(self, data: mujoco.MjData) -> tuple | None:
        """``(kernels, addresses, buffer, n, nv)`` of the compiled :meth:`apply` bound to ``data`` (``None``: numpy).

        For a caller that fuses :meth:`apply` with its own compiled work
        (:meth:`~isf_robot.arm.monitor.SafetyMonitor.substep`).
        """
        if self._kernels is None:
            return None
        if data is not self._data:
            self._bind(data)
        return self._kernels, self._ptrs, self._buf, self.n, self._acc_full.size

    def command(self, data: mujoco.MjData, u: np.ndarray, period: float | None = None) -> float:
        """The tracking error of the held command, then :meth:`set_command` and :meth:`apply` in one.

        Returns ``|q_dot - u_held|`` [rad/s] at the state in ``data`` (before ``u`` takes over): the
        error the simulation records per control step.
        """
        if (u.shape[0] if type(u) is np.ndarray and u.ndim == 1 else np.size(u)) != self.n:  # (the kernel reads n)
            raise ShapeError(f"velocity command of {np.size(u)} joints for a tracker of {self.n}")
        step = self._step
        if step is not None:
            if data is not self._data:
                self._bind(data)
            ff = self.feedforward and period is not None and period > 0
            if type(u) is np.ndarray and u.dtype is _F64 and u.ndim == 1 and u.flags.c_contiguous:
                sd = self._step_direct  # (the other arrays are the tracker's own: jit.direct)
                if sd[0] is not step:
                    sd = self._step_direct = (step, direct(step, (self._maddr, self._daddr, self._ptrs, self._buf,
                                                                  self.n, self._acc_full.size, u, 0.0, ff)))
                step = sd[1]
            elif type(u) is not np.ndarray:
                u = np.asarray(u, float)
            return float(step(self._maddr, self._daddr, self._ptrs, self._buf, self.n, self._acc_full.size, u,
                              1.0 / period if ff else 0.0, ff))  # type: ignore[operator]
        err = float(tracking_error(data.qvel[self._dof].tolist(), self.u.tolist()))
        self.set_command(u, period)
        self.apply(data)
        return err

    def apply(self, data: mujoco.MjData) -> None:
        """Write ``data.ctrl`` for the current state; call between ``mj_step1`` and ``mj_step2``.

        Advances the reference by one physics step. Works in preallocated buffers and, with the
        arm's joints and actuators contiguous, in views bound once per ``data`` (it runs at the
        physics rate), or in one compiled call (:mod:`isf_robot.arm.kernels`; the same formulas).
        """
        if data is not self._data:
            self._bind(data)
        if self._daddr:
            self._kernels["track_apply"](self._maddr, self._daddr, self._ptrs, self._buf, self.n,  # type: ignore[index]
                                         self._acc_full.size)
            return
        views = self._views
        if views is None:
            self._apply_indexed(data)
            return
        q, qd, acc, tau, ctrl, bias, passive = views
        u, ref = self.u, self.q_ref
        err = reference_error(ref, u, self._dt, q, self.max_ref_error)
        np.add(q, err, out=ref)
        acc[:] = desired_acceleration(u, qd, err, self._kd, self._kp, self.a_ff)
        mujoco.mj_mulM(self.model, data, self._tau_full, self._acc_full)
        dof = self._dof
        fric = friction_feedforward(self.friction, u, self._ftmp) if self._fric else 0.0
        ctrl[:] = motor_ctrl(tau, bias[dof], passive[dof], fric, self._inv_gain, self._lo, self._hi)

    def _apply_indexed(self, data: mujoco.MjData) -> None:
        """:meth:`apply` for joints or actuators that are not contiguous (index arrays, copies)."""
        dof = self._dof
        q = data.qpos[self._qadr]
        u, ref = self.u, self.q_ref
        err = reference_error(ref, u, self._dt, q, self.max_ref_error)
        np.add(q, err, out=ref)
        self._acc_full[dof] = desired_acceleration(u, data.qvel[dof], err, self._kd, self._kp, self.a_ff)
        mujoco.mj_mulM(self.model, data, self._tau_full, self._acc_full)
        fric = friction_feedforward(self.friction, u, self._ftmp) if self._fric else 0.0
        data.ctrl[self._act] = motor_ctrl(self._tau_full[dof], data.qfrc_bias[dof], data.qfrc_passive[dof], fric,
                                          self._inv_gain, self._lo, self._hi)
