"""The arm's rigid-body dynamics at one state, as the torque-level filter plans with them.

The filter's model of the arm (its joints' dofs ``a``, torque ``tau`` on them)::

    M(q) q_ddot = tau + qfrc_passive(q, q_dot) - qfrc_bias(q, q_dot) + d_tau

``qfrc_bias`` holds gravity and the Coriolis and centrifugal forces, ``qfrc_passive`` the
joint damping and springs the model states; ``d_tau`` everything the model leaves out
(friction losses, joint-limit and contact forces, an unmodelled payload, the zero-order hold
of ``tau`` over a control period). So ``q_ddot = a0 + Minv tau + d`` with

    a0   = [M^-1 (qfrc_passive - qfrc_bias)]_a     the free acceleration, shape (n,)
    Minv = [M^-1]_aa                               shape (n, n)

and ``d = M^-1 d_tau`` the disturbance on the accelerations [rad/s^2] whose bound ``d_bar`` is
calibrated (:mod:`isf_robot.arm.torque_calibration`). The terms are read from an ``MjData`` on
which ``mj_step1`` (or ``mj_forward``) has run: ``mj_fullM`` of its sparse mass matrix, ``mj_solveM`` on
the factor of it they computed (``qLD``), its ``qfrc_bias`` and ``qfrc_passive``.

Torque limits (:func:`torque_limits`): each arm actuator's largest joint torque
(:class:`~isf_robot.arm.actuation.ActuatorInfo` ``force_limit``: ``forcerange`` times the gear; a
motor's ``ctrlrange`` times gain and gear).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError
from isf_robot.core.jit import direct

from . import kernels
from .actuation import arm_actuators
from .dynamics_law import free_force, model_acceleration
from .scene import Scene

__all__ = ["ArmDynamics", "DynamicsTerms", "torque_limits"]

_new, _set = object.__new__, object.__setattr__  # (DynamicsTerms._of: a frozen dataclass's __dict__ set whole)


@dataclass(frozen=True)
class DynamicsTerms:
    """The model's terms at one state (see the module docstring).

    Attributes:
        mass: ``M_aa``, the arm block of the mass matrix [kg m^2], shape (n, n).
        minv: ``[M^-1]_aa`` [1/(kg m^2)], shape (n, n).
        a0: Free acceleration ``[M^-1 (qfrc_passive - qfrc_bias)]_a`` [rad/s^2], shape (n,).
        hold: ``qfrc_bias - qfrc_passive`` on the arm dofs [N m]: the torque that holds the arm at its
            current velocity (gravity compensation at rest), shape (n,).

    """

    mass: np.ndarray
    minv: np.ndarray
    a0: np.ndarray
    hold: np.ndarray

    @classmethod
    def _of(cls, mass: np.ndarray, minv: np.ndarray, a0: np.ndarray, hold: np.ndarray) -> DynamicsTerms:
        """The terms with these fields, unchecked: :meth:`ArmDynamics.terms`'s fast path.

        Same object as ``DynamicsTerms(...)`` would build, without the frozen dataclass's field-by-field ``__init__``.
        """
        terms = _new(cls)
        _set(terms, "__dict__", {"mass": mass, "minv": minv, "a0": a0, "hold": hold})
        return terms

    def acceleration(self, tau: np.ndarray) -> np.ndarray:
        """The model's ``q_ddot = a0 + Minv tau`` [rad/s^2] under the arm torques ``tau`` (n,)."""
        return model_acceleration(self.a0, self.minv, tau)


