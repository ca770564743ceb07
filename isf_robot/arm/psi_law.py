"""The formulas of the torque level's rows' ``phi`` (:mod:`isf_robot.arm.second_order`), one source for both paths.

Plain functions on arrays that :class:`~isf_robot.arm.second_order.SecondOrderRows`, the torque rollout and the
compiled difference of ``phi`` (``_second_order_jit``, :func:`~isf_robot.core.jit.formula`) all call::

    phi   = J q_dot + dh/dt                                  (phi_rows)
    dh/dt -> -|dh/dt|  with approaching                      (obstacle_rate)
    D phi = (phi(q + eps q_dot, t + eps) - phi) / eps        (phi_difference)
    psi   = phi + alpha_1 h                                  (psi_value)
    Lf psi = D phi + J a0 + alpha_1 phi,  Lg psi = J Minv    (psi_rows, with psi)
"""

from __future__ import annotations

import numpy as np

from isf_robot.core.jit import formula

__all__ = ["obstacle_rate", "phi_rows", "phi_difference", "psi_value", "psi_rows"]


@formula
def obstacle_rate(dhdt: np.ndarray, approaching: bool) -> np.ndarray:
    """The moving obstacles' part of ``h_dot``: ``dh/dt`` itself, or ``-|dh/dt|`` with ``approaching``.

    ``approaching`` takes every moving obstacle as closing in at its speed, whichever way it moves (the torque
    level's rows: :class:`~isf_robot.arm.second_order.SecondOrderRows`, and its rollout's).
    """
    return -np.abs(dhdt) if approaching else dhdt


@formula
def phi_rows(grad: np.ndarray, q_dot: np.ndarray, dhdt: np.ndarray) -> np.ndarray:
    """``phi = J q_dot + dh/dt`` of rows with gradients ``grad`` (k, n) and ``dh/dt`` (k,) [m/s], shape (k,)."""
    return grad @ q_dot + dhdt


@formula
def phi_difference(phi_shifted: np.ndarray, phi: np.ndarray, eps: float) -> np.ndarray:
    """``D phi`` by the forward difference ``(phi(q + eps q_dot, t + eps) - phi) / eps`` [m/s^2], shape (k,)."""
    return (phi_shifted - phi) / eps


@formula
def psi_value(phi: np.ndarray, h: np.ndarray, alpha_1: float) -> np.ndarray:
    """``psi = phi + alpha_1 h`` [m/s] of rows with ``phi`` [m/s] and ``h`` [m] (arrays or floats)."""
    return phi + alpha_1 * h


@formula
def psi_rows(h: np.ndarray, grad: np.ndarray, phi: np.ndarray, dphi: np.ndarray, a0: np.ndarray, minv: np.ndarray,
             alpha_1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(psi, Lf psi, Lg psi)`` of rows ``h`` (k,), ``J`` (k, n), ``phi``, ``D phi`` (k,) on ``a0 + Minv tau``.

    ``psi = phi + alpha_1 h`` [m/s], ``Lf psi = D phi + J a0 + alpha_1 phi`` [m/s^2], ``Lg psi = J Minv``, shape (k, n).
    """
    return psi_value(phi, h, alpha_1), dphi + grad @ a0 + alpha_1 * phi, grad @ minv
