"""The numba kernels of :mod:`isf_robot.arm.kernels` (imported only when numba is installed).

Module-level functions, so numba's cache (``__pycache__``) serves later processes; MuJoCo's C
functions are resolved by symbol in the ``libmujoco`` the ``mujoco`` package loaded.
"""

from __future__ import annotations

import math

import llvmlite.binding as llvm
import numpy as np
from llvmlite import ir
from numba import carray, njit, types
from numba.extending import intrinsic

from isf_robot.core.jit import watch_compiles

from .libmujoco import library_path

watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)

_PATH = library_path()
if _PATH is None:  # (kernels._build treats this as "numba missing")
    raise ImportError("the mujoco package's libmujoco was not found")
llvm.load_library_permanently(_PATH)

_ptr, _i32, _f64 = types.intp, types.int32, types.float64
# mjtNum mj_geomDistance(const mjModel*, mjData*, int geom1, int geom2, mjtNum distmax, mjtNum fromto[6])
geom_distance = types.ExternalFunction("mj_geomDistance", _f64(_ptr, _ptr, _i32, _i32, _f64, _ptr))
# void mj_jac(const mjModel*, const mjData*, mjtNum* jacp, mjtNum* jacr, const mjtNum point[3], int body)
jac = types.ExternalFunction("mj_jac", types.void(_ptr, _ptr, _ptr, _ptr, _ptr, _i32))




def _pointer(kind: ir.Type, numba_type: types.Type):  # type: ignore[no-untyped-def]
    @intrinsic
    def cast(typingctx, addr):  # pragma: no cover (compile time)
        sig = types.CPointer(numba_type)(types.intp)

        def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
            return builder.inttoptr(args[0], ir.PointerType(kind))

        return sig, codegen

    return cast


f64p = _pointer(ir.DoubleType(), types.float64)
"""``f64p(addr)``: the address ``addr`` (an int) as a float64 pointer, for ``carray``."""
i64p = _pointer(ir.IntType(64), types.int64)
"""``i64p(addr)``: the address ``addr`` as an int64 pointer."""


@njit(cache=True, nogil=True, inline="always")
def row_norm(g, k):  # pragma: no cover (compiled)
    """|g[k]|: the squares added in column order from 0 (:func:`isf_robot.core.sums.row_norms`)."""
    s = 0.0
    for c in range(g.shape[1]):
        s += g[k, c] * g[k, c]
    return np.sqrt(s)


@njit(cache=True, nogil=True, inline="always")
def dot3(a0, a1, a2, b0, b1, b2):  # pragma: no cover (compiled)
    """``a . b`` of 3-vectors, ``((0 + a0 b0) + a1 b1) + a2 b2`` (:func:`isf_robot.core.sums.dots3`)."""
    return ((0.0 + a0 * b0) + a1 * b1) + a2 * b2


