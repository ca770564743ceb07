"""Collision barriers of the arm from MuJoCo geometry.

Collision barrier of a pair (robot geom 1, obstacle or robot geom 2)::

    h = min(dist(q, t), cutoff) - margin
    dh/dq = n^T (J_1(p_1) - J_2(p_2))        (0 while dist >= cutoff)
    dh/dt = -n^T v_2(p_2)                     (obstacle velocity at its witness point)

``dist`` is the signed distance of ``mujoco.mj_geomDistance`` (negative when the geoms
overlap: minus the penetration depth), ``p_1``, ``p_2`` its witness points on geom 1 and 2,
``n`` the unit vector that increases the distance when geom 1 moves along it, and ``J_i(p)``
the translational Jacobian of the point ``p`` fixed to geom i's body. Witness points:
``fromto[:3]`` lies on geom 1 and ``fromto[3:]`` on geom 2; when apart, ``p_1 - p_2`` points
from geom 2 to geom 1; when overlapping, it points the other way (each point lies inside the
other geom). In both cases ``n = (p_1 - p_2) / dist``. Saturating at ``cutoff`` keeps ``h``
continuous while the broad phase (:mod:`isf_robot.arm.broadphase`: bounding spheres,
``geom_rbound``) skips far pairs.

Accuracy (checked against finite differences, MuJoCo 4.0): exact for pairs among spheres,
capsules, boxes-vs-spheres and box-box; pairs routed through GJK/EPA (convex meshes,
cylinders, ellipsoids) are as accurate as the model's ``ccd_tolerance`` (our models set
1e-10); capsule-box pairs are exact while apart but wrong while overlapping (a warning
says so), so our models build boxes that capsules may touch as convex meshes. Where the
witness points are not unique (a capsule parallel to a face, crossing capsule axes) the
distance has a kink; the gradient returned is then that of the piece MuJoCo's witness
points belong to (a one-sided derivative), while central differences give the average.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, IsfWarning, ShapeError

from .batch import BarrierBatch
from .broadphase import BroadPhase, JointCoherence
from .clearance import Clearance, _ClearanceSearch
from .pairs import CollisionPairs, collision_pairs

if TYPE_CHECKING:
    from .scene import Scene

__all__ = ["CollisionBarriers", "NearPairs"]

_EPS_DIST = 1e-9  # [m] below this |dist| the witness points give no direction

_G = mujoco.mjtGeom
# Type pairs whose penetration depth from mj_geomDistance (MuJoCo's primitive capsule-box
# contact generator) is not a signed distance: the witness points do not give its gradient.
_BAD_OVERLAP = {frozenset((int(_G.mjGEOM_CAPSULE), int(_G.mjGEOM_BOX)))}


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


class CollisionBarriers:
    """Collision barriers ``h = min(dist, cutoff) - margin`` for a fixed set of geom pairs.

    Index arrays and scratch buffers are built once; :meth:`evaluate` returns fresh output
    arrays and keeps no state between calls (the scratch buffers are overwritten each call,
    so one instance must not be evaluated from two threads at once).

    Cost: the broad phase (one small product over the pairs that can ever come near; pairs
    that never can are found once, here), one ``mj_geomDistance`` per candidate pair and one
    ``mj_jac`` per pair closer than ``cutoff`` (two for robot-robot pairs), then a few numpy
    operations on those pairs only. Pairs that are not near cost one row of each output array
    (``benchmarks/broadphase_bench.py``: 64 far spheres, 896 extra pairs, add about 15%).

    Args:
        model: The model.
        pairs: The geom pairs (from :func:`~isf_robot.arm.pairs.collision_pairs`).
        dof_adr: The arm's dof addresses (columns of ``dh/dq``), shape (n,).
        cutoff: Broad-phase cut-off distance [m], > 0.

    """

    def __init__(self, model: mujoco.MjModel, pairs: CollisionPairs, dof_adr: Sequence[int] | np.ndarray,
                 cutoff: float) -> None:
        if not cutoff > 0:
            raise ConfigError(f"cutoff must be > 0 [m], got {cutoff}")
        if pairs.k == 0:
            raise ConfigError("no collision pairs left after filtering; excluded: "
                              f"{list(pairs.excluded)}")
        self.model = model
        self.pairs = pairs
        self.cutoff = float(cutoff)
        self.dof_adr = np.asarray(dof_adr, dtype=np.int64)
        self._all_dofs = bool(np.array_equal(self.dof_adr, np.arange(model.nv)))
        bad = [nm for nm, a, b in zip(pairs.names, pairs.geom1, pairs.geom2)
               if frozenset((int(model.geom_type[a]), int(model.geom_type[b]))) in _BAD_OVERLAP]
        if bad:
            warnings.warn(
                f"capsule-box pairs {bad}: MuJoCo's capsule-box collider does not return a signed "
                "distance when the geoms overlap, so dh/dq is wrong there; model the box as a "
                "convex mesh (8 vertices) to route the pair through GJK/EPA",
                IsfWarning, stacklevel=2)
        k, n = pairs.k, self.dof_adr.size
        self.broadphase = BroadPhase(model, pairs.geom1, pairs.geom2, self.cutoff)
        self._g1 = pairs.geom1.tolist()
        self._g2 = pairs.geom2.tolist()
        self._b1 = model.body_weldid[model.geom_bodyid[pairs.geom1]].tolist()
        self._b2 = model.body_weldid[model.geom_bodyid[pairs.geom2]].tolist()
        self._self = pairs.is_self.tolist()
        self._margin = pairs.margin
        self._marginl = pairs.margin.tolist()
        self._pair_geoms = np.stack([pairs.geom1, pairs.geom2], axis=1)
        self._pair_geoms.flags.writeable = False
        # Every output starts as the row of a pair beyond the cut-off (copied per call).
        self._h_far = self.cutoff - pairs.margin
        self._witness_far = np.full((k, 2, 3), np.nan)
        self._h_far_min = float(self._h_far.min())
        empty = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, n)), np.zeros(0),
                 np.zeros((0, 2, 3)))
        for arr in empty:
            arr.flags.writeable = False
        self._none = NearPairs(empty[0], [], empty[1], empty[2], empty[3], empty[4], math.inf, math.inf)
        self._grad_shape = (k, n)
        # Scratch buffers for the pairs within the cut-off, packed in rows 0, 1, ... (at most
        # one per live pair); overwritten on every call, never part of a returned result.
        m = max(self.broadphase.live.size, 1)
        self._fromto = np.zeros((m, 6))
        self._jac1 = np.zeros((m, 3, model.nv))
        self._jac2 = np.zeros((m, 3, model.nv))
        self._p1 = self._fromto[:, :3]
        self._p2 = self._fromto[:, 3:]
        self._ft_rows = [self._fromto[i] for i in range(m)]
        self._p1_rows = [self._fromto[i, :3] for i in range(m)]
        self._p2_rows = [self._fromto[i, 3:] for i in range(m)]
        self._j1_rows = [self._jac1[i] for i in range(m)]
        self._j2_rows = [self._jac2[i] for i in range(m)]
        # Mocap index of the obstacle side (-1: static or robot) for dh/dt.
        b2 = np.asarray(self._b2, dtype=np.int64)
        mocap = np.where(pairs.is_self, -1, model.body_mocapid[b2])
        self._mocap = mocap.astype(np.int64)
        self._is_moving = (self._mocap >= 0).tolist()
        self._any_moving = any(self._is_moving)
        self._any_self = any(self._self)
        self._all_live = self.broadphase.live.size == k
        self._obstacle_body = b2
        self._clearance = _ClearanceSearch(model, pairs)

    @classmethod
    def from_scene(cls, scene: Scene) -> CollisionBarriers:
        """Barriers for a scene's robot and obstacle geoms with its config's margins."""
        bc = scene.config.barrier
        pairs = collision_pairs(scene.model, scene.robot_geom_ids, scene.obstacle_geom_ids,
                                margin=bc.margin, self_collision=scene.config.robot.self_collision,
                                self_margin=bc.self_margin)
        return cls(scene.model, pairs, scene.dof_adr, bc.cutoff)

    @property
    def names(self) -> tuple[str, ...]:
        """Pair names, ``"<geom1>|<geom2>"``."""
        return self.pairs.names

    def evaluate(self, data: mujoco.MjData, mocap_lin: np.ndarray | None = None,
                 mocap_ang: np.ndarray | None = None) -> BarrierBatch:
        """Evaluate every pair at the state in ``data``.

        ``data`` must hold the kinematics of its current ``qpos`` and ``mocap_pos``:
        call ``mj_kinematics`` and ``mj_comPos`` (or ``mj_forward``) first; after
        ``mj_step`` they belong to the previous state.

        Args:
            data: The data.
            mocap_lin: Linear velocity of every mocap body [m/s], float array of shape
                (nmocap, 3) (rows indexed like ``data.mocap_pos``), or ``None`` for static
                obstacles (dh/dt = 0). :meth:`Scene.mocap_velocities` gives it.
            mocap_ang: Angular velocity of every mocap body [rad/s] about its origin, world
                frame, shape (nmocap, 3), or ``None`` (zero).

        Returns:
            The batch, one row per pair (rows beyond the cut-off: ``h = cutoff - margin``,
            zero gradient and ``dh/dt``, inactive, NaN witness points).

        """
        return self.batch(self.near(data, mocap_lin, mocap_ang, witness=True))

    def batch(self, near: NearPairs) -> BarrierBatch:
        """The full batch (one row per pair) of a :meth:`near` result taken with ``witness=True``."""
        p = self.pairs
        h = self._h_far.copy()
        active = np.zeros(p.k, dtype=bool)
        dhdt = np.zeros(p.k)
        grad = np.zeros(self._grad_shape)
        witness = self._witness_far.copy()
        idx = near.rows
        if idx.size:
            h[idx] = near.h
            grad[idx] = near.grad
            dhdt[idx] = near.dhdt
            active[idx] = True
            if near.witness is None:
                raise ConfigError("CollisionBarriers.batch needs near(..., witness=True)")
            witness[idx] = near.witness
        return BarrierBatch._of(h, grad, dhdt, p.names, active, witness, self._pair_geoms)

    @property
    def h_far_min(self) -> float:
        """Smallest barrier value a pair beyond the cut-off can have: ``min(cutoff - margin)``."""
        return self._h_far_min

    def near(self, data: mujoco.MjData, mocap_lin: np.ndarray | None = None,
             mocap_ang: np.ndarray | None = None, *, witness: bool = False,
             coherence: JointCoherence | None = None) -> NearPairs:
        """The pairs within the cut-off at the state in ``data``: the rows a filter needs.

        The same numbers as the active rows of :meth:`evaluate` (which is built on this), without
        the rows of far pairs (their barrier is ``cutoff - margin``, gradient and ``dh/dt`` zero).
        Needs the kinematics of the current state, like :meth:`evaluate`.

        Args:
            data: The MuJoCo data at the state (kinematics computed).
            mocap_lin: As :meth:`evaluate` (mocap linear velocities, for ``dh/dt``).
            mocap_ang: As :meth:`evaluate` (mocap angular velocities).
            witness: Also return the witness points (a copy).
            coherence: The run's distance bounds (:meth:`coherence`), for the states of one run
                in order: pairs they prove beyond the cut-off skip the narrow phase. The rows
                are the same as without.

        Returns:
            Fresh arrays (the empty result's arrays are shared and read-only).

        """
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
        dhdt = np.zeros(j)
        if self._any_moving and mocap_lin is not None:
            is_moving = self._is_moving
            moving = [t for t, i in enumerate(rows) if is_moving[i]]
            if moving:  # pairs with a mocap obstacle
                shape = (m.nmocap, 3)
                if mocap_lin.shape != shape or (mocap_ang is not None and mocap_ang.shape != shape):
                    raise ShapeError(f"mocap velocities must have shape {shape} (rows like "
                                     f"data.mocap_pos); got {mocap_lin.shape} and "
                                     f"{None if mocap_ang is None else mocap_ang.shape}")
                mp = idx[moving]
                mi = self._mocap[mp]
                v = mocap_lin[mi]
                if mocap_ang is not None and np.any(mocap_ang):
                    r = fr[moving, 3:] - data.xpos[self._obstacle_body[mp]]
                    v = v + _cross(mocap_ang[mi], r)
                dhdt[moving] = -np.einsum("ij,ij->i", n[moving], v)
        wit = fr.reshape(j, 2, 3).copy() if witness else None
        return NearPairs(idx, rows, np.array(hs), g, dhdt, wit, min(hs), min(ds))

    def coherence(self) -> JointCoherence | None:
        """Distance bounds for one run's states (:class:`~isf_robot.arm.broadphase.JointCoherence`).

        ``None`` where the joint angles do not capture the geoms' motion.
        """
        return JointCoherence.of(self.model, self.broadphase)

    def min_distance(self, data: mujoco.MjData) -> Clearance:
        """True minimum signed distance over this object's pairs (no cut-off, no margin).

        See :func:`~isf_robot.arm.clearance.min_distance`; needs the kinematics of the
        current state only.
        """
        return self._clearance(data)
