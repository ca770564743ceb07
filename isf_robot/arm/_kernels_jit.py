"""The collision kernels of :mod:`isf_robot.arm.kernels` (imported only when numba is installed).

Plain functions that :func:`~isf_robot.core.jit.compiled` compiles (:mod:`isf_robot.arm.kernels`
hands them out); the ones other kernels call are :func:`~isf_robot.core.jit.formula` functions.
What is here is what only compiled code can do: MuJoCo's C functions, resolved by symbol in the
``libmujoco`` the ``mujoco`` package loaded, called on raw addresses, and the loops over pairs
around them. The rows' formulas are those of :mod:`isf_robot.arm.narrow` and
:mod:`isf_robot.arm.joint_limits`, which the numpy path calls too.
"""

from __future__ import annotations

import math

import llvmlite.binding as llvm
import numpy as np
from llvmlite import ir
from numba import carray, types
from numba.extending import intrinsic

from isf_robot.core.jit import formula

from .joint_limits import joint_value
from .libmujoco import library_path
from .narrow import (
    P_DOF,
    P_FROMTO,
    P_JAC1,
    P_JAC2,
    P_JGRAD,
    P_JOFF,
    P_JQ,
    P_JSIGN,
    P_LEVER,
    P_LIVE,
    P_LOWER,
    P_MARGIN,
    P_MOCAP,
    P_NDOF,
    P_NFT,
    P_NGEOM,
    P_NJ,
    P_NLOWER,
    P_NQ,
    P_NU,
    P_NV,
    P_QADR,
    P_QPOS,
    P_QPREV,
    P_QSTATE,
    P_TAB,
    P_THR2,
    P_XPOS,
    dot3,
    obstacle_dhdt,
    pair_value,
    substep_distmax,
    unit_normal,
)

_PATH = library_path()
if _PATH is None:  # (kernels._build treats this as "numba missing")
    raise ImportError("the mujoco package's libmujoco was not found")
llvm.load_library_permanently(_PATH)

_ptr, _i32, _f64 = types.intp, types.int32, types.float64
# mjtNum mj_geomDistance(const mjModel*, mjData*, int geom1, int geom2, mjtNum distmax, mjtNum fromto[6])
geom_distance = types.ExternalFunction("mj_geomDistance", _f64(_ptr, _ptr, _i32, _i32, _f64, _ptr))
# void mj_jac(const mjModel*, const mjData*, mjtNum* jacp, mjtNum* jacr, const mjtNum point[3], int body)
jac = types.ExternalFunction("mj_jac", types.void(_ptr, _ptr, _ptr, _ptr, _ptr, _i32))
# void mj_mulM(const mjModel* m, const mjData* d, mjtNum* res, const mjtNum* vec)
mul_m = types.ExternalFunction("mj_mulM", types.void(_ptr, _ptr, _ptr, _ptr))
# void mj_jacSite(const mjModel* m, const mjData* d, mjtNum* jacp, mjtNum* jacr, int site)
jac_site = types.ExternalFunction("mj_jacSite", types.void(_ptr, _ptr, _ptr, _ptr, _i32))
# void mj_kinematics(const mjModel* m, mjData* d)
kinematics = types.ExternalFunction("mj_kinematics", types.void(_ptr, _ptr))
# void mj_comPos(const mjModel* m, mjData* d)
com_pos = types.ExternalFunction("mj_comPos", types.void(_ptr, _ptr))
# void mj_fullM(const mjModel* m, const mjData* d, mjtNum* dst)
full_m = types.ExternalFunction("mj_fullM", types.void(_ptr, _ptr, _ptr))
# void mj_solveM(const mjModel* m, mjData* d, mjtNum* x, const mjtNum* y, int n)
solve_m = types.ExternalFunction("mj_solveM", types.void(_ptr, _ptr, _ptr, _ptr, _i32))




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


