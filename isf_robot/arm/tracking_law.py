"""The velocity tracker's control law, one plain function per formula (:mod:`isf_robot.arm.lowlevel`).

Each formula works on floats and on numpy arrays alike (element by element): the numpy path of
:class:`~isf_robot.arm.lowlevel.VelocityTracker` calls it once on the arm's joints, the compiled
kernel (``_kernels_step``) once per joint, the same source compiled by numba
(:func:`~isf_robot.core.jit.formula`). Units: [rad], [rad/s], [rad/s^2], [Nm] per joint::

    e     = clip(q_ref + u dt - q, +-e_max)          (reference_error; then q_ref <- q + e)
    a     = kd (u - q_dot) + kp e + a_ff             (desired_acceleration)
    ctrl  = clip((M a + c - f_passive + f_fric) / gear, ctrlrange)   (motor_ctrl)
    a_ff  = (u_k - u_{k-1}) / T                      (command_feedforward)
"""

from __future__ import annotations

import math

import numpy as np

from isf_robot.core.jit import formula

__all__ = ["reference_error", "desired_acceleration", "motor_ctrl", "command_feedforward", "tracking_error"]


@formula
def reference_error(ref, u, dt, q, e_max):  # type: ignore[no-untyped-def]
    """``clip(q_ref + u dt - q, +-e_max)``: the error of the reference advanced by one physics step ``dt`` [s]."""
    return np.maximum(np.minimum((ref + u * dt) - q, e_max), -e_max)


@formula
def desired_acceleration(u, qd, err, kd, kp, a_ff):  # type: ignore[no-untyped-def]
    """``kd (u - q_dot) + kp e + a_ff`` [rad/s^2]: velocity loop, reference loop and feedforward."""
    return ((u - qd) * kd + err * kp) + a_ff


@formula
def motor_ctrl(tau, bias, passive, friction, inv_gain, lo, hi):  # type: ignore[no-untyped-def]
    """``clip((M a + c - f_passive + f_fric) / gear, [lo, hi])``: a motor's control from the torque ``tau = M a``."""
    return np.maximum(np.minimum((((tau + bias) - passive) + friction) * inv_gain, hi), lo)


@formula
def command_feedforward(u_new, u_old, inv_period):  # type: ignore[no-untyped-def]
    """``(u_k - u_{k-1}) / T`` [rad/s^2]: the acceleration fed forward over the control period (``1/T`` given)."""
    return (u_new - u_old) * inv_period


@formula
def tracking_error(qd, u):  # type: ignore[no-untyped-def]
    """``|q_dot - u|`` [rad/s]: the velocity error of the held command (the disturbance ``d`` of the reduced model).

    Arrays, or (the plain path, faster in Python) lists.
    """
    s = 0.0
    for k in range(len(qd)):
        s += (qd[k] - u[k]) * (qd[k] - u[k])
    return math.sqrt(s)
