"""The numba kernel of the rollout's Euler step (:mod:`isf_robot.arm.rollout`; imported only with numba).

A module-level function, so numba's cache (``__pycache__``) serves later processes. MuJoCo's C
functions ``mj_kinematics`` and ``mj_comPos`` are called directly on the raw addresses of the
``MjModel``/``MjData`` the bindings hold, as in :mod:`isf_robot.arm._kernels_step`.
"""

from __future__ import annotations

from numba import njit, types

from . import _kernels_jit  # noqa: F401  (importing it loads libmujoco's symbols; ImportError without it)

_ptr = types.intp
# void mj_kinematics(const mjModel* m, mjData* d)
kinematics = types.ExternalFunction("mj_kinematics", types.void(_ptr, _ptr))
# void mj_comPos(const mjModel* m, mjData* d)
com_pos = types.ExternalFunction("mj_comPos", types.void(_ptr, _ptr))


@njit(cache=True, nogil=True)
def euler_step(ma, da, q, u, dt, qpos, qadr):  # pragma: no cover (compiled)
    """``q <- q + dt u`` (each ``q_i + (dt u_i)``, numpy's two roundings), ``qpos[qadr] = q``, then the kinematics."""
    for i in range(q.shape[0]):
        q[i] = q[i] + dt * u[i]
        qpos[qadr[i]] = q[i]
    kinematics(ma, da)
    com_pos(ma, da)
