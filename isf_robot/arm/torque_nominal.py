"""The torque level's nominal: computed torque on the velocity level's reaching command.

The velocity level's nominal (:class:`~isf_robot.arm.nominal.ReachingController`: damped least
squares through the scene's goals, rate-limited) gives a joint velocity reference ``v_ref``. The
torque nominal tracks it on the filter's model (:mod:`isf_robot.arm.dynamics`)::

    a_ref = (v_ref,k - v_ref,k-1) / T                    (0 at the first tick)
    tau   = clip(M (kd (v_ref - q_dot) + a_ref) + hold, -tau_max, tau_max)

``hold = qfrc_bias - qfrc_passive`` (gravity, Coriolis, the model's damping). So both levels run
the same task toward the same goals; only what the filter changes differs.

The tick's arithmetic (``a_ref``, the law, the clip) is one plain function, :func:`nominal_torque`, which
:func:`~isf_robot.core.jit.compiled` compiles (one call instead of a dozen small numpy operations, about 10 us of
a torque-level control step); ``ISF_ROBOT_JIT=0`` runs it as written, on numpy.
"""

from __future__ import annotations

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError
from isf_robot.core.jit import compiled, formula

from .dynamics import DynamicsTerms
from .nominal import NominalController

__all__ = ["TorqueNominal", "computed_torque", "torque_law", "torque_clip", "torque_peak", "nominal_torque"]


@formula
def torque_law(mass: np.ndarray, hold: np.ndarray, v_ref: np.ndarray, a_ref: np.ndarray, q_dot: np.ndarray,
               kd: float, tau_max: np.ndarray) -> np.ndarray:
    """``clip(M (kd (v_ref - q_dot) + a_ref) + hold, -tau_max, tau_max)`` [N m], shape (n,)."""
    return torque_clip(mass @ (kd * (v_ref - q_dot) + a_ref) + hold, tau_max)


@formula
def torque_clip(tau: np.ndarray, tau_max: np.ndarray) -> np.ndarray:
    """``clip(tau, -tau_max, tau_max)`` [N m] (np.clip, which numba lacks for arrays)."""
    return np.minimum(np.maximum(tau, -tau_max), tau_max)


@formula
def torque_peak(tau: np.ndarray, tau_max: np.ndarray) -> float:
    """The largest ``|tau_i| / tau_max,i`` (not finite exactly when ``tau`` is not: ``tau_max`` > 0, finite)."""
    return (np.abs(tau) / tau_max).max()


def computed_torque(terms: DynamicsTerms, v_ref: np.ndarray, a_ref: np.ndarray, q_dot: np.ndarray, kd: float,
                    tau_max: np.ndarray) -> np.ndarray:
    """:func:`torque_law` on the terms' ``M`` and ``hold`` [N m], shape (n,)."""
    return torque_law(terms.mass, terms.hold, v_ref, a_ref, q_dot, kd, tau_max)


def nominal_torque(mass: np.ndarray, hold: np.ndarray, v: np.ndarray, v_prev: np.ndarray, first: bool,
                   period: float, qvel: np.ndarray, dof: np.ndarray, kd: float, tau_max: np.ndarray,
                   out: np.ndarray) -> None:
    """The torque nominal at a tick (:class:`TorqueNominal`): :func:`torque_law` on the reference ``v`` into ``out``.

    ``a_ref = (v - v_prev) / period`` (zero at the ``first`` tick); ``v_prev`` (the last tick's reference) then
    gets ``v``; ``q_dot = qvel[dof]``. A plain function: :func:`~isf_robot.core.jit.compiled` compiles it. ``out``
    is the caller's (numpy's own array: an array a cached numba kernel returns carries a dtype object that is not
    numpy's float64 singleton, and the core's strategies test ``dtype is float64`` before their compiled passes).
    """
    a_ref = np.zeros_like(v) if first else (v - v_prev) / period
    v_prev[:] = v
    out[:] = torque_law(mass, hold, v, a_ref, qvel[dof], kd, tau_max)


class TorqueNominal:
    """Computed-torque tracking of a velocity-level nominal (see the module docstring).

    Args:
        reference: The velocity-level nominal (its ``goal_index``, ``goals_reached`` ... are this one's).
        dof_adr: The arm's dof addresses, shape (n,).
        tau_max: Torque limits [N m], shape (n,).
        period: Control period T [s] (for ``a_ref``).
        kd: Velocity-tracking gain [1/s], > 0.

    """

    def __init__(self, reference: NominalController, dof_adr: np.ndarray, tau_max: np.ndarray, period: float,
                 kd: float = 40.0) -> None:
        if not (np.isfinite(kd) and kd > 0):
            raise ConfigError(f"torque nominal kd must be a positive number [1/s], got {kd}")
        self.reference, self.dof = reference, np.asarray(dof_adr, dtype=np.int64)
        self.tau_max, self.period, self.kd = np.asarray(tau_max, dtype=float), float(period), float(kd)
        self.v_ref = np.zeros(self.dof.size)  # (the last tick's reference, this object's own array)
        self._first = True
        self._step = compiled(nominal_torque)  # (ISF_ROBOT_JIT is read here)

    def reset(self) -> None:
        """Forget the previous reference (and reset the velocity-level nominal)."""
        self.reference.reset()
        self.v_ref[:] = 0.0
        self._first = True

    def __call__(self, t: float, data: mujoco.MjData, terms: DynamicsTerms) -> np.ndarray:
        """The nominal torque at the tick [N m], shape (n,) (``v_ref`` keeps the velocity reference)."""
        v = self.reference(t, data)
        if not (type(v) is np.ndarray and v.dtype == np.float64 and v.ndim == 1):  # (else used as it is: copied)
            v = np.array(v, dtype=float)
        first, self._first = self._first, False
        tau = np.empty(self.dof.size)  # (fresh: the strategy may keep it)
        self._step(terms.mass, terms.hold, v, self.v_ref, first, self.period, data.qvel, self.dof, self.kd,
                   self.tau_max, tau)
        return tau