@njit(cache=True, nogil=True)
def near(ma, da, qpos, xpos, live, margin, thr2, coh, lower, qprev, qstate, lever, qadr,
         cutoff, distmax, slack, eps, dof, fromto, jac1, jac2, jq, jsign, joff, jgrad, norms_in,
         mocap, lin, dhdt_in, rows, h, g, gn, wit, lf):  # pragma: no cover (compiled)
    """Fill rows[:j], h[:j + l], g[:j + l], gn[:j + l] (with ``norms_in``) and wit[:j] = (p1, p2, n).

    With ``dhdt_in``: ``lf[k] = dh/dt = -n^T v`` (:func:`dot3`)
    of each near pair whose obstacle is mocap body ``mocap[r] >= 0``, ``v`` its row of ``lin``
    (flat, 3 per mocap body); ``lf`` is left alone otherwise.

    Returns (j, min h, min dist, min joint value, whether some witness points coincide, the key of the near
    pairs' set: the sum of ``2**r`` over their live rows ``r`` where there are at most 62 live rows, else -1).
    """
    n_live = live.shape[0]
    cand = np.empty(n_live, np.int64)
    nc = 0
    if coh:
        nu = qadr.size
        if qstate[0] != 0:
            dq = np.empty(nu)
            for u in range(nu):
                dq[u] = abs(qpos[qadr[u]] - qprev[u])
            for r in range(n_live):
                s = 0.0
                for u in range(nu):
                    s += lever[r, u] * dq[u]
                lower[r] -= s
        for u in range(nu):
            qprev[u] = qpos[qadr[u]]
        qstate[0] = 1
        for r in range(n_live):
            if lower[r] < cutoff:
                cand[nc] = r
                nc += 1
        dmax = distmax
    else:
        for r in range(n_live):
            a, b = live[r, 1], live[r, 2]
            dx = xpos[a, 0] - xpos[b, 0]
            dy = xpos[a, 1] - xpos[b, 1]
            dz = xpos[a, 2] - xpos[b, 2]
            if dx * dx + dy * dy + dz * dz < thr2[r]:
                cand[nc] = r
                nc += 1
        dmax = cutoff
    # Narrow phase: near pairs packed in rows 0, 1, ... of the scratch (a far one's row is reused).
    sel = np.empty(nc, np.int64)
    ds = np.empty(nc)
    j = 0
    for c in range(nc):
        r = cand[c]
        d = geom_distance(ma, da, np.int32(live[r, 1]), np.int32(live[r, 2]), dmax,
                          fromto[j].ctypes.data)
        if coh:
            lower[r] = d - slack
        if d < cutoff:
            sel[j] = r
            ds[j] = d
            j += 1
    ndof = dof.size
    nj = jq.size
    jmin = math.inf
    for i in range(nj):  # the joint-limit rows after the pairs'
        hj = jsign[i] * qpos[jq[i]] + joff[i]
        h[j + i] = hj
        jmin = min(jmin, hj)
        for c in range(ndof):
            g[j + i, c] = jgrad[i, c]
    hmin = math.inf
    dmin = math.inf
    touching = False
    key = 0 if n_live <= 62 else -1  # the set of near pairs, as bits of their live rows (-1: too many rows)
    for k in range(j):
        r = sel[k]
        if key >= 0:
            key |= 1 << r
        d = ds[k]
        rows[k] = live[r, 0]
        hk = d - margin[r]
        h[k] = hk
        hmin = min(hmin, hk)
        dmin = min(dmin, d)
        for e in range(3):
            wit[k, 0, e] = fromto[k, e]
            wit[k, 1, e] = fromto[k, 3 + e]
        if -eps < d < eps:
            touching = True
            continue
        inv = 1.0 / d
        n0 = (fromto[k, 0] - fromto[k, 3]) * inv
        n1 = (fromto[k, 1] - fromto[k, 4]) * inv
        n2 = (fromto[k, 2] - fromto[k, 5]) * inv
        wit[k, 2, 0], wit[k, 2, 1], wit[k, 2, 2] = n0, n1, n2
        if dhdt_in != 0 and mocap[r] >= 0:
            b = 3 * mocap[r]
            lf[k] = -dot3(n0, n1, n2, lin[b], lin[b + 1], lin[b + 2])
        jac(ma, da, jac1.ctypes.data, 0, fromto[k].ctypes.data, np.int32(live[r, 3]))
        for c in range(ndof):
            col = dof[c]
            g[k, c] = 0.0 + n0 * jac1[0, col] + n1 * jac1[1, col] + n2 * jac1[2, col]
        if live[r, 5] != 0:
            jac(ma, da, jac2.ctypes.data, 0, fromto[k, 3:].ctypes.data, np.int32(live[r, 4]))
            for c in range(ndof):
                col = dof[c]
                g[k, c] = g[k, c] - (0.0 + n0 * jac2[0, col] + n1 * jac2[1, col] + n2 * jac2[2, col])
    if norms_in != 0:
        for k in range(j + nj):
            gn[k] = row_norm(g, k)
    return j, hmin, dmin, jmin, touching, key

@njit(cache=True, nogil=True)
def monitor(ma, da, rows, g1, g2, margin, thresh, bound):  # pragma: no cover (compiled)
    step_h = math.inf
    step_d = math.inf
    for t in range(rows.size):
        i = rows[t]
        cap = max(thresh + margin[i], bound) + 1e-6
        d = geom_distance(ma, da, np.int32(g1[i]), np.int32(g2[i]), cap, 0)
        if d - margin[i] < step_h:
            step_h = d - margin[i]
        if d < step_d:
            step_d = d
    return step_h, step_d


