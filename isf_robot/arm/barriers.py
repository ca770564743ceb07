"""Barriers of the arm from MuJoCo geometry: collision pairs and joint limits.

The filter acts on the kinematic model ``q_dot = u + d`` of the n arm joints, so for every
barrier it needs ``h``, ``dh/dq`` (= ``Lg h``, shape (n,)) and the explicit time derivative
``dh/dt`` (= ``Lf h``: moving obstacles). :class:`BarrierBatch` carries them for k barriers.

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
continuous while the broad phase (bounding spheres, ``geom_rbound``) skips far pairs.

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
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, IsfWarning, ShapeError
from isf_robot.core.system import LieData

if TYPE_CHECKING:
    from .scene import Scene

__all__ = [
    "BarrierBatch",
    "stack_batches",
    "CollisionPairs",
    "collision_pairs",
    "CollisionBarriers",
    "JointLimitBarriers",
    "Clearance",
    "min_distance",
]

_EPS_DIST = 1e-9  # [m] below this |dist| the witness points give no direction

_G = mujoco.mjtGeom
# Type pairs whose penetration depth from mj_geomDistance (MuJoCo's primitive capsule-box
# contact generator) is not a signed distance: the witness points do not give its gradient.
_BAD_OVERLAP = {frozenset((int(_G.mjGEOM_CAPSULE), int(_G.mjGEOM_BOX)))}


@dataclass(frozen=True, eq=False)
class BarrierBatch:
    """Values and derivatives of k barriers at one state.

    Attributes:
        h: Barrier values, shape (k,) ([m] for collisions, [rad] for joint limits).
        grad: ``dh/dq`` w.r.t. the arm joints, shape (k, n).
        dhdt: Explicit time derivative ``dh/dt`` (moving obstacles), shape (k,).
        names: One label per barrier, e.g. ``"link2_geom|pole_a"`` or ``"j1:min"``.
        active: False where the pair was skipped by the cut-off (``h`` saturated, zero
            gradient), shape (k,).
        witness: Witness points (on geom 1, on geom 2) [m], shape (k, 2, 3); NaN for rows
            without geometry (joint limits) and for inactive pairs.
        pair_geoms: Geom ids of each pair, shape (k, 2); -1 for joint-limit rows.

    Arrays that do not change between calls (``pair_geoms``; the constant parts of
    joint-limit batches) are shared and read-only: copy them before modifying.

    """

    h: np.ndarray
    grad: np.ndarray
    dhdt: np.ndarray
    names: tuple[str, ...]
    active: np.ndarray
    witness: np.ndarray
    pair_geoms: np.ndarray

    @property
    def k(self) -> int:
        """Number of barriers."""
        return int(self.h.shape[0])

    def to_lie_data(self) -> LieData:
        """The core's :class:`~isf_robot.core.system.LieData` for ``q_dot = u + d``.

        With f0 = 0 and g = I: ``Lf h = dh/dt``, ``Lg h = dh/dq``, ``|dh/dx| = |dh/dq|``.
        """
        return LieData(h=self.h, lf=self.dhdt, lg=self.grad,
                       grad_norm=np.linalg.norm(self.grad, axis=1), names=self.names)


def stack_batches(*batches: BarrierBatch) -> BarrierBatch:
    """Concatenate batches row-wise (all must have the same number of joints n)."""
    if not batches:
        raise ConfigError("stack_batches needs at least one batch")
    n = {b.grad.shape[1] for b in batches}
    if len(n) != 1:
        raise ShapeError(f"batches have different joint counts {sorted(n)}")
    return BarrierBatch(
        h=np.concatenate([b.h for b in batches]),
        grad=np.concatenate([b.grad for b in batches]),
        dhdt=np.concatenate([b.dhdt for b in batches]),
        names=tuple(x for b in batches for x in b.names),
        active=np.concatenate([b.active for b in batches]),
        witness=np.concatenate([b.witness for b in batches]),
        pair_geoms=np.concatenate([b.pair_geoms for b in batches]),
    )


# ----------------------------------------------------------------------------- pairs


@dataclass(frozen=True, eq=False)
class CollisionPairs:
    """The geom pairs that get a collision barrier, after filtering.

    Attributes:
        geom1: Robot geom id of each pair, shape (k,).
        geom2: Obstacle (or, for self pairs, robot) geom id, shape (k,).
        margin: Margin per pair [m], shape (k,).
        is_self: True for robot-robot pairs, shape (k,).
        names: ``"<geom1>|<geom2>"`` per pair.
        excluded: ``(name, reason)`` of every candidate pair that was filtered out.

    """

    geom1: np.ndarray
    geom2: np.ndarray
    margin: np.ndarray
    is_self: np.ndarray
    names: tuple[str, ...]
    excluded: tuple[tuple[str, str], ...]

    @property
    def k(self) -> int:
        """Number of pairs."""
        return int(self.geom1.shape[0])


def _exclusion_reason(model: mujoco.MjModel, g1: int, g2: int) -> str | None:
    b1, b2 = int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])
    w1, w2 = int(model.body_weldid[b1]), int(model.body_weldid[b2])
    if w1 == w2:
        return "same body"
    if w1 != 0 and w2 != 0:
        p1 = int(model.body_weldid[model.body_parentid[w1]])
        p2 = int(model.body_weldid[model.body_parentid[w2]])
        if p1 == w2 or p2 == w1:
            return "parent-child"
    ct1, ca1 = int(model.geom_contype[g1]), int(model.geom_conaffinity[g1])
    ct2, ca2 = int(model.geom_contype[g2]), int(model.geom_conaffinity[g2])
    if not (ct1 & ca2 or ct2 & ca1):
        return "contype/conaffinity"
    sig = {(b1 << 16) + b2, (b2 << 16) + b1}
    if model.nexclude and sig & {int(s) for s in model.exclude_signature}:
        return "excluded in MJCF"
    return None


def collision_pairs(
    model: mujoco.MjModel,
    robot_geoms: Sequence[int] | np.ndarray,
    obstacle_geoms: Sequence[int] | np.ndarray,
    *,
    margin: float,
    self_collision: bool = False,
    self_margin: float = 0.0,
) -> CollisionPairs:
    """Build the filtered robot-obstacle (and optionally robot-robot) pairs.

    A candidate pair is dropped when both geoms are on the same (welded) body, on a parent
    and child body (unless one is the world), when their contype/conaffinity bits exclude
    contact, or when the MJCF has an ``<exclude>`` for their bodies. Robot-robot pairs (only
    with ``self_collision``) are taken once per unordered pair.

    Args:
        model: The model.
        robot_geoms: Robot geom ids.
        obstacle_geoms: Obstacle geom ids.
        margin: Robot-obstacle margin [m].
        self_collision: Add the non-adjacent robot-robot pairs.
        self_margin: Robot-robot margin [m].

    Returns:
        The pairs, robot-obstacle first.

    """
    def name(g: int) -> str:
        return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"

    cands = [(int(r), int(o), False) for r in robot_geoms for o in obstacle_geoms]
    if self_collision:
        rg = [int(g) for g in robot_geoms]
        cands += [(rg[i], rg[j], True) for i in range(len(rg)) for j in range(i + 1, len(rg))]
    keep, excluded = [], []
    for g1, g2, is_self in cands:
        why = _exclusion_reason(model, g1, g2)
        if why is None:
            keep.append((g1, g2, is_self))
        else:
            excluded.append((f"{name(g1)}|{name(g2)}", why))
    return CollisionPairs(
        geom1=np.array([p[0] for p in keep], dtype=np.int64),
        geom2=np.array([p[1] for p in keep], dtype=np.int64),
        margin=np.array([self_margin if p[2] else margin for p in keep], dtype=float),
        is_self=np.array([p[2] for p in keep], dtype=bool),
        names=tuple(f"{name(p[0])}|{name(p[1])}" for p in keep),
        excluded=tuple(excluded),
    )


# ----------------------------------------------------------------------------- collisions


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (k, 3) arrays (cheaper than ``np.cross`` for small k)."""
    i, j = [1, 2, 0], [2, 0, 1]
    return a[:, i] * b[:, j] - a[:, j] * b[:, i]


