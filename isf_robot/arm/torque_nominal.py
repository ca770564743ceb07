"""The torque level's nominal: computed torque on the velocity level's reaching command.

The velocity level's nominal (:class:`~isf_robot.arm.nominal.ReachingController`: damped least
squares through the scene's goals, rate-limited) gives a joint velocity reference ``v_ref``. The
torque nominal tracks it on the filter's model (:mod:`isf_robot.arm.dynamics`)::

    a_ref = (v_ref,k - v_ref,k-1) / T                    (0 at the first tick)
    tau   = clip(M (kd (v_ref - q_dot) + a_ref) + hold, -tau_max, tau_max)

``hold = qfrc_bias - qfrc_passive`` (gravity, Coriolis, the model's damping). So both levels run
the same task toward the same goals; only what the filter changes differs.
"""

from __future__ import annotations

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError

from .dynamics import DynamicsTerms
from .nominal import NominalController

__all__ = ["TorqueNominal", "computed_torque"]


def computed_torque(terms: DynamicsTerms, v_ref: np.ndarray, a_ref: np.ndarray, q_dot: np.ndarray, kd: float,
                    tau_max: np.ndarray) -> np.ndarray:
    """``clip(M (kd (v_ref - q_dot) + a_ref) + hold, -tau_max, tau_max)`` [N m], shape (n,)."""
    tau = terms.mass @ (kd * (v_ref - q_dot) + a_ref)
    tau += terms.hold
    return np.minimum(np.maximum(tau, -tau_max, out=tau), tau_max, out=tau)  # (np.clip, without its wrapper)


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

    def reset(self) -> None:
        """Forget the previous reference (and reset the velocity-level nominal)."""
        self.reference.reset()
        self.v_ref = np.zeros(self.dof.size)
        self._first = True

    def __call__(self, t: float, data: mujoco.MjData, terms: DynamicsTerms) -> np.ndarray:
        """The nominal torque at the tick [N m], shape (n,) (``v_ref`` keeps the velocity reference)."""
        v = np.array(self.reference(t, data), dtype=float)  # (a copy: a nominal may reuse its buffer)
        a = np.zeros_like(v) if self._first else (v - self.v_ref) / self.period
        self.v_ref, self._first = v, False
        return computed_torque(terms, v, a, data.qvel[self.dof], self.kd, self.tau_max)