# The tables of near_packed's P (addresses and sizes; see NarrowPhase._kernel_context).
(P_LIVE, P_NJ, P_NDOF, P_NV, P_NGEOM, P_NQ, P_NU, P_NLOWER, P_NFT, P_QPOS, P_XPOS, P_TAB, P_MARGIN, P_THR2,
 P_LOWER, P_QPREV, P_QSTATE, P_LEVER, P_QADR, P_DOF, P_FROMTO, P_JAC1, P_JAC2, P_JQ, P_JSIGN, P_JOFF,
 P_JGRAD, P_MOCAP) = range(28)


@njit(cache=True, nogil=True)
def near_packed_key(ma, da, p, blk, rows, coh, cutoff, distmax, slack, eps, norms_in, lin, dhdt_in):  # pragma: no cover
    """:func:`near` (and its key of the set of near pairs) with its tables as the addresses in ``p``.

    Its outputs go to ``blk``.

    One numba call costs about 0.1 us per 1-D array argument and 0.6 us per 2-D one; :func:`near`'s
    31 arguments cost more than its work. ``blk`` (float64, fresh per call) holds, for
    ``L = live pairs + joint rows`` and ``n`` dofs: ``h`` (L), ``g`` (L, n), ``gn`` (L), ``lf`` (L,
    zeroed here: the rows' ``dh/dt``, of moving obstacles filled here with ``dhdt_in``, else by the caller)
    and the witness points (live pairs, 3, 3). ``lin``: the mocap bodies' velocities, flat.
    """
    n_live, nj, n, nv = p[P_LIVE], p[P_NJ], p[P_NDOF], p[P_NV]
    nu, nlower = p[P_NU], p[P_NLOWER]
    qpos = carray(f64p(p[P_QPOS]), p[P_NQ])
    xpos = carray(f64p(p[P_XPOS]), (p[P_NGEOM], 3))
    live = carray(i64p(p[P_TAB]), (n_live, 6))
    margin = carray(f64p(p[P_MARGIN]), n_live)
    thr2 = carray(f64p(p[P_THR2]), n_live)
    lower = carray(f64p(p[P_LOWER]), nlower)
    qprev = carray(f64p(p[P_QPREV]), nu)
    qstate = carray(i64p(p[P_QSTATE]), 1)
    lever = carray(f64p(p[P_LEVER]), (nlower, nu))
    qadr = carray(i64p(p[P_QADR]), nu)
    dof = carray(i64p(p[P_DOF]), n)
    fromto = carray(f64p(p[P_FROMTO]), (p[P_NFT], 6))
    jac1 = carray(f64p(p[P_JAC1]), (3, nv))
    jac2 = carray(f64p(p[P_JAC2]), (3, nv))
    jq = carray(i64p(p[P_JQ]), nj)
    jsign = carray(f64p(p[P_JSIGN]), nj)
    joff = carray(f64p(p[P_JOFF]), nj)
    jgrad = carray(f64p(p[P_JGRAD]), (nj, n))
    mocap = carray(i64p(p[P_MOCAP]), n_live)
    m = n_live + nj
    h = blk[:m]
    g = blk[m: m + m * n].reshape((m, n))
    gn = blk[m + m * n: 2 * m + m * n]
    lf = blk[2 * m + m * n: 3 * m + m * n]
    wit = blk[3 * m + m * n: 3 * m + m * n + 9 * n_live].reshape((n_live, 3, 3))
    for i in range(m):
        lf[i] = 0.0
    return near(ma, da, qpos, xpos, live, margin, thr2, coh, lower, qprev, qstate, lever, qadr, cutoff, distmax,
                slack, eps, dof, fromto, jac1, jac2, jq, jsign, joff, jgrad, norms_in, mocap, lin, dhdt_in, rows, h, g,
                gn, wit, lf)


@njit(cache=True, nogil=True)
def near_packed(ma, da, p, blk, rows, coh, cutoff, distmax, slack, eps, norms_in, lin, dhdt_in):  # pragma: no cover
    """:func:`near_packed_key` without the key: (j, min h, min dist, min joint value, touching)."""
    j, hmin, dmin, jmin, touching, _ = near_packed_key(ma, da, p, blk, rows, coh, cutoff, distmax, slack, eps, norms_in,
                                                       lin, dhdt_in)
    return j, hmin, dmin, jmin, touching