class CollisionBarriers:
    """Collision barriers ``h = min(dist, cutoff) - margin`` for a fixed set of geom pairs.

    Index arrays and scratch buffers are built once; :meth:`evaluate` returns fresh output
    arrays and keeps no state between calls (the scratch buffers are overwritten each call,
    so one instance must not be evaluated from two threads at once).

    Cost: one ``mj_geomDistance`` per pair that passes the bounding-sphere test and one
    ``mj_jac`` per pair closer than ``cutoff`` (two for robot-robot pairs), plus about a dozen
    small numpy operations; 12-23 us per call on the shipped scenes (4-56 pairs).

    Args:
        model: The model.
        pairs: The geom pairs (from :func:`collision_pairs`).
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
        k = pairs.k
        self._g1 = pairs.geom1.tolist()
        self._g2 = pairs.geom2.tolist()
        # Broad phase: active when |c1 - c2| < cutoff + r1 + r2 (always when a geom is unbounded).
        rb1, rb2 = model.geom_rbound[pairs.geom1], model.geom_rbound[pairs.geom2]
        thresh = np.where((rb1 == 0) | (rb2 == 0), np.inf, self.cutoff + rb1 + rb2)
        self._thresh2 = thresh**2
        self._b1 = model.body_weldid[model.geom_bodyid[pairs.geom1]].tolist()
        self._b2 = model.body_weldid[model.geom_bodyid[pairs.geom2]].tolist()
        self._self = pairs.is_self.tolist()
        self._has_self = bool(pairs.is_self.any())
        # diff = D @ geom_xpos gives c1 - c2 for every pair in one product.
        self._dmat = np.zeros((k, model.ngeom))
        self._dmat[np.arange(k), pairs.geom1] += 1.0
        self._dmat[np.arange(k), pairs.geom2] -= 1.0
        self._pair_geoms = np.stack([pairs.geom1, pairs.geom2], axis=1)
        self._pair_geoms.flags.writeable = False
        # Scratch buffers, overwritten on every call (never part of a returned result).
        self._fromto = np.zeros((k, 6))
        self._dist = np.zeros(k)
        self._inv = np.zeros(k)
        self._jac1 = np.zeros((k, 3, model.nv))
        self._jac2 = np.zeros((k, 3, model.nv))
        self._p1 = self._fromto[:, :3]
        self._p2 = self._fromto[:, 3:]
        self._n = np.zeros((k, 3))
        self._n_row = self._n[:, None, :]
        self._inv_col = self._inv[:, None]
        self._ft_rows = [self._fromto[i] for i in range(k)]
        self._p1_rows = [self._fromto[i, :3] for i in range(k)]
        self._p2_rows = [self._fromto[i, 3:] for i in range(k)]
        self._j1_rows = [self._jac1[i] for i in range(k)]
        self._j2_rows = [self._jac2[i] for i in range(k)]
        # Mocap index of the obstacle side (-1: static or robot) for dh/dt.
        b2 = np.asarray(self._b2, dtype=np.int64)
        mocap = np.where(pairs.is_self, -1, model.body_mocapid[b2])
        self._mocap = mocap.astype(np.int64)
        self._is_moving = (self._mocap >= 0).tolist()
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
            The batch, one row per pair.

        """
        m = self.model
        p = self.pairs
        diff = self._dmat @ data.geom_xpos
        candidates = np.nonzero(np.einsum("ij,ij->i", diff, diff) < self._thresh2)[0].tolist()

        dist, inv = self._dist, self._inv
        dist.fill(self.cutoff)
        inv.fill(0.0)
        g1, g2, b1, b2, cutoff = self._g1, self._g2, self._b1, self._b2, self.cutoff
        ft, p1r, p2r, j1r, j2r = (self._ft_rows, self._p1_rows, self._p2_rows, self._j1_rows,
                                  self._j2_rows)
        is_self, is_moving = self._self, self._is_moving
        geom_distance, jac = mujoco.mj_geomDistance, mujoco.mj_jac
        touching, moving = [], []
        for i in candidates:
            di = geom_distance(m, data, g1[i], g2[i], cutoff, ft[i])
            if di >= cutoff:
                continue
            dist[i] = di
            jac(m, data, j1r[i], None, p1r[i], b1[i])
            if is_self[i]:
                jac(m, data, j2r[i], None, p2r[i], b2[i])
            elif is_moving[i]:
                moving.append(i)
            if -_EPS_DIST < di < _EPS_DIST:
                touching.append(i)
            else:
                inv[i] = 1.0 / di

        # n = (p1 - p2) / dist on active rows, 0 elsewhere (inv = 0 there).
        n = self._n
        np.subtract(self._p1, self._p2, out=n)
        n *= self._inv_col
        if touching:  # witness points coincide: use the direction between the geom centres
            c = diff[touching]
            n[touching] = c / np.maximum(np.linalg.norm(c, axis=1, keepdims=True), 1e-12)
        grad = np.matmul(self._n_row, self._jac1)[:, 0]
        if self._has_self:
            grad -= np.matmul(self._n_row, self._jac2)[:, 0]
        if not self._all_dofs:
            grad = grad[:, self.dof_adr]

        active = dist < cutoff
        dhdt = np.zeros(p.k)
        if moving and mocap_lin is not None:  # active pairs with a mocap obstacle
            shape = (self.model.nmocap, 3)
            if mocap_lin.shape != shape or (mocap_ang is not None and mocap_ang.shape != shape):
                raise ShapeError(f"mocap velocities must have shape {shape} (rows like "
                                 f"data.mocap_pos); got {mocap_lin.shape} and "
                                 f"{None if mocap_ang is None else mocap_ang.shape}")
            mi = self._mocap[moving]
            v = mocap_lin[mi]
            if mocap_ang is not None and np.any(mocap_ang):
                r = self._p2[moving] - data.xpos[self._obstacle_body[moving]]
                v = v + _cross(mocap_ang[mi], r)
            dhdt[moving] = -np.einsum("ij,ij->i", n[moving], v)

        witness = np.where(active[:, None, None], self._fromto.reshape(-1, 2, 3), np.nan)
        return BarrierBatch(h=dist - p.margin, grad=grad, dhdt=dhdt, names=p.names,
                            active=active, witness=witness, pair_geoms=self._pair_geoms)

    def min_distance(self, data: mujoco.MjData) -> Clearance:
        """True minimum signed distance over this object's pairs (no cut-off, no margin).

        See :func:`min_distance`; needs the kinematics of the current state only.
        """
        return self._clearance(data)


