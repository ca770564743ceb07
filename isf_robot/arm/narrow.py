"""The narrow phase of the collision barriers: the rows of the pairs within the cut-off.

:class:`NarrowPhase` is the part of :class:`~isf_robot.arm.collision.CollisionBarriers` that
evaluates the candidate pairs at a state, in two interchangeable ways: numpy around per-pair
``mj_geomDistance``/``mj_jac`` calls, and the compiled kernel of :mod:`isf_robot.arm.kernels` (one
call per state). Both compute a pair's row with the formulas here, one source each::

    h = dist - margin                       (pair_value)
    n = (p_1 - p_2) / dist                  (unit_normal, per component)
    dh/dq = n^T (J_1(p_1) - J_2(p_2))       (dot3 of n and each Jacobian column)
    dh/dt = -n^T v_2(p_2)                   (obstacle_dhdt: a moving obstacle's velocity at p_2)

(the numpy path calls them on arrays of all near pairs, the kernel on the scalars of one pair;
the two agree to rounding, ``tests/arm/test_kernels.py`` checks 1e-12 relative). The geometry is
in :mod:`isf_robot.arm.collision`; the types of the rows in :mod:`isf_robot.arm.rows`.
"""

from __future__ import annotations

from operator import itemgetter
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from isf_robot.core import LieData
from isf_robot.core.exceptions import ShapeError
from isf_robot.core.jit import direct, formula

from .output_blocks import BlockPool
from .rows import FilterRows, NearPairs, TickRows

if TYPE_CHECKING:
    from .broadphase import BroadPhase, JointCoherence
    from .joint_limits import JointLimitBarriers
    from .pairs import CollisionPairs

__all__ = ["FilterRows", "NarrowPhase", "NearPairs", "TickRows", "pair_value", "unit_normal", "dot3", "obstacle_dhdt",
           "substep_distmax"]

_F64 = np.dtype(np.float64)
_EPS_DIST = 1e-9  # [m] below this |dist| the witness points give no direction
_new = tuple.__new__  # a NamedTuple from a tuple of its fields (as _make, without the length check)
_BLOCK_FLOATS = 32768  # a control tick's outputs are allocated up to this many float64s (256 kB) at a time

# The tables of the packed kernel's address array ``p`` (``_kernels_jit.near_packed_key``; built by
# NarrowPhase._build_context): sizes first, then the arrays' addresses.
(P_LIVE, P_NJ, P_NDOF, P_NV, P_NGEOM, P_NQ, P_NU, P_NLOWER, P_NFT, P_QPOS, P_XPOS, P_TAB, P_MARGIN, P_THR2,
 P_LOWER, P_QPREV, P_QSTATE, P_LEVER, P_QADR, P_DOF, P_FROMTO, P_JAC1, P_JAC2, P_JQ, P_JSIGN, P_JOFF,
 P_JGRAD, P_MOCAP) = range(28)


@formula
def pair_value(dist, margin):  # type: ignore[no-untyped-def]
    """A pair's barrier value ``h = dist - margin`` [m] (floats or arrays)."""
    return dist - margin


@formula
def unit_normal(a, b, dist):  # type: ignore[no-untyped-def]
    """A component of the unit normal ``n = (p_1 - p_2) / dist`` (``a``, ``b``: that component of p_1, p_2).

    Floats, or arrays that broadcast (all near pairs' components at once). ``dist`` must not be
    near 0 (the callers treat ``|dist| < 1e-9`` apart).
    """
    return (a - b) / dist


@formula
def dot3(a0, a1, a2, b0, b1, b2):  # type: ignore[no-untyped-def]
    """``a . b`` of 3-vectors given by components (floats, or arrays that broadcast).

    ``dh/dq`` column ``c`` of a pair is ``dot3(n, J_1[:, c]) - dot3(n, J_2[:, c])``.
    """
    return a0 * b0 + a1 * b1 + a2 * b2


@formula
def obstacle_dhdt(n0, n1, n2, v0, v1, v2):  # type: ignore[no-untyped-def]
    """``dh/dt = -n^T v``: a pair's barrier rate from its obstacle's velocity ``v`` at the witness point [m/s]."""
    return -dot3(n0, n1, n2, v0, v1, v2)


