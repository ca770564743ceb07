"""The numba kernels of the nominal and act phases (:mod:`isf_robot.arm.kernels`; only with numba).

Module-level functions, so numba's cache serves later processes. MuJoCo's C functions are called
directly (``mj_mulM``, ``mj_jacSite``, ``mju_cholFactor``, ``mju_cholSolve``), on the raw addresses of
the ``MjModel``/``MjData`` the bindings hold. The arrays a kernel works on are passed as one int64
array of their addresses (a numba call costs about 0.1-0.6 us per array argument, more than the
kernels' own work): the callers keep the arrays alive and never reallocate them (see
:class:`~isf_robot.arm.lowlevel.VelocityTracker` and :class:`~isf_robot.arm.nominal.ReachingController`).

Same answers: each kernel makes the floating-point operations of the numpy code it replaces in the
same order. The small products of the reaching controller (``err . err`` of 3, ``J J^T`` of (3, n),
``y J``) and the tracking error's ``e . e`` are written in one order on both sides (the numpy side in
:mod:`isf_robot.core.sums`, no BLAS, no fused multiply-add), so the two agree on every machine.
"""

from __future__ import annotations

import math

import numpy as np
from numba import carray, njit, types

from isf_robot.core.jit import watch_compiles

from ._kernels_jit import f64p as _f64p  # (importing it loads libmujoco's symbols; ImportError without it)
from ._kernels_jit import monitor

watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)

_ptr, _i32, _f64 = types.intp, types.int32, types.float64
# void mj_mulM(const mjModel* m, const mjData* d, mjtNum* res, const mjtNum* vec)
mul_m = types.ExternalFunction("mj_mulM", types.void(_ptr, _ptr, _ptr, _ptr))
# void mj_jacSite(const mjModel* m, const mjData* d, mjtNum* jacp, mjtNum* jacr, int site)
jac_site = types.ExternalFunction("mj_jacSite", types.void(_ptr, _ptr, _ptr, _ptr, _i32))
# int mju_cholFactor(mjtNum* mat, int n, mjtNum mindiag)
chol_factor = types.ExternalFunction("mju_cholFactor", _i32(_ptr, _i32, _f64))
# void mju_cholSolve(mjtNum* res, const mjtNum* mat, const mjtNum* vec, int n)
chol_solve = types.ExternalFunction("mju_cholSolve", types.void(_ptr, _ptr, _ptr, _i32))


@njit(cache=True, nogil=True, inline="always")
def _vec(addr, n):  # pragma: no cover (compiled)
    return carray(_f64p(addr), n)


@njit(cache=True, nogil=True, inline="always")
def _minimum(a, b):  # pragma: no cover (compiled)
    """``np.minimum`` of two floats (NaN propagates; of two equal values, ``b``)."""
    return a if (a < b or a != a) else b


@njit(cache=True, nogil=True, inline="always")
def _maximum(a, b):  # pragma: no cover (compiled)
    """``np.maximum`` of two floats (NaN propagates; of two equal values, ``b``)."""
    return a if (a > b or a != a) else b


# -- the tracker (VelocityTracker.apply), its buffer: rows of n, then two of nv, then scalars ----
U, REF, AFF, KD, KP, INVG, LO, HI, ERR = range(9)
"""Rows of the tracker's buffer (n values each): command, reference, feedforward, gains, limits, scratch."""


@njit(cache=True, nogil=True, inline="always")
def _apply(ma, da, p, buf, n, nv):  # pragma: no cover (compiled)
    """VelocityTracker.apply's view path, the same operations in the same order."""
    q, qd, ctrl, bias, passive = _vec(p[0], n), _vec(p[1], n), _vec(p[2], n), _vec(p[3], n), _vec(p[4], n)
    dof0 = p[5]
    acc_full = buf[9 * n: 9 * n + nv]
    tau_full = buf[9 * n + nv: 9 * n + 2 * nv]
    dt, emax = buf[9 * n + 2 * nv], buf[9 * n + 2 * nv + 1]
    for i in range(n):
        u = buf[U * n + i]
        ref = buf[REF * n + i] + u * dt
        err = _maximum(_minimum(ref - q[i], emax), -emax)
        buf[REF * n + i] = q[i] + err
        acc_full[dof0 + i] = (((u - qd[i]) * buf[KD * n + i]) + err * buf[KP * n + i]) + buf[AFF * n + i]
    mul_m(ma, da, tau_full.ctypes.data, acc_full.ctypes.data)
    for i in range(n):
        tau = (tau_full[dof0 + i] + bias[i]) - passive[i]
        ctrl[i] = _maximum(_minimum(tau * buf[INVG * n + i], buf[HI * n + i]), buf[LO * n + i])


@njit(cache=True, nogil=True)
def track_apply(ma, da, p, buf, n, nv):  # pragma: no cover (compiled)
    """VelocityTracker.apply: the torques for the held command (one physics step)."""
    _apply(ma, da, p, buf, n, nv)


