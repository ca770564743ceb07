"""The compiled difference of ``phi`` of the torque level's rows (:mod:`isf_robot.arm.kernels`; only with numba).

:meth:`SecondOrderRows.phi_rate <isf_robot.arm.second_order.SecondOrderRows.phi_rate>` evaluates the velocity
level's rows a second time, at ``(q + eps q_dot, t + eps)`` on a scratch ``MjData``, and differences their ``phi``.
From Python that is a dozen small numpy calls and the bindings' calls around one collision kernel call: most of the
torque level's barrier phase. :func:`phi_rate` does it in one call: the shifted ``qpos``, ``mj_kinematics`` and
``mj_comPos`` on the scratch data, the tick's pairs measured there by the probe's collision kernel
(``_kernels_jit.near_packed``, on the tables of its context, those pairs given), and the difference, with the
formulas of :mod:`isf_robot.arm.psi_law`, which the numpy path calls too. The two paths agree to rounding
(``tests/arm/test_second_order_kernel.py``). :func:`psi_tick` adds the tick's ``phi`` and the ``psi`` rows' Lie data
(:func:`~isf_robot.arm.psi_law.psi_rows`) around it: the whole barrier phase after the tick's rows.
:func:`psi_points` is the torque rollout's (:class:`~isf_robot.arm.torque_rollout.TorqueRollout`): the ``psi`` of
every row of the points the whole-rollout kernel made, put in the rollout's table by row key.
"""

from __future__ import annotations

import numpy as np
from numba import carray

from isf_robot.core.jit import formula

from ._kernels_jit import com_pos, f64p, kinematics, near_packed  # (importing it loads libmujoco; ImportError without)
from .narrow import P_LIVE, P_NDOF, P_NJ
from .psi_law import obstacle_rate, phi_difference, phi_rows, psi_rows, psi_value

DONE, TOUCHING, MISSING = 0, 1, 2
"""Returns of :func:`phi_rate` and :func:`psi_tick`: ``out`` filled (the rows made); witness points coincide at
the shifted state; a pair of ``rows`` is not among the probe's near pairs (the caller's numpy path handles both,
from the shifted state left in ``sa``)."""


@formula
def phi_rate(ma, sa, p, blk, prow, cutoff, eps_dist, lin, dhdt_in, qpos, sqpos, qadr, q_dot, eps, rows, phi, live_of,
             approaching, out):  # pragma: no cover (compiled)
    """``D phi`` of the pairs ``rows`` into ``out``: ``(phi(q + eps q_dot, t + eps) - phi) / eps``.

    ``sa``: the scratch data (its obstacles already where they are at ``t + eps``), which gets ``qpos`` with
    ``q_dot`` added at ``qadr`` (times ``eps``) and its kinematics. ``p``, ``blk``, ``prow``, ``cutoff``: the probe's
    packed kernel context on ``sa`` (no joints, no coherence), an output block and rows of its layout, its
    cut-off; ``lin``, ``dhdt_in``: the obstacles' velocities as ``near_packed_key`` takes them; ``live_of``: each
    pair's row among the context's live pairs (-1: none). The pairs ``rows`` alone are measured
    (``_kernels_jit.near_packed`` with them given), not every pair within the probe's cut-off: the rows the probe's
    near pairs would give them, for some half of the narrow phase's calls. Returns :data:`DONE`, :data:`TOUCHING` or
    :data:`MISSING` (a pair not within the probe's cut-off).
    """
    for i in range(qpos.size):
        sqpos[i] = qpos[i]
    for u in range(qadr.size):
        sqpos[qadr[u]] = qpos[qadr[u]] + eps * q_dot[u]
    kinematics(ma, sa)
    com_pos(ma, sa)
    K = rows.size
    if K > prow.size:  # (more rows than the probe has live pairs: some repeat; the NumPy path takes them)
        return TOUCHING
    for i in range(K):  # (the pairs' live rows, given to the kernel in prow: its scratch may hold them)
        r = live_of[rows[i]]
        if r < 0:
            return MISSING
        prow[i] = r
    j, _, _, _, touching, _ = near_packed(ma, sa, p, blk, prow, False, cutoff, cutoff, 0.0, eps_dist, 0, lin, dhdt_in,
                                          prow[:K])
    if touching:
        return TOUCHING
    if j < K:
        return MISSING
    n, m = p[P_NDOF], p[P_LIVE] + p[P_NJ]
    g = blk[m: m + m * n].reshape((m, n))
    lf = blk[2 * m + m * n: 3 * m + m * n]
    grad = np.empty((K, n))
    dhdt = np.empty(K)
    for i in range(K):
        grad[i] = g[i]
        dhdt[i] = lf[i]
    out[:] = phi_difference(phi_rows(grad, q_dot, obstacle_rate(dhdt, approaching)), phi, eps)
    return DONE


