"""The formula of the dynamics' terms (:mod:`isf_robot.arm.dynamics`), one source for both paths.

A plain function that :class:`~isf_robot.arm.dynamics.ArmDynamics` calls on numpy arrays and the compiled terms
(``_dynamics_jit``, :func:`~isf_robot.core.jit.formula`) compile into themselves::

    free = qfrc_passive - qfrc_bias          (free_force: the force whose solution is the free acceleration a0)
"""

from __future__ import annotations

import numpy as np

from isf_robot.core.jit import formula

__all__ = ["free_force"]


@formula
def free_force(passive: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """The free generalized force ``qfrc_passive - qfrc_bias`` [N m], shape (nv,)."""
    return passive - bias
