"""The numba kernels of the predictive off trigger's rollout (:mod:`isf_robot.arm.rollout`; imported only with numba).

Module-level functions, so numba's cache (``__pycache__``) serves later processes. MuJoCo's C
functions ``mj_kinematics`` and ``mj_comPos`` are called directly on the raw addresses of the
``MjModel``/``MjData`` the bindings hold, as in :mod:`isf_robot.arm._kernels_step`.

:func:`rollout_points` calls the reaching controller's kernel (``_kernels_step.reach``) and the
collision kernel (``_kernels_jit.near_packed``). numba's cache does not notice a change of a function
that a cached function calls from another file (a documented limitation), so :func:`guard_cache`
flushes this module's cached code whenever those files' sources change (a stamp beside the cache).
"""

from __future__ import annotations

import hashlib
import os

from numba import carray, njit, types

from isf_robot.core.jit import watch_compiles

from ._kernels_jit import f64p, near_packed  # (importing it loads libmujoco's symbols; ImportError without it)
from ._kernels_step import reach

watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)

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


@njit(cache=True, nogil=True)
def rollout_points(ma, da, q, u0, t, dt, qpos, qadr, rp, nb, outs, n, nv, dof0, site, index, t_prev, a_max, kp,
                   max_ee, max_js, lam2, pn, blks, rows, keys, npairs, res, cutoff, distmax, slack, eps, norms_in, lin,
                   dhdt_in, mp_addr, nmocap, mids, mpos, lins):  # pragma: no cover (compiled)
    """Every point of a rollout with the goal ``index`` held, in one call.

    Per point ``j`` (time ``t + (j + 1) dt``): the Euler step from the previous command, the reaching
    controller's command into ``outs[j]`` (``reach``, buffer ``nb``, addresses ``rp``), the collision
    kernel's rows into ``blks[j]``/``rows[j]`` (``near_packed``, tables ``pn``, no coherence bounds), and
    each row's key into ``keys[j]`` (a pair's index for the pair rows, ``npairs + i`` for the i-th row
    after them: the joint rows).
    ``res[j]``: near pairs, h_min, dist_min, joint_min, touching, goal distance. Returns the points done:
    it stops after a point with touching witness points (which the caller hands to the general path).
    Moving obstacles: before each point's kinematics, mocap body ``mids[r]`` is put at ``mpos[j, r]``
    (the scratch data's ``mocap_pos`` at address ``mp_addr``, ``nmocap`` rows), and the collision
    kernel reads the mocap velocities ``lins[j]`` (no rows: ``lin`` at every point).
    """
    u = u0
    nm = mids.shape[0]
    mp = carray(f64p(mp_addr), (max(nmocap, 1), 3))
    for j in range(outs.shape[0]):
        s = (j + 1) * dt
        tj = t + s
        for r in range(nm):  # (the obstacles' place first: the kinematics below read it)
            for e in range(3):
                mp[mids[r], e] = mpos[j, r, e]
        euler_step(ma, da, q, u, dt, qpos, qadr)
        res[j, 5] = reach(ma, da, rp, nb, outs[j], n, nv, dof0, site, index, False, tj, t_prev, True, a_max, kp,
                          max_ee, max_js, lam2)
        t_prev = tj
        u = outs[j]
        k, h_min, dist_min, jmin, touching = near_packed(ma, da, pn, blks[j], rows[j], False, cutoff, distmax, slack,
                                                         eps, norms_in, lins[j] if lins.shape[0] else lin, dhdt_in)
        res[j, 0], res[j, 1], res[j, 2], res[j, 3], res[j, 4] = k, h_min, dist_min, jmin, 1.0 if touching else 0.0
        for i in range(k):
            keys[j, i] = rows[j, i]
        for i in range(keys.shape[1] - k):
            keys[j, k + i] = npairs + i
        if touching:
            return j + 1
    return outs.shape[0]


def guard_cache() -> bool:
    """Flush :func:`rollout_points`'s cached code when the sources of the kernels it calls have changed.

    ``False`` when it cannot tell (a source unreadable, or a numba without the cache object this
    reads): the caller then does not use :func:`rollout_points`.
    """
    here = os.path.dirname(os.path.abspath(__file__))
    digest = hashlib.sha256()
    cache = getattr(rollout_points, "_cache", None)  # (numba's FunctionCache of a cache=True dispatcher)
    if cache is None or not hasattr(cache, "flush") or not isinstance(getattr(cache, "_cache_path", None), str):
        return False
    try:
        for name in ("_kernels_jit.py", "_kernels_step.py", "_rollout_jit.py"):
            with open(os.path.join(here, name), "rb") as f:
                digest.update(f.read())
    except OSError:
        return False
    stamp = digest.hexdigest()
    path = os.path.join(cache._cache_path, "_rollout_jit.rollout_points.deps")
    try:
        with open(path, encoding="ascii") as f:
            if f.read() == stamp:
                return True
    except OSError:
        pass
    cache.flush()  # (an empty index: compiled anew at the first call, then cached again)
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        with open(tmp, "w", encoding="ascii") as f:
            f.write(stamp)
        os.replace(tmp, path)
    except OSError:  # (a read-only cache folder: the code is compiled in each process)
        pass
    return True