# ----------------------------------------------------------------------------- joint limits


class JointLimitBarriers:
    """Joint-limit barriers ``h = q - q_min - margin`` and ``h = q_max - margin - q``.

    Rows are ordered ``[j1:min, j1:max, j2:min, ...]`` over the limited joints;
    ``dh/dq`` is ``+e_i`` / ``-e_i``, ``dh/dt = 0``.

    Args:
        qpos_adr: qpos addresses of the arm joints, shape (n,).
        joint_range: Limits [rad or m], shape (n, 2); unlimited joints (inf) get no rows.
        margin: Margin [rad or m], >= 0.
        joint_names: One name per joint.

    """

    def __init__(self, qpos_adr: Sequence[int] | np.ndarray, joint_range: np.ndarray, margin: float,
                 joint_names: Sequence[str]) -> None:
        rng = np.asarray(joint_range, dtype=float)
        n = len(qpos_adr)
        if rng.shape != (n, 2) or len(joint_names) != n:
            raise ShapeError(f"joint_range must have shape ({n}, 2) and {n} names; got "
                             f"{rng.shape} and {len(joint_names)} names")
        if margin < 0:
            raise ConfigError(f"joint-limit margin must be >= 0 [rad], got {margin}")
        limited = np.nonzero(np.isfinite(rng).all(axis=1))[0]
        width = rng[limited, 1] - rng[limited, 0]
        if np.any(width <= 2 * margin):
            raise ConfigError(f"joint-limit margin {margin} leaves no room in some joint range")
        self._qadr = np.repeat(np.asarray(qpos_adr, dtype=np.int64)[limited], 2)
        self._sign = np.tile([1.0, -1.0], limited.size)
        self._offset = np.empty(2 * limited.size)
        self._offset[0::2] = -(rng[limited, 0] + margin)
        self._offset[1::2] = rng[limited, 1] - margin
        self._grad = np.zeros((2 * limited.size, n))
        self._grad[np.arange(2 * limited.size), np.repeat(limited, 2)] = self._sign
        self.names = tuple(f"{joint_names[int(i)]}:{s}" for i in limited for s in ("min", "max"))
        # Constant parts of every result, shared between calls and therefore read-only.
        k = self._sign.size
        self._const = {
            "grad": self._grad, "dhdt": np.zeros(k), "active": np.ones(k, dtype=bool),
            "witness": np.full((k, 2, 3), np.nan), "pair_geoms": np.full((k, 2), -1, dtype=np.int64),
        }
        for arr in self._const.values():
            arr.flags.writeable = False

    @classmethod
    def from_scene(cls, scene: Scene) -> JointLimitBarriers:
        """Limits of a scene's arm joints with its config's joint margin."""
        return cls(scene.qpos_adr, scene.joint_range, scene.config.barrier.joint_margin,
                   scene.joint_names)

    def evaluate(self, data: mujoco.MjData) -> BarrierBatch:
        """Barrier rows at ``data.qpos`` (no kinematics needed).

        Only ``h`` is computed; ``grad``, ``dhdt``, ``active``, ``witness`` and ``pair_geoms``
        are constant, shared, read-only arrays.
        """
        h = self._sign * data.qpos[self._qadr] + self._offset
        return BarrierBatch(h=h, names=self.names, **self._const)


