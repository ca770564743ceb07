"""The narrow phase of the collision barriers: the rows of the pairs within the cut-off.

:class:`NarrowPhase` is the part of :class:`~isf_robot.arm.collision.CollisionBarriers` that
evaluates the candidate pairs at a state, in two interchangeable ways with the same results bit
for bit: numpy around per-pair ``mj_geomDistance``/``mj_jac`` calls, and the compiled kernel of
:mod:`isf_robot.arm.kernels` (one call per state). The formulas are in
:mod:`isf_robot.arm.collision`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import mujoco
import numpy as np

from isf_robot.core.exceptions import ShapeError

if TYPE_CHECKING:
    from .broadphase import BroadPhase, JointCoherence
    from .joint_limits import JointLimitBarriers

__all__ = ["FilterRows", "NarrowPhase", "NearPairs"]

_EPS_DIST = 1e-9  # [m] below this |dist| the witness points give no direction

def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (k, 3) arrays (cheaper than ``np.cross`` for small k)."""
    i, j = [1, 2, 0], [2, 0, 1]
    return a[:, i] * b[:, j] - a[:, j] * b[:, i]


class NearPairs(NamedTuple):
    """The collision pairs within the cut-off at one state (:meth:`CollisionBarriers.near`).

    Attributes:
        rows: Their pair indices, ascending, shape (j,) int64.
        row_list: The same as a list.
        h: ``dist - margin``, shape (j,).
        grad: ``dh/dq``, shape (j, n).
        dhdt: ``dh/dt``, shape (j,).
        witness: Witness points (on geom 1, on geom 2) [m], shape (j, 2, 3), when asked for.
        h_min: Smallest ``h`` (``inf`` when no pair is near).
        dist_min: Smallest distance [m] (``inf`` when no pair is near).

    """

    rows: np.ndarray
    row_list: list[int]
    h: np.ndarray
    grad: np.ndarray
    dhdt: np.ndarray
    witness: np.ndarray | None
    h_min: float
    dist_min: float