def psi_tick(ma, sa, p, blk, prow, cutoff, eps_dist, lin, dhdt_in, qpos, sqpos, qadr, q_dot, eps, rows, live_of,
             approaching, h, grad, dhdt, a0, minv, alpha_1, out):  # pragma: no cover (compiled)
    """The tick's ``psi`` rows (:func:`~isf_robot.arm.psi_law.psi_rows`) into ``out``: ``psi``, ``Lf psi``, ``Lg psi``.

    Of the rows ``h``, ``grad`` (k, n), ``dhdt`` (the pairs ``rows``, then the joint limits) on the terms ``a0``,
    ``minv``; ``D phi`` of the pairs by :func:`phi_rate` (the same arguments), zero for the joint limits. ``out``
    (k (n + 2),): ``psi`` (k), ``Lf psi`` (k), then ``Lg psi`` row by row (an array of the caller's: the rows
    handed to the filter are numpy's own). Returns :data:`DONE`, else :func:`phi_rate`'s code (``out`` not filled).
    """
    phi = phi_rows(grad, q_dot, obstacle_rate(dhdt, approaching))
    dphi = np.zeros(phi.size)
    nc = rows.size
    if nc:
        code = phi_rate(ma, sa, p, blk, prow, cutoff, eps_dist, lin, dhdt_in, qpos, sqpos, qadr, q_dot, eps, rows,
                        phi[:nc], live_of, approaching, dphi[:nc])
        if code != DONE:
            return code
    psi, lf, lg = psi_rows(h, grad, phi, dphi, a0, minv, alpha_1)
    k, n = grad.shape
    for i in range(k):
        out[i] = psi[i]
        out[k + i] = lf[i]
        for c in range(n):
            out[2 * k + i * n + c] = lg[i, c]
    return DONE


def psi_points(blk, keys, res, vs, nj, m, n, o_gn, o_lf, alpha_1, approaching, psi, gn, present):  # pragma: no cover
    """Rows ``1 .. len(res)`` of the rollout's tables ``psi``, ``gn`` (``|J|``), ``present`` (points + 1, keys).

    From the outputs of ``_rollout_jit.closed_loop_points`` (its rows with their ``|J|``, the joint limits'
    after the pairs): per point ``j`` (row ``j + 1``), each row's ``psi = J v + obstacle_rate(dh/dt) + alpha_1 h``
    with the point's joint velocity ``vs[j]``, at the column of its key ``keys[j]``. (The per-point views are of raw
    aliases of ``blk`` and ``vs``, as in ``_rollout_jit.closed_loop_points``: no reference counts.)
    """
    if not (blk.flags.c_contiguous and vs.flags.c_contiguous):  # (the aliases below read them as C arrays)
        raise ValueError("psi_points: blk and vs must be C-contiguous")
    blk, vs = carray(f64p(blk.ctypes.data), blk.shape), carray(f64p(vs.ctypes.data), vs.shape)
    for j in range(res.shape[0]):
        k = int(res[j, 0]) + nj
        grad = np.ascontiguousarray(blk[j, m: m + k * n]).reshape((k, n))
        dhdt = np.ascontiguousarray(blk[j, o_lf: o_lf + k])
        phi = phi_rows(grad, vs[j], obstacle_rate(dhdt, approaching))
        val = psi_value(phi, blk[j, :k], alpha_1)
        for i in range(k):
            key = keys[j, i]
            psi[j + 1, key] = val[i]
            gn[j + 1, key] = blk[j, o_gn + i]
            present[j + 1, key] = True