@formula
def substep_distmax(thresh, margin, bound):  # type: ignore[no-untyped-def]
    """The ``distmax`` of a pair's distance call at a physics sub-step [m].

    ``max(thresh, bound) + margin + 1e-6``: a distance at or above it gives a barrier value ``dist - margin``
    that can change neither the run's minimum barrier ``thresh`` (>= 0) nor the control step's running
    minimum barrier ``bound`` (the safety monitor; ``-inf`` when only the run's minimum matters).
    """
    return max(thresh, bound) + margin + 1e-6


KERNEL_CONTEXTS = 4
"""Kernel contexts kept per :class:`NarrowPhase` (the episode's ``MjData`` and a rollout's scratch one, with room)."""


def _context_current(c: tuple, coherence: JointCoherence | None) -> bool:
    """Whether context ``c`` still points at ``coherence``'s bounds (:meth:`JointCoherence.reset` replaces them)."""
    return coherence is None or c[3] is coherence.lower


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (k, 3) arrays (cheaper than ``np.cross`` for small k)."""
    i, j = [1, 2, 0], [2, 0, 1]
    return a[:, i] * b[:, j] - a[:, j] * b[:, i]


class NarrowPhase:
    """Evaluation of the candidate pairs at a state.

    Mixed into :class:`~isf_robot.arm.collision.CollisionBarriers`, whose constructor sets the
    tables used here.
    """

    model: mujoco.MjModel
    cutoff: float
    broadphase: BroadPhase
    dof_adr: np.ndarray
    _none: NearPairs
    _kctx: tuple | None
    _kctxs: dict[tuple[int, int, int], tuple]
    _kout: tuple
    _kblocks: dict
    _kdirect: tuple  # (the kernel, its compiled code for the context's argument types: jit.direct)
    _lie_names: tuple
    _tick_names: tuple
    pairs: CollisionPairs

    def _kernel_context(self, data: mujoco.MjData, coherence: JointCoherence | None,
                        joints: JointLimitBarriers | None) -> tuple:
        """The packed kernel's tables for ``data``, ``coherence`` and ``joints``, from a small cache.

        Their addresses (``p``), sizes and the layout of the output block (see ``_kernels_jit.near_packed_key``).
        :data:`KERNEL_CONTEXTS` are kept, keyed by the three objects' ids (each entry holds them): the
        rollout's scratch ``MjData`` between two steps of the episode's costs a lookup, not two rebuilds.
        An entry is rebuilt when ``coherence.reset`` has replaced the bounds (the kernel writes into them).
        """
        key = (id(data), id(coherence), id(joints))
        cache = self._kctxs
        c = cache.get(key)
        if c is None or not _context_current(c, coherence):
            if c is None and len(cache) >= KERNEL_CONTEXTS:
                del cache[next(iter(cache))]  # (the oldest entry)
            c = cache[key] = self._build_context(data, coherence, joints)
        self._kctx = c
        return c

    def _block_lie(self, c: tuple, blk: np.ndarray, g: np.ndarray, rows: np.ndarray, j: int,
                   joints: JointLimitBarriers, key: int = -1) -> tuple[LieData, np.ndarray, tuple[int, ...]]:
        """Lie data (pairs, then joints), pair indices and tuple of an output ``blk`` of context ``c`` with ``j`` pairs.

        ``key``: the kernel's key of the set of near pairs (``near_packed_key``; -1: none, more than 62 live pairs,
        as at the torque level with the arm's own pairs: the bytes of the pair indices instead), under which the
        rows' names and tuple are kept (one lookup instead of a list, a tuple and the names' lookup).
        """
        k, o_gn, o_lf, norms_in = j + c[9], c[10], c[11], c[13]
        rows, gk = rows[:j], g[:k]  # (g: blk's (m, n) gradient view)
        if key < 0:  # (the set by its indices' bytes: a bytes key is never equal to an int key)
            key = rows.tobytes()  # type: ignore[assignment]
        tn = self._tick_names
        hit = tn[1].get(key) if tn[0] is joints.names else None
        if hit is None:
            hit = self._tick_key(key, rows.tolist(), joints)
        gn = blk[o_gn: o_gn + k] if norms_in else np.linalg.norm(gk, axis=1)
        return (LieData._of(blk[:k], blk[o_lf: o_lf + k], gk, gn, hit[0]),
                rows, hit[1])

    def _point_outputs(self, c: tuple, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``count`` output blocks of ``c`` in one allocation (a rollout's points): blk, its g views, rows.

        As fresh as a new allocation: one that nothing holds any more is reused (:class:`BlockPool`).
        """
        return self._pool(c, count).take_all()

    def _build_context(self, data: mujoco.MjData, coherence: JointCoherence | None,
                       joints: JointLimitBarriers | None) -> tuple:
        """The tables of :meth:`_kernel_context`, built."""
        if coherence is None:
            lower, qprev, qstate, lever, qadr = self._knone
            distmax, slack = self.cutoff, 0.0
        else:
            lower, qprev, qstate, lever, qadr = coherence.lower, coherence.qprev, coherence.qstate, \
                coherence.lever, coherence.qadr
            distmax, slack = coherence.distmax, coherence.slack
        jq, jsign, joff, jgrad = self._kjoints if joints is None else joints.tables
        f64 = (data.qpos, data.geom_xpos, self._kmargin, self._kthr2, lower, qprev, lever, self._kfromto, self._kjac1,
               self._kjac2, jsign, joff, jgrad)
        i64 = (self._ktab, qstate, qadr, self._kdof, jq, self._kmocap)
        if any(a.dtype != np.float64 or not a.flags.c_contiguous for a in f64) or any(
                a.dtype != np.int64 or not a.flags.c_contiguous for a in i64):
            raise TypeError("the collision kernel's tables must be C-contiguous float64/int64 arrays")
        n_live, nj, n = self._ktab.shape[0], jq.size, self.dof_adr.size
        p = np.zeros(28, dtype=np.int64)
        p[:9] = (n_live, nj, n, self.model.nv, data.geom_xpos.shape[0], data.qpos.size, qadr.size, lower.size,
                 self._kfromto.shape[0])
        arrays = {P_QPOS: data.qpos, P_XPOS: data.geom_xpos, P_TAB: self._ktab, P_MARGIN: self._kmargin,
                  P_THR2: self._kthr2, P_LOWER: lower, P_QPREV: qprev, P_QSTATE: qstate,
                  P_LEVER: lever, P_QADR: qadr, P_DOF: self._kdof, P_FROMTO: self._kfromto,
                  P_JAC1: self._kjac1, P_JAC2: self._kjac2, P_JQ: jq, P_JSIGN: jsign, P_JOFF: joff,
                  P_JGRAD: jgrad, P_MOCAP: self._kmocap}
        for slot, arr in arrays.items():
            p[slot] = arr.ctypes.data
        m = n_live + nj
        layout = (m, n, nj, m + m * n, 2 * m + m * n, 3 * m + m * n + 9 * n_live,  # offsets of gn and lf; size
                  self._knorms if joints is not None else 0, distmax, slack)
        return (data, coherence, joints, lower, p, int(data._address), arrays, *layout)

    def packed_arguments(self, data: mujoco.MjData) -> tuple | None:
        """The leading arguments of the packed kernel on ``data``, for a kernel that calls it (``None``: no kernel).

        ``(model address, data address, p, blk, rows, cutoff, eps)`` of ``_kernels_jit.near_packed_key`` without
        joint rows or coherence bounds, with an output block and rows of the context's layout that the caller
        reuses (read within its call: ``_second_order_jit.phi_rate``). The velocities: :meth:`packed_velocities`.
        """
        if self._kernel is None:
            return None
        c = self._kernel_context(data, None, None)
        return (self._maddr, c[5], c[4], np.empty(c[12]), np.empty(max(c[7], 1), dtype=np.int64), self.cutoff,
                _EPS_DIST)

    def packed_velocities(self, mocap_lin: np.ndarray | None) -> tuple[np.ndarray, int]:
        """``(lin, dhdt_in)`` of the packed kernel for the mocap velocities ``mocap_lin`` (nmocap, 3) or ``None``.

        The velocities flat and 1 where a pair's obstacle moves (its ``dh/dt`` made in the kernel, as :meth:`near`
        does), else an empty array and 0.
        """
        if not (self._any_moving and mocap_lin is not None):
            return self._knolin, 0
        if mocap_lin.shape != self._lin_shape:
            raise ShapeError(f"mocap velocities must have shape {self._lin_shape} (rows like data.mocap_pos); "
                             f"got {mocap_lin.shape}")
        return np.ascontiguousarray(mocap_lin, dtype=np.float64).reshape(-1), 1

    def _near_compiled(self, data: mujoco.MjData, mocap_lin: np.ndarray | None, mocap_ang: np.ndarray | None,
                       witness: bool, coherence: JointCoherence | None, joints: JointLimitBarriers | None,
                       tick: bool = False) -> FilterRows | TickRows:
        """:meth:`near` by the compiled kernel, with the joint rows of ``joints`` appended (see :meth:`rows`).

        With ``tick`` (and ``joints``): the :class:`TickRows` of :meth:`lie_rows` instead, made from the
        same outputs without the :class:`NearPairs` (where the rows are the kernel's alone).

        The fields after ``near``: ``h``, ``dh/dq``, the smallest joint value, the rows' norms ``|dh/dq|`` (only
        with ``joints``, else ``None``) and ``dh/dt`` (zero for the joint rows).
        """
        c = self._kctx
        if (c is None or c[0] is not data or c[1] is not coherence or c[2] is not joints
                or (coherence is not None and c[3] is not coherence.lower)):  # (a reset replaces the bounds)
            c = self._kernel_context(data, coherence, joints)
        _, _, _, _, p, daddr, _, m, n, nj, o_gn, o_lf, size, norms_in, distmax, slack = c
        out = self._kout
        if out[0] is not c:  # (another context: the output blocks of its layout)
            out = self._kout = (c, self._pool(c))
        blk, rows, g2 = out[1].take()  # (as fresh as new ones: BlockPool; arrays a kernel returns cost more)
        lin, dhdt_in = self._knolin, 0
        moving = self._any_moving and mocap_lin is not None
        if moving and self._kdhdt and mocap_ang is None:  # dh/dt in the kernel (obstacle_dhdt)
            if mocap_lin.shape != self._lin_shape:  # type: ignore[union-attr]
                raise ShapeError(f"mocap velocities must have shape {self._lin_shape} (rows like data.mocap_pos); "
                                 f"got {mocap_lin.shape}")  # type: ignore[union-attr]
            if not (type(mocap_lin) is np.ndarray and mocap_lin.dtype is _F64 and mocap_lin.flags.c_contiguous):
                mocap_lin = np.ascontiguousarray(mocap_lin, dtype=np.float64)
            lin, dhdt_in = mocap_lin.reshape(-1), self._kdhdt  # type: ignore[union-attr]
        kd = self._kdirect
        if kd[0] is not self._kernel:  # (its arrays are of fixed types: the context's and the output blocks')
            kd = self._kdirect = (self._kernel, direct(self._kernel, (
                self._maddr, daddr, p, blk, rows, coherence is not None, self.cutoff, distmax, slack, _EPS_DIST,
                norms_in, lin, dhdt_in)))
        j, h_min, dist_min, jmin, touching, key = kd[1](self._maddr, daddr, p, blk, rows, coherence is not None,
                                                        self.cutoff, distmax, slack, _EPS_DIST, norms_in, lin, dhdt_in)
        k = j + nj
        if touching:  # coinciding witness points: the numpy path (the same rows without the bounds)
            near = self._near_numpy(data, mocap_lin, mocap_ang, witness, None)
            lf = np.concatenate((near.dhdt, np.zeros(nj)))
            if joints is None:
                return _new(FilterRows, (near, near.h, near.grad, jmin, None, lf))
            fr = (near, np.concatenate((near.h, blk[j:k])), np.concatenate((near.grad, joints.grad)), jmin, None, lf)
            return self._tick_rows(_new(FilterRows, fr), joints, tick)
        if tick and not (moving and not dhdt_in):  # (lie_rows: the kernel's rows, without the NearPairs)
            lie, rows, row_list = self._block_lie(c, blk, g2, rows, j, joints, key)  # type: ignore[arg-type]
            wit = blk[o_lf + m: o_lf + m + 9 * j].reshape(j, 3, 3) if witness else None  # (p1, p2, n per pair)
            return _new(TickRows, (lie, rows, row_list, h_min, dist_min, jmin, wit))
        h, g, lf = blk[:k], g2[:k], blk[o_lf: o_lf + k]
        gn = blk[o_gn: o_gn + k] if norms_in else None
        if not j:
            return self._tick_rows(_new(FilterRows, (self._none, h, g, jmin, gn, lf)), joints, tick)
        rows = rows[:j]
        if witness or (moving and not dhdt_in):
            wit = blk[o_lf + m: o_lf + m + 9 * j].reshape(j, 3, 3)  # wit[k]: p1, p2, n
            if moving and not dhdt_in:
                dhdt = lf[:j] = self._dhdt(data, rows.tolist(), rows, wit[:, 2], wit[:, 1], mocap_lin, mocap_ang)
            else:
                dhdt = lf[:j]
            wit = wit[:, :2] if witness else None
        else:
            dhdt, wit = blk[o_lf: o_lf + j], None
        near = _new(NearPairs, (rows, rows.tolist(), blk[:j], g2[:j], dhdt, wit, h_min, dist_min))  # (no __new__ call)
        return self._tick_rows(_new(FilterRows, (near, h, g, jmin, gn, lf)), joints, tick)

    def _tick_rows(self, rows: FilterRows, joints: JointLimitBarriers | None, tick: bool) -> FilterRows | TickRows:
        """``rows``, or with ``tick`` its :class:`TickRows` (the general way: as without the kernel)."""
        if not tick:
            return rows
        near = rows.near
        return TickRows(self.lie(rows, joints), near.rows, tuple(near.row_list), near.h_min,  # type: ignore[arg-type]
                        near.dist_min, rows.joint_min, near.witness)

    def _tick_key(self, key: int | bytes, row_list: list[int], joints: JointLimitBarriers
                  ) -> tuple[tuple[str, ...], tuple[int, ...]]:
        """The names and the tuple of the rows ``row_list``, kept under the ``key`` of the set (``>= 0``, or bytes)."""
        hit = (self._row_names(row_list, joints), tuple(row_list))
        if type(key) is bytes or key >= 0:
            tn = self._tick_names
            if tn[0] is not joints.names or len(tn[1]) >= 4096:  # (another joint set, or bounded: start again)
                tn = self._tick_names = (joints.names, {})
            tn[1][key] = hit
        return hit

    def _row_names(self, row_list: list[int], joints: JointLimitBarriers) -> tuple[str, ...]:
        """The names of the rows: the near pairs' (``"<geom1>|<geom2>"``), then the joints'; built once per set."""
        cache = self._lie_names
        if cache[0] is not joints.names:  # (the names of another joint set: start again)
            cache = self._lie_names = (joints.names, {})
        key = tuple(row_list)
        names = cache[1].get(key)
        if names is None:
            if len(cache[1]) >= 4096:  # (bounded: a long run through many pair sets)
                cache[1].clear()
            pn = self.pairs.names
            pairs = itemgetter(*key)(pn) if len(key) > 1 else tuple(pn[i] for i in key)  # (one call: a tuple)
            names = cache[1][key] = pairs + joints.names
        return names

    def _pool(self, c: tuple, count: int = 0) -> BlockPool:
        """The output blocks of kernel context ``c``'s layout (one pool per layout, shared by contexts).

        ``count``: blocks per allocation, handed out together (a rollout's points); 0: a control tick's, one at a
        time, up to :data:`_BLOCK_FLOATS` floats per allocation.
        """
        m, n, nj, size = c[7], c[8], c[9], c[12]
        key = (m, n, nj, size, count)
        pool = self._kblocks.get(key)
        if pool is None:
            per = count or max(1, min(64, _BLOCK_FLOATS // max(size, 1)))
            pool = self._kblocks[key] = BlockPool(size, m, n, m - nj, per)
        return pool

    def _dhdt(self, data: mujoco.MjData, row_list: list[int], idx: np.ndarray, n: np.ndarray,
              p2: np.ndarray, mocap_lin: np.ndarray | None, mocap_ang: np.ndarray | None) -> np.ndarray:
        """``dh/dt = -n^T v_2(p_2)`` of the near pairs (zero for pairs with a static obstacle)."""
        dhdt = np.zeros(len(row_list))
        if self._any_moving and mocap_lin is not None:
            is_moving = self._is_moving
            moving = [t for t, i in enumerate(row_list) if is_moving[i]]
            if moving:  # pairs with a mocap obstacle
                shape = (self.model.nmocap, 3)
                if mocap_lin.shape != shape or (mocap_ang is not None and mocap_ang.shape != shape):
                    raise ShapeError(f"mocap velocities must have shape {shape} (rows like "
                                     f"data.mocap_pos); got {mocap_lin.shape} and "
                                     f"{None if mocap_ang is None else mocap_ang.shape}")
                mp = idx[moving]
                mi = self._mocap[mp]
                v = mocap_lin[mi]
                if mocap_ang is not None and np.any(mocap_ang):
                    r = p2[moving] - data.xpos[self._obstacle_body[mp]]
                    v = v + _cross(mocap_ang[mi], r)
                nm = n[moving]
                dhdt[moving] = obstacle_dhdt(nm[:, 0], nm[:, 1], nm[:, 2], v[:, 0], v[:, 1], v[:, 2])
        return dhdt

    def _near_numpy(self, data: mujoco.MjData, mocap_lin: np.ndarray | None, mocap_ang: np.ndarray | None,
                    witness: bool, coherence: JointCoherence | None) -> NearPairs:
        """:meth:`near` in numpy and per-pair MuJoCo calls (without the compiled kernel)."""
        m, cutoff = self.model, self.cutoff
        if coherence is None:
            cand = self.broadphase.candidates(data)
            distmax = cutoff
        else:
            live = coherence.candidates(data)
            cand = (live if self._all_live else self.broadphase.live[live]).tolist()
            distmax = coherence.distmax
        if not cand:
            return self._none
        gd, g1, g2, ft = mujoco.mj_geomDistance, self._g1, self._g2, self._ft_rows
        ds = [gd(m, data, g1[i], g2[i], distmax, ft[r]) for r, i in enumerate(cand)]
        if coherence is not None:
            coherence.update(live, ds)
        # Scratch row r holds candidate r's witness points; fr those of the near ones, packed.
        sel = [r for r, d in enumerate(ds) if d < cutoff]
        j = len(sel)
        if not j:
            return self._none
        if j < len(cand):
            rows = [cand[r] for r in sel]
            ds = [ds[r] for r in sel]
            fr = self._fromto.take(sel, 0)
        else:
            rows = cand
            fr = self._fromto[:j]
        marg, b1, p1r, j1r, jac = self._marginl, self._b1, self._p1_rows, self._j1_rows, mujoco.mj_jac
        hs = [pair_value(d, marg[i]) for d, i in zip(ds, rows)]
        for k, r in enumerate(sel):
            jac(m, data, j1r[k], None, p1r[r], b1[cand[r]])
        # n = (p1 - p2) / dist; where the witness points coincide, the direction between the geom centres.
        touching = [r for r, d in enumerate(ds) if -_EPS_DIST < d < _EPS_DIST]
        dcol = np.array(ds)[:, None]
        if touching:
            dcol[touching] = 1.0
        n = unit_normal(fr[:, :3], fr[:, 3:], dcol)
        idx = np.array(rows, dtype=np.int64)
        if touching:
            ti = idx[touching]
            c = data.geom_xpos[self.pairs.geom1[ti]] - data.geom_xpos[self.pairs.geom2[ti]]
            n[touching] = c / np.maximum(np.linalg.norm(c, axis=1, keepdims=True), 1e-12)
        n0, n1, n2 = n[:, 0, None], n[:, 1, None], n[:, 2, None]
        j1 = self._jac1[:j]
        g = dot3(n0, n1, n2, j1[:, 0], j1[:, 1], j1[:, 2])  # n^T J_1
        if self._any_self:
            selfs = [r for r, i in enumerate(rows) if self._self[i]]
            if selfs:
                b2, p2r, j2r = self._b2, self._p2_rows, self._j2_rows
                for k in selfs:
                    jac(m, data, j2r[k], None, p2r[sel[k]], b2[rows[k]])
                j2 = self._jac2[selfs]
                g[selfs] -= dot3(n0[selfs], n1[selfs], n2[selfs], j2[:, 0], j2[:, 1], j2[:, 2])
        if not self._all_dofs:
            g = g[:, self.dof_adr]
        dhdt = self._dhdt(data, rows, idx, n, fr[:, 3:], mocap_lin, mocap_ang)
        wit = fr.reshape(j, 2, 3).copy() if witness else None
        return NearPairs(idx, rows, np.array(hs), g, dhdt, wit, min(hs), min(ds))
