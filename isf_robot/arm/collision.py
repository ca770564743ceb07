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
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from isf_robot.core import LieData
from isf_robot.core.exceptions import ConfigError, IsfWarning

from . import kernels
from .arms import geom_arms
from .batch import BarrierBatch
from .broadphase import BroadPhase, JointCoherence
from .clearance import Clearance, _ClearanceSearch
from .narrow import FilterRows, NarrowPhase, NearPairs, TickRows
from .pairs import CollisionPairs, collision_pairs

if TYPE_CHECKING:
    from .joint_limits import JointLimitBarriers
    from .scene import Scene

__all__ = ["CollisionBarriers", "FilterRows", "NearPairs", "TickRows"]

_G = mujoco.mjtGeom
# Type pairs whose penetration depth from mj_geomDistance (MuJoCo's primitive capsule-box
# contact generator) is not a signed distance: the witness points do not give its gradient.
_BAD_OVERLAP = {frozenset((int(_G.mjGEOM_CAPSULE), int(_G.mjGEOM_BOX)))}


class CollisionBarriers(NarrowPhase):
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
        jit: Use the compiled kernel of :mod:`isf_robot.arm.kernels` when it is available (the
            same formulas, equal to rounding; ``False``: always the numpy path).

    """

    def __init__(self, model: mujoco.MjModel, pairs: CollisionPairs, dof_adr: Sequence[int] | np.ndarray,
                 cutoff: float, *, jit: bool = True) -> None:
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
        b1arr = model.body_weldid[model.geom_bodyid[pairs.geom1]]
        self._b1 = b1arr.tolist()
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
        self._lie_names: tuple[tuple[str, ...] | None, dict[tuple[int, ...], tuple[str, ...]]] = (None, {})
        # The compiled kernel's tables: one row per live pair (pair, geom1, geom2, body1, body2, self).
        # (the kernels need the raw MjModel/MjData addresses the bindings expose as _address)
        self._kernel = kernels.near_kernel() if jit and getattr(model, "_address", 0) else None
        self._knorms = int(self._kernel is not None)  # 1: |dh/dq| in the kernel
        live = self.broadphase.live
        self._ktab = np.ascontiguousarray(np.stack(
            [live, pairs.geom1[live], pairs.geom2[live], b1arr[live], b2[live], pairs.is_self[live]], axis=1),
            dtype=np.int64)
        self._kmargin = np.ascontiguousarray(pairs.margin[live], dtype=float)
        self._kthr2 = np.ascontiguousarray(self.broadphase.thresh2, dtype=float)
        self._kfromto = np.zeros((max(live.size, 1), 6))
        self._kdof = np.ascontiguousarray(self.dof_adr, dtype=np.int64)
        self._kmocap = np.ascontiguousarray(self._mocap[live], dtype=np.int64)  # per live pair (-1: not moving)
        self._kdhdt = int(self._kernel is not None)  # 1: dh/dt in the kernel (narrow.obstacle_dhdt; 0: numpy)
        self._knolin = np.zeros(0)
        self._lin_shape = (model.nmocap, 3)
        self._kctx: tuple | None = None  # (see NarrowPhase._kernel_context)
        self._kout: tuple = (None, None)  # (a context, the output blocks of its layout; NarrowPhase._pool)
        self._kdirect: tuple = (None, None)  # (the kernel, its code for the call's argument types: jit.direct)
        self._kblocks: dict = {}
        self._tick_names: tuple = (None, {})  # (NarrowPhase._tick_key)
        self._kjac1 = np.zeros((3, model.nv))
        self._kjac2 = np.zeros((3, model.nv))
        self._knone = (np.zeros(0), np.zeros(0), np.zeros(1, dtype=np.int64), np.zeros((0, 0)),
                       np.zeros(0, dtype=np.int64))  # (no coherence bounds)
        self._kjoints = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), np.zeros((0, n)))  # (no joint rows)
        self._maddr = getattr(model, "_address", 0)
        self._kctxs: dict[tuple[int, int, int], tuple] = {}  # (the cache of NarrowPhase._kernel_context)

    @classmethod
    def from_scene(cls, scene: Scene) -> CollisionBarriers:
        """Barriers for a scene's robot and obstacle geoms with its config's margins."""
        bc = scene.config.barrier
        pairs = collision_pairs(scene.model, scene.robot_geom_ids, scene.obstacle_geom_ids,
                                margin=bc.margin, self_collision=scene.config.robot.self_collision,
                                self_margin=bc.self_margin,
                                arm_of=geom_arms(scene.arms, scene.robot_geom_ids) if scene.arms else None)
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
    def h_far(self) -> np.ndarray:
        """Barrier value of each pair beyond the cut-off, ``cutoff - margin``, shape (k,) (read-only)."""
        return self._h_far

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
        if self._kernel is None:
            return self._near_numpy(data, mocap_lin, mocap_ang, witness, coherence)
        return self._near_compiled(data, mocap_lin, mocap_ang, witness, coherence, None)[0]

    def rows(self, data: mujoco.MjData, joints: JointLimitBarriers, mocap_lin: np.ndarray | None = None, *,
             witness: bool = False, coherence: JointCoherence | None = None) -> FilterRows:
        """:meth:`near` and the joint-limit rows after it, stacked: the rows of a filter at the state.

        Args:
            data: As :meth:`near`.
            joints: The arm's joint-limit barriers (:class:`~isf_robot.arm.joint_limits.JointLimitBarriers`).
            mocap_lin: As :meth:`near`.
            witness: As :meth:`near`.
            coherence: As :meth:`near`.

        Returns:
            ``near`` and ``h``, ``grad`` of its pairs followed by the joint rows (``near.h`` and
            ``near.grad`` are views of their first rows), the smallest joint value, the norms (or
            ``None``) and ``dh/dt`` of the rows.

        """
        if self._kernel is not None:
            return self._near_compiled(data, mocap_lin, None, witness, coherence, joints)
        near = self._near_numpy(data, mocap_lin, None, witness, coherence)
        jh = joints.values(data)
        jl = jh.tolist()
        return FilterRows(near, np.concatenate((near.h, jh)), np.concatenate((near.grad, joints.grad)),
                          min(jl) if jl else math.inf, None, np.concatenate((near.dhdt, np.zeros(jh.size))))

    def lie(self, rows: FilterRows, joints: JointLimitBarriers) -> LieData:
        """The filter's Lie data of :meth:`rows` on the reduced model ``q_dot = u``: ``Lg h = dh/dq``, ``Lf h = dh/dt``.

        One row per near pair, then the joint limits, each named (``"<geom1>|<geom2>"``, then
        the joint names). The simulation and the rollout of the predictive off trigger both build
        their rows here. The names tuple of each set of near pairs is built once and shared.
        """
        g, gn = rows.grad, rows.grad_norm
        return LieData._of(rows.h, rows.lf, g, gn if gn is not None else np.linalg.norm(g, axis=1),
                           self._row_names(rows.near.row_list, joints))

    def lie_rows(self, data: mujoco.MjData, joints: JointLimitBarriers, mocap_lin: np.ndarray | None = None, *,
                 coherence: JointCoherence | None = None, witness: bool = False) -> TickRows:
        """``lie(rows(...))`` with what a control tick's accounting needs of ``rows(...)``, in one pass.

        The same Lie data (computed once, by the same path), and ``near.rows``, ``near.row_list`` (as a
        tuple), ``near.h_min``, ``near.dist_min``, ``joint_min`` of :meth:`rows` (arguments as there; the
        near pairs' witness points with ``witness``): the simulation's barrier phase. The compiled path builds no
        :class:`NearPairs` (nor its views of ``h``, ``dh/dq``, ``dh/dt``) for it.
        """
        if self._kernel is not None:
            return self._near_compiled(data, mocap_lin, None, witness, coherence, joints, True)  # type: ignore[return-value]
        return self._tick_rows(self.rows(data, joints, mocap_lin, witness=witness, coherence=coherence),  # type: ignore[return-value]
                               joints, True)

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
