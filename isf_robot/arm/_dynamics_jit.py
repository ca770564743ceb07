"""The compiled terms of the arm's dynamics (:class:`~isf_robot.arm.dynamics.ArmDynamics`; only with numba).

:meth:`ArmDynamics.terms <isf_robot.arm.dynamics.ArmDynamics.terms>` calls ``mj_fullM`` and ``mj_solveM`` and
forms the free force between them: from Python, three binding calls and a few numpy operations (some 5 us of the
torque level's sense phase). :func:`dynamics_terms` makes the same calls on the raw addresses of the bindings'
``MjModel``/``MjData`` (the ``libmujoco`` the ``mujoco`` package loaded) in one call; the free force is
:func:`~isf_robot.arm.dynamics_law.free_force`, which the numpy path calls too. Same C calls on the same inputs: the
two paths agree to the last bit (``tests/arm/test_dynamics.py``).
"""

from __future__ import annotations

import numpy as np

from ._kernels_jit import full_m, solve_m  # (importing it loads libmujoco; ImportError without it)
from .dynamics_law import free_force


def dynamics_terms(ma, da, passive, bias, full, rhs, sol):  # pragma: no cover (compiled)
    """``M`` into ``full`` (nv, nv), ``free_force`` into the last row of ``rhs`` (n + 1, nv), ``M^-1 rhs`` into ``sol``.

    ``ma``, ``da``: the addresses of the model and of the data (after ``mj_step1`` or ``mj_forward``: ``qLD``);
    ``passive``, ``bias``: its ``qfrc_passive`` and ``qfrc_bias``; ``rhs``'s other rows: the arm dofs' unit vectors.
    """
    n = rhs.shape[0] - 1
    rhs[n] = free_force(passive, bias)
    full_m(ma, da, full.ctypes.data)
    solve_m(ma, da, sol.ctypes.data, rhs.ctypes.data, np.int32(n + 1))
