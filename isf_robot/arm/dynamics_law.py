"""The formula of the dynamics' terms (:mod:`isf_robot.arm.dynamics`), one source for both paths.

A plain function that :class:`~isf_robot.arm.dynamics.ArmDynamics` calls on numpy arrays and the compiled terms
(``_dynamics_jit``, :func:`~isf_robot.core.jit.formula`) compile into themselves::

    free = qfrc_passive - qfrc_bias          (free_force: the force whose solution is the free acceleration a0)
    q_ddot_model = a0 + Minv tau             (model_acceleration: the model's acceleration under tau)
    |(q_dot - q_dot_0) / T - q_ddot_model|   (model_error: a period's error of the model [rad/s^2])
"""

from __future__ import annotations

import numpy as np

from isf_robot.core.jit import formula

__all__ = ["free_force", "model_acceleration", "model_error"]


@formula
def free_force(passive: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """The free generalized force ``qfrc_passive - qfrc_bias`` [N m], shape (nv,)."""
    return passive - bias


@formula
def model_acceleration(a0: np.ndarray, minv: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """The model's ``q_ddot = a0 + Minv tau`` [rad/s^2] under the arm torques ``tau`` (n,)."""
    return a0 + minv @ tau


@formula
def model_error(qvel: np.ndarray, dof: np.ndarray, v0: np.ndarray, pred: np.ndarray, period: float) -> float:
    """``|(q_dot - v0) / period - pred|`` [rad/s^2]: the model's error over a control period.

    ``q_dot = qvel[dof]`` at its end, ``v0`` at its start, ``pred`` the model's ``q_ddot = a0 + Minv tau`` there.
    """
    e = (qvel[dof] - v0) / period - pred
    return np.sqrt(e.dot(e))