class FilterRows(NamedTuple):
    """The rows of a filter at one state (:meth:`CollisionBarriers.rows`).

    Attributes:
        near: The collision pairs within the cut-off.
        h: Their ``h``, then the joint-limit values, shape (j + l,).
        grad: Their ``dh/dq``, then the joint-limit rows (``+-e_i``), shape (j + l, n).
        joint_min: The smallest joint-limit value (``inf`` without joint rows).
        grad_norm: ``sqrt(einsum("ij,ij->i", grad, grad))``, the same bits, shape (j + l,), or ``None``
            (not computed: the caller computes it).

    """

    near: NearPairs
    h: np.ndarray
    grad: np.ndarray
    joint_min: float
    grad_norm: np.ndarray | None = None


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

    def _near_compiled(self, data: mujoco.MjData, mocap_lin: np.ndarray | None, mocap_ang: np.ndarray | None,
                       witness: bool, coherence: JointCoherence | None,
                       joints: JointLimitBarriers | None
                       ) -> tuple[NearPairs, np.ndarray, np.ndarray, float, np.ndarray | None]:
        """:meth:`near` by the compiled kernel, with the joint rows of ``joints`` appended (see :meth:`rows`).

        The last item: the rows' norms ``|dh/dq|`` (only with ``joints``; ``None`` where numpy must
        compute them, see :func:`~isf_robot.arm.kernels.norm_lanes`).
        """
        if data is not self._data:
            self._data, self._daddr = data, data._address
        if coherence is None:
            lower, qprev, qstate, lever, qadr = self._knone
            distmax, slack = self.cutoff, 0.0
        else:
            lower, qprev, qstate, lever, qadr = coherence.lower, coherence.qprev, coherence.qstate, \
                coherence.lever, coherence.qadr
            distmax, slack = coherence.distmax, coherence.slack
        jq, jsign, joff, jgrad = self._kjoints if joints is None else joints.tables
        n_live, nj = self._ktab.shape[0], jq.size
        lanes = self._klanes if joints is not None else 0
        # Fresh outputs at their largest size (allocated here: arrays made inside a kernel cost more to return).
        rows, h, g = np.empty(n_live, dtype=np.int64), np.empty(n_live + nj), np.empty((n_live + nj, self.dof_adr.size))
        gn = np.empty(n_live + nj if lanes else 0)
        moving = self._any_moving and mocap_lin is not None
        wit = np.empty((n_live, 3, 3)) if witness or moving else self._kwit  # wit[k]: p1, p2, n (scratch if unused)
        j, h_min, dist_min, jmin, touching = self._kernel(
            self._maddr, self._daddr, data.qpos, data.geom_xpos, self._ktab, self._kmargin, self._kthr2,
            coherence is not None, lower, qprev, qstate, lever, qadr, self.cutoff, distmax, slack, _EPS_DIST,
            self.dof_adr, self._kfromto, self._kjac1, self._kjac2, jq, jsign, joff, jgrad, lanes,
            rows, h, g, gn, wit)
        k = j + nj
        if touching:  # coinciding witness points: the numpy path (the same rows without the bounds)
            near = self._near_numpy(data, mocap_lin, mocap_ang, witness, None)
            if joints is None:
                return near, near.h, near.grad, jmin, None
            return (near, np.concatenate((near.h, h[j:k])), np.concatenate((near.grad, joints.grad)),
                    jmin, None)
        if not j:
            return self._none, h[:k], g[:k], jmin, gn[:k] if lanes else None
        rows = rows[:j]
        row_list = rows.tolist()
        if moving:
            dhdt = self._dhdt(data, row_list, rows, wit[:j, 2], wit[:j, 1], mocap_lin, mocap_ang)
        else:
            dhdt = np.zeros(j)
        near = NearPairs._make((rows, row_list, h[:j], g[:j], dhdt, wit[:j, :2] if witness else None, h_min,
                                dist_min))  # (_make: tuple.__new__, cheaper than the generated __new__)
        return near, h[:k], g[:k], jmin, gn[:k] if lanes else None

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
                dhdt[moving] = -np.einsum("ij,ij->i", n[moving], v)
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
        hs = [d - marg[i] for d, i in zip(ds, rows)]
        for k, r in enumerate(sel):
            jac(m, data, j1r[k], None, p1r[r], b1[cand[r]])
        # n = (p1 - p2) / dist, as (p1 - p2) * (1 / dist); where the witness points coincide, the
        # direction between the geom centres.
        n = fr[:, :3] - fr[:, 3:]
        inv = [0.0 if -_EPS_DIST < d < _EPS_DIST else 1.0 / d for d in ds]
        touching = [r for r, v in enumerate(inv) if v == 0.0]  # (1/d is never 0 for a finite d)
        n *= np.array(inv)[:, None]
        idx = np.array(rows, dtype=np.int64)
        if touching:
            ti = idx[touching]
            c = data.geom_xpos[self.pairs.geom1[ti]] - data.geom_xpos[self.pairs.geom2[ti]]
            n[touching] = c / np.maximum(np.linalg.norm(c, axis=1, keepdims=True), 1e-12)
        n_row = n[:, None, :]
        g = np.matmul(n_row, self._jac1[:j])[:, 0]
        if self._any_self:
            selfs = [r for r, i in enumerate(rows) if self._self[i]]
            if selfs:
                b2, p2r, j2r = self._b2, self._p2_rows, self._j2_rows
                for k in selfs:
                    jac(m, data, j2r[k], None, p2r[sel[k]], b2[rows[k]])
                g[selfs] -= np.matmul(n_row[selfs], self._jac2[selfs])[:, 0]
        if not self._all_dofs:
            g = g[:, self.dof_adr]
        dhdt = self._dhdt(data, rows, idx, n, fr[:, 3:], mocap_lin, mocap_ang)
        wit = fr.reshape(j, 2, 3).copy() if witness else None
        return NearPairs(idx, rows, np.array(hs), g, dhdt, wit, min(hs), min(ds))