# ----------------------------------------------------------------------------- clearance


@dataclass(frozen=True)
class Clearance:
    """Smallest signed distance over a set of pairs.

    Attributes:
        distance: Signed distance [m] (negative: penetration depth).
        index: Index of the closest pair.
        name: Its name.

    """

    distance: float
    index: int
    name: str


class _ClearanceSearch:
    """Precomputed index arrays for :func:`min_distance` over a fixed set of pairs."""

    def __init__(self, model: mujoco.MjModel, pairs: CollisionPairs) -> None:
        k = pairs.k
        self.model = model
        self.names = pairs.names
        self.g1, self.g2 = pairs.geom1.tolist(), pairs.geom2.tolist()
        self.dmat = np.zeros((k, model.ngeom))
        self.dmat[np.arange(k), pairs.geom1] += 1.0
        self.dmat[np.arange(k), pairs.geom2] -= 1.0
        rb1, rb2 = model.geom_rbound[pairs.geom1], model.geom_rbound[pairs.geom2]
        # Unbounded geoms (planes, rbound 0) get an infinite allowance: always searched first.
        self.rbsum = np.where((rb1 == 0) | (rb2 == 0), np.inf, rb1 + rb2)

    def __call__(self, data: mujoco.MjData) -> Clearance:
        diff = self.dmat @ data.geom_xpos
        bound = np.sqrt(np.einsum("ij,ij->i", diff, diff)) - self.rbsum
        order = np.argsort(bound).tolist()
        bounds = bound.tolist()
        m, g1, g2 = self.model, self.g1, self.g2
        geom_distance = mujoco.mj_geomDistance
        best, best_i = math.inf, order[0]
        for i in order:
            if bounds[i] >= best:
                break
            d = geom_distance(m, data, g1[i], g2[i], best if best < math.inf else 1e6, None)
            if d < best:
                best, best_i = d, i
        return Clearance(distance=float(best), index=int(best_i), name=self.names[best_i])


def min_distance(model: mujoco.MjModel, data: mujoco.MjData, pairs: CollisionPairs) -> Clearance:
    """True minimum signed distance over all pairs: no cut-off, no margin, no Jacobians.

    Pairs are visited in order of their bounding-sphere distance (a lower bound on the true
    distance) and the search stops once that bound exceeds the best distance found.
    Needs the kinematics of the current state (``mj_kinematics`` or ``mj_forward``).
    :meth:`CollisionBarriers.min_distance` does the same with its index arrays precomputed.
    """
    return _ClearanceSearch(model, pairs)(data)