class ArmDynamics:
    """The :class:`DynamicsTerms` of a model's arm dofs.

    Args:
        model: The model the filter plans with.
        dof_adr: The arm's dof addresses, shape (n,).
        own_data: The states come from another model (the simulated arm, e.g. with a payload the
            filter does not know): copy each state into a data of ``model`` and compute its terms
            there. ``False``: the given data belong to ``model`` (or to a model with the same
            inertias) and have their terms computed.

    """

    def __init__(self, model: mujoco.MjModel, dof_adr: np.ndarray, own_data: bool = False) -> None:
        self.model = model
        self.dof = np.asarray(dof_adr, dtype=np.int64)
        n = self.dof.size
        self._nv2 = (model.nv, model.nv)
        self._own = mujoco.MjData(model) if own_data else None
        self._all = bool(np.array_equal(self.dof, np.arange(model.nv)))  # (the arm is every dof: no selection)
        # Right-hand sides of the one solve per state: the arm dofs' unit vectors, then the free force.
        self._rhs = np.zeros((n + 1, model.nv))
        self._rhs[np.arange(n), self.dof] = 1.0
        self._kernel = kernels.dynamics_kernel()  # (the compiled terms; None: the bindings' calls below)
        self._bound: tuple = (None,)  # (the data the kernel was last given, its address and force arrays: _bind)

    def __getstate__(self) -> dict:
        """A copy or a pickle binds its compiled call again: the binding holds raw addresses of this object's data."""
        state = dict(self.__dict__)
        state["_bound"] = (None,)
        return state

    def _bind(self, data: mujoco.MjData) -> tuple:
        """The compiled call's arguments of ``data``: ``(data, kernel, its address, qfrc_passive, qfrc_bias)``.

        The kernel called directly (:func:`~isf_robot.core.jit.direct`): its arguments are of fixed types (the model's
        and data's addresses, their own arrays, this object's buffers).
        """
        nv = self.model.nv
        args = (int(self.model._address), int(data._address), data.qfrc_passive, data.qfrc_bias,
                np.empty((nv, nv)), self._rhs, np.empty_like(self._rhs))
        self._bound = (data, direct(self._kernel, args), *args[:4])
        return self._bound

    def terms(self, data: mujoco.MjData) -> DynamicsTerms:
        """The terms at the state in ``data`` (after ``mj_step1`` or ``mj_forward``).

        ``M^-1`` comes from the factor of ``M`` those leave in ``data`` (``qLD``, ``mj_solveM``): one solve of
        ``n + 1`` right-hand sides (the arm dofs' unit vectors, whose solutions' arm entries are ``[M^-1]_aa``
        (``M`` symmetric), and ``qfrc_passive - qfrc_bias``, whose solution is the free acceleration). With numba
        ``mj_fullM``, the free force and ``mj_solveM`` are one compiled call (``_dynamics_jit.dynamics_terms``: the
        same C calls, the same figures to the bit).
        """
        if self._own is not None:
            own = self._own
            own.qpos[:], own.qvel[:], own.time = data.qpos, data.qvel, data.time
            own.mocap_pos[:], own.mocap_quat[:] = data.mocap_pos, data.mocap_quat
            mujoco.mj_fwdPosition(self.model, own)
            mujoco.mj_fwdVelocity(self.model, own)
            data = own
        model, rhs, n = self.model, self._rhs, self.dof.size
        full = np.empty(self._nv2)  # (fresh, as the solution: the terms of a state are never overwritten)
        sol = np.empty_like(rhs)
        if self._kernel is not None:  # (the same calls in one compiled call)
            b = self._bound if self._bound[0] is data else self._bind(data)
            b[1](b[2], b[3], b[4], b[5], full, rhs, sol)
        else:
            mujoco.mj_fullM(model, data, full)
            rhs[n] = free_force(data.qfrc_passive, data.qfrc_bias)
            mujoco.mj_solveM(model, data, sol, rhs)
        free = rhs[n]
        if self._all:
            return DynamicsTerms._of(full, sol[:n], sol[n], -free)
        dof = self.dof
        return DynamicsTerms._of(full[np.ix_(dof, dof)], sol[:n, dof], sol[n, dof], -free[dof])


def torque_limits(scene: Scene) -> np.ndarray:
    """The largest joint torque of each arm joint [N m], shape (n,).

    Raises:
        ConfigError: An arm joint's actuator has no torque limit (no ``forcerange``, and for a
            motor no ``ctrlrange``): the torque level needs one.

    """
    infos = arm_actuators(scene)
    lim = np.array([i.force_limit for i in infos], dtype=float)
    bad = [scene.joint_names[k] for k, v in enumerate(lim.tolist()) if not (math.isfinite(v) and v > 0)]
    if bad:
        raise ConfigError(f"the torque level needs a torque limit on every arm joint; joints {bad} have none "
                          "(give their actuators forcerange, or ctrlrange for a <motor>)")
    return lim