@formula
def near(ma, da, qpos, xpos, live, margin, thr2, coh, lower, qprev, qstate, lever, qadr,
         cutoff, distmax, slack, eps, dof, fromto, jac1, jac2, jq, jsign, joff, jgrad, norms_in,
         mocap, lin, dhdt_in, rows, h, g, gn, wit, lf, given):  # pragma: no cover (compiled)
    """Fill rows[:j], h[:j + l], g[:j + l], gn[:j + l] (with ``norms_in``) and wit[:j] = (p1, p2, n).

    ``given`` (live rows; empty: the broad phase's or the bounds' candidates): exactly these pairs are measured, in
    this order, up to ``cutoff`` (without ``coh``; ``given`` may be ``rows``' first entries), and the near ones among
    them made rows (the torque level's difference of ``phi``: ``_second_order_jit.phi_rate``).

    ``rows`` (at least one entry per live pair) and ``h`` are its scratch too: their other entries are left as it used
    them.

    With ``dhdt_in``: ``lf[k] = dh/dt = -n^T v`` (``narrow.obstacle_dhdt``)
    of each near pair whose obstacle is mocap body ``mocap[r] >= 0``, ``v`` its row of ``lin``
    (flat, 3 per mocap body); ``lf`` is left alone otherwise.

    Returns (j, min h, min dist, min joint value, whether some witness points coincide, the key of the near
    pairs' set: the sum of ``2**r`` over their live rows ``r`` where there are at most 62 live rows, else -1).
    """
    n_live = live.shape[0]
    # Scratch without allocation: the candidates, then the near ones among them, in ``rows`` (n_live entries; each
    # read before its entry is written, at an index as large or larger), their distances in ``h`` (rows 0 .. j - 1,
    # each read before pair_value's h there; the joint rows go after them).
    cand = rows
    nc = 0
    if given.size:
        for c in range(given.size):
            cand[c] = given[c]
        nc = given.size
        dmax = cutoff
    elif coh:
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
    sel, ds = cand, h
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
        hj = joint_value(jsign[i], qpos[jq[i]], joff[i])
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
        hk = pair_value(d, margin[r])
        h[k] = hk
        hmin = min(hmin, hk)
        dmin = min(dmin, d)
        for e in range(3):
            wit[k, 0, e] = fromto[k, e]
            wit[k, 1, e] = fromto[k, 3 + e]
        if -eps < d < eps:
            touching = True
            continue
        n0 = unit_normal(fromto[k, 0], fromto[k, 3], d)
        n1 = unit_normal(fromto[k, 1], fromto[k, 4], d)
        n2 = unit_normal(fromto[k, 2], fromto[k, 5], d)
        wit[k, 2, 0], wit[k, 2, 1], wit[k, 2, 2] = n0, n1, n2
        if dhdt_in != 0 and mocap[r] >= 0:
            b = 3 * mocap[r]
            lf[k] = obstacle_dhdt(n0, n1, n2, lin[b], lin[b + 1], lin[b + 2])
        jac(ma, da, jac1.ctypes.data, 0, fromto[k].ctypes.data, np.int32(live[r, 3]))
        for c in range(ndof):
            col = dof[c]
            g[k, c] = dot3(n0, n1, n2, jac1[0, col], jac1[1, col], jac1[2, col])
        if live[r, 5] != 0:
            jac(ma, da, jac2.ctypes.data, 0, fromto[k, 3:].ctypes.data, np.int32(live[r, 4]))
            for c in range(ndof):
                col = dof[c]
                g[k, c] -= dot3(n0, n1, n2, jac2[0, col], jac2[1, col], jac2[2, col])
    if norms_in != 0:  # |dh/dq| of each row (the numpy path: np.linalg.norm; a loop here, no BLAS call per row)
        for k in range(j + nj):
            s = 0.0
            for c in range(ndof):
                s += g[k, c] * g[k, c]
            gn[k] = math.sqrt(s)
    return j, hmin, dmin, jmin, touching, key

@formula
def monitor(ma, da, rows, g1, g2, margin, thresh, bound):  # pragma: no cover (compiled)
    """The smallest ``h = dist - margin`` of the pairs ``rows`` at a physics sub-step (``SafetyMonitor.substep``)."""
    step_h = math.inf
    for t in range(rows.size):
        i = rows[t]
        d = geom_distance(ma, da, np.int32(g1[i]), np.int32(g2[i]), substep_distmax(thresh, margin[i], bound), 0)
        step_h = min(step_h, pair_value(d, margin[i]))
    return step_h


@formula
def near_packed_key(ma, da, p, blk, rows, coh, cutoff, distmax, slack, eps, norms_in, lin, dhdt_in):  # pragma: no cover
    """:func:`near_packed` of the broad phase's (or the bounds') candidates."""
    return near_packed(ma, da, p, blk, rows, coh, cutoff, distmax, slack, eps, norms_in, lin, dhdt_in, rows[:0])


@formula
def near_packed(ma, da, p, blk, rows, coh, cutoff, distmax, slack, eps, norms_in, lin, dhdt_in,
                given):  # pragma: no cover
    """:func:`near` (and its key of the set of near pairs) with its tables as the addresses in ``p``.

    Its outputs go to ``blk``.

    One numba call costs about 0.1 us per 1-D array argument and 0.6 us per 2-D one; :func:`near`'s
    31 arguments cost more than its work. ``blk`` (float64, uninitialised, shared with no result kept) holds, for
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
                gn, wit, lf, given)