@njit(cache=True, nogil=True)
def track_step(ma, da, p, buf, n, nv, cmd, inv_period, feedforward):  # pragma: no cover (compiled)
    """Tracking error of the held command, then set_command(cmd) and apply.

    Returns ``|qd - u_held|`` (the squares added in order from 0, as :func:`isf_robot.core.sums.sq_sum`).
    """
    qd = _vec(p[1], n)
    s = 0.0
    for i in range(n):
        e = qd[i] - buf[U * n + i]
        s += e * e
    for i in range(n):
        if feedforward:
            buf[AFF * n + i] = (cmd[i] - buf[U * n + i]) * inv_period
        else:
            buf[AFF * n + i] = 0.0
        buf[U * n + i] = cmd[i]
    _apply(ma, da, p, buf, n, nv)
    return math.sqrt(s)


@njit(cache=True, nogil=True)
def monitor_apply(ma, da, rows, g1, g2, margin, thresh, bound, p, buf, n, nv):  # pragma: no cover (compiled)
    """A physics sub-step's safety check (``_kernels_jit.monitor``), then the tracker's apply, in one call."""
    step_h, step_d = monitor(ma, da, rows, g1, g2, margin, thresh, bound)
    _apply(ma, da, p, buf, n, nv)
    return step_h, step_d


# -- the reaching controller (ReachingController.__call__) -------------------------------------
@njit(cache=True, nogil=True)
def reach(ma, da, p, nb, out, n, nv, dof0, site, index, restore, t, t_prev, has_prev, a_max,
          kp, max_ee, max_js, lam2):  # pragma: no cover (compiled)
    """The DLS command toward goal ``index``, speed-capped and rate-limited, into ``out``.

    ``p``: addresses of the goal positions (g, 3) and of ``site_xpos``; ``nb``: the controller's
    buffer (the rate limit's previous command, a copy of it, and scratch). The rate limit's previous
    command becomes ``out`` (``restore``: first put back the copy, for a second call at the same tick).
    Returns the distance to the goal.
    """
    goal = _vec(p[0] + index * 24, 3)
    ee = _vec(p[1] + site * 24, 3)
    prev = nb[0:n]
    backup = nb[n: 2 * n]
    jac = nb[2 * n: 2 * n + 3 * nv]  # (3, nv), row-major
    a = nb[2 * n + 3 * nv: 2 * n + 3 * nv + 9]
    v = nb[2 * n + 3 * nv + 9: 2 * n + 3 * nv + 12]
    y = nb[2 * n + 3 * nv + 12: 2 * n + 3 * nv + 15]
    if restore:
        for i in range(n):
            prev[i] = backup[i]
    else:
        for i in range(n):
            backup[i] = prev[i]
    e0, e1, e2 = goal[0] - ee[0], goal[1] - ee[1], goal[2] - ee[2]
    dist = math.sqrt(((0.0 + e0 * e0) + e1 * e1) + e2 * e2)
    speed = kp * dist
    gain = kp if speed <= max_ee else max_ee / dist
    v[0], v[1], v[2] = e0 * gain, e1 * gain, e2 * gain
    jac_site(ma, da, jac.ctypes.data, 0, np.int32(site))
    # J J^T (sums.gram): each entry the products added in column order, from the first
    for r in range(3):
        for c in range(r, 3):
            s = jac[r * nv + dof0] * jac[c * nv + dof0]
            for k in range(1, n):
                s = s + jac[r * nv + dof0 + k] * jac[c * nv + dof0 + k]
            a[r * 3 + c] = s
            a[c * 3 + r] = s
    for r in range(3):
        for c in range(3):
            a[r * 3 + c] = a[r * 3 + c] + (lam2 if r == c else 0.0)
    chol_factor(a.ctypes.data, 3, 0.0)
    chol_solve(y.ctypes.data, a.ctypes.data, v.ctypes.data, 3)
    # u = y J (sums.combine3: ((0 + y0 J0) + y1 J1) + y2 J2), then the speed cap (the whole command scaled)
    peak = -1.0
    for k in range(n):
        col = dof0 + k
        uk = ((0.0 + y[0] * jac[col]) + y[1] * jac[nv + col]) + y[2] * jac[2 * nv + col]
        out[k] = uk
        m = abs(uk)
        if k == 0 or m > peak:
            peak = m
    if peak > max_js:
        f = max_js / peak
        for k in range(n):
            out[k] = out[k] * f
    # the rate limit (see nominal._RateLimit)
    if a_max != math.inf:
        if has_prev:
            dtk = t - t_prev
            step = (dtk if not (0.0 > dtk) else 0.0) * a_max
            peak = -1.0
            for k in range(n):
                m = abs(out[k] - prev[k])
                if k == 0 or m > peak:
                    peak = m
            if peak > step:
                f = step / peak
                for k in range(n):
                    out[k] = prev[k] + (out[k] - prev[k]) * f
        else:
            for k in range(n):
                out[k] = 0.0
    for k in range(n):
        prev[k] = out[k]
    return dist
