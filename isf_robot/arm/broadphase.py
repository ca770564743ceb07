"""Broad phase of the collision barriers: which pairs are worth an ``mj_geomDistance`` call.

A pair (geom 1, geom 2) is a *candidate* at a state iff its bounding spheres (centres
``c1``, ``c2`` = ``geom_xpos``, radii ``geom_rbound``) are closer than the cut-off::

    |c1 - c2| < cutoff + r1 + r2          (always, when either geom is unbounded: rbound 0)

A pair that is not a candidate is farther apart than the cut-off, so its barrier saturates.

Two levels keep obstacles that can never come near free of per-step cost:

1. **Once, at construction: reach bounds.** Every geom's centre stays within a distance
   ``S`` of a world point ``E``, whatever the joint positions: walking up the kinematic tree,
   a hinge or ball joint turns its child about its anchor (fixed in the parent), so the
   distance to the anchor is constant; welded bodies add nothing. Slide joints (MuJoCo's
   limits are soft), free joints and mocap bodies give ``S = inf``. Static obstacles have
   ``S = 0``. A pair with ``|E1 - E2| - S1 - S2 >= cutoff + r1 + r2`` (plus 1 um) can never be
   a candidate and is left out of the per-step test.
2. **Every step: the exact test** on the remaining ("live") pairs, one small matrix product
   over the geoms they involve.

The candidate set is exactly that of the test above on all pairs; the tests check this against a
brute-force evaluation at random configurations. MuJoCo's own broad phase is not used: it is
reachable from Python only through ``mj_collision``, which also runs the narrow phase and writes
contacts, and whose distance threshold is each geom's ``margin``, a physics parameter.

**Along a run** (:class:`JointCoherence`, for arms of hinge joints among static obstacles): when
the joints move by ``dq``, a point of a geom moves by at most ``sum_j L_j |dq_j|``, ``L_j`` a bound
on its distance from joint j's axis (the same walk up the tree as the reach bounds), so a pair's
distance drops by at most ``P @ |dq|`` with ``P`` the sum of its two geoms' levers. A run keeps a
lower bound per live pair (its distance at its last narrow evaluation, taken with a larger
``distmax``, minus those drops) and sends a pair to the narrow phase only while the bound is
below the cut-off. A pair it skips is provably beyond the cut-off, so the barrier rows are the
same as with the per-state test, while most far pairs skip ``mj_geomDistance``.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

__all__ = ["BroadPhase", "JointCoherence", "reach_bounds"]

_SLACK = 1e-6  # [m] static pruning only drops pairs farther than the threshold by this much

_J = mujoco.mjtJoint
_ROTATIONS = (int(_J.mjJNT_HINGE), int(_J.mjJNT_BALL))


def reach_bounds(model: mujoco.MjModel, geoms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each geom's centre can be: within ``S`` [m] of the world point ``E`` [m].

    Evaluated at the model's reference configuration (``qpos0``, mocap bodies at their
    ``body_pos``); see the module docstring for the argument.

    Args:
        model: The model.
        geoms: Geom ids, shape (g,).

    Returns:
        ``(S, E)``: shape (g,) (``inf`` where the centre is not bounded) and (g, 3).

    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    geoms = np.asarray(geoms, dtype=np.int64)
    reach = np.zeros(geoms.size)
    end = np.array(data.geom_xpos[geoms], dtype=float).reshape(-1, 3)
    for row, g in enumerate(geoms.tolist()):
        p, s = end[row].copy(), 0.0
        b = int(model.geom_bodyid[g])
        while b != 0 and math.isfinite(s):
            if model.body_mocapid[b] >= 0:
                s = math.inf
                break
            adr, num = int(model.body_jntadr[b]), int(model.body_jntnum[b])
            for j in range(adr + num - 1, adr - 1, -1):  # last joint first: it moves p directly
                if int(model.jnt_type[j]) not in _ROTATIONS:
                    s = math.inf
                    break
                a = data.xanchor[j]
                s += float(np.linalg.norm(p - a))
                p = a.copy()
            b = int(model.body_parentid[b])
        reach[row], end[row] = s, p
    return reach, end


class BroadPhase:
    """Candidate pairs of a fixed set of geom pairs (see the module docstring).

    Args:
        model: The model (its geometry and kinematic tree must not change afterwards).
        geom1: First geom of each pair, shape (k,).
        geom2: Second geom of each pair, shape (k,).
        cutoff: Cut-off distance [m], > 0.

    Attributes:
        live: Indices of the pairs tested at every step (the others can never be candidates),
            shape (l,).
        thresh2: The live pairs' squared thresholds ``(cutoff + r1 + r2)^2`` [m^2] (``inf``:
            always a candidate), shape (l,).

    """

    def __init__(self, model: mujoco.MjModel, geom1: np.ndarray, geom2: np.ndarray,
                 cutoff: float) -> None:
        geom1 = np.asarray(geom1, dtype=np.int64)
        geom2 = np.asarray(geom2, dtype=np.int64)
        rb1, rb2 = model.geom_rbound[geom1], model.geom_rbound[geom2]
        thresh = np.where((rb1 == 0) | (rb2 == 0), np.inf, cutoff + rb1 + rb2)
        geoms, inv = np.unique(np.concatenate([geom1, geom2]), return_inverse=True)
        reach, end = reach_bounds(model, geoms)
        i1, i2 = inv[: geom1.size], inv[geom1.size:]
        with np.errstate(invalid="ignore"):  # inf - inf where both sides are unbounded
            lower = np.linalg.norm(end[i1] - end[i2], axis=1) - reach[i1] - reach[i2]
        never = np.isfinite(thresh) & np.isfinite(lower) & (lower >= thresh + _SLACK)
        self.live = np.flatnonzero(~never)
        self._live = self.live.tolist()
        self._all_live = self.live.size == geom1.size
        # diff = D @ geom_xpos[cols] gives c1 - c2 of every live pair in one product; cols are
        # the geoms the live pairs involve (far obstacles' geoms are not even read).
        g1, g2 = geom1[self.live], geom2[self.live]
        self._cols, pos = np.unique(np.concatenate([g1, g2]), return_inverse=True)
        rows = np.arange(self.live.size)
        self._dmat = np.zeros((self.live.size, self._cols.size))
        self._dmat[rows, pos[: rows.size]] += 1.0
        self._dmat[rows, pos[rows.size:]] -= 1.0
        self.thresh2 = self._thresh2 = thresh[self.live] ** 2
        self.cutoff = float(cutoff)
        self.geom1, self.geom2 = geom1, geom2
        # Per-call buffers (overwritten on every call).
        self._sq = np.empty((self.live.size, 3))
        self._s = np.empty(self.live.size)
        self._hit = np.empty(self.live.size, dtype=bool)
        self._ones = np.ones(3)

    def candidates(self, data: mujoco.MjData) -> list[int]:
        """Indices of the candidate pairs at the state in ``data`` (needs ``geom_xpos``), ascending."""
        if not self._live:
            return []
        diff = self._dmat @ data.geom_xpos.take(self._cols, 0)
        s = np.multiply(diff, diff, out=self._sq).dot(self._ones, out=self._s)
        hit = np.less(s, self._thresh2, out=self._hit).nonzero()[0]
        return hit.tolist() if self._all_live else self.live[hit].tolist()


def joint_levers(model: mujoco.MjModel, geoms: np.ndarray) -> np.ndarray | None:
    """Per geom and joint, a bound on the distance of the geom's points from the joint's axis [m].

    Shape (g, njnt); 0 where the joint does not move the geom. ``None`` when some geom moves in
    a way the joint angles do not capture (a mocap body, a non-hinge joint, an unbounded geom
    on a moving body).
    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    out = np.zeros((len(geoms), model.njnt))
    for row, g in enumerate(np.asarray(geoms, dtype=np.int64).tolist()):
        p, s = data.geom_xpos[g].copy(), 0.0
        rb = float(model.geom_rbound[g])
        b = int(model.geom_bodyid[g])
        while b != 0:
            if model.body_mocapid[b] >= 0:
                return None
            adr, num = int(model.body_jntadr[b]), int(model.body_jntnum[b])
            for j in range(adr + num - 1, adr - 1, -1):  # last joint first: it moves p directly
                if int(model.jnt_type[j]) != int(_J.mjJNT_HINGE) or rb == 0.0:
                    return None
                a = data.xanchor[j]
                s += float(np.linalg.norm(p - a))
                p = a.copy()
                out[row, j] = s + rb
            b = int(model.body_parentid[b])
    return out


class JointCoherence:
    """Lower bounds on the live pairs' distances along one run (see the module docstring).

    Use: :meth:`candidates` at each state, in run order; a narrow evaluation of each candidate
    with ``distmax`` = :attr:`distmax`; :meth:`update` with the distances it returned.
    :meth:`reset` forgets the bounds (a new run, or a jump of the state other than by the joints).
    Build with :meth:`of`, which says ``None`` where the joint angles do not capture the motion.

    Args:
        broadphase: The pairs' broad phase.
        levers: :func:`joint_levers` of ``broadphase.geom1[live]`` and ``geom2[live]``, stacked.
        qpos_adr: ``jnt_qposadr`` of every joint, shape (njnt,).
        reach: How far beyond the cut-off the narrow phase measures [m] (a pair measured at
            ``cutoff + s`` is skipped while its geoms' moves add up to less than ``s``).
        slack: Margin of the bounds for the narrow phase's rounding [m].

    """

    def __init__(self, broadphase: BroadPhase, levers: np.ndarray, qpos_adr: np.ndarray,
                 reach: float = 0.1, slack: float = 1e-6) -> None:
        n = broadphase.live.size
        pair = levers[:n] + levers[n:]
        used = np.flatnonzero(pair.any(axis=0))
        self.lever = self._lever = np.ascontiguousarray(pair[:, used])
        self.qadr = self._qadr = np.asarray(qpos_adr, dtype=np.int64)[used]
        self.cutoff = broadphase.cutoff
        self.distmax = broadphase.cutoff + float(reach)
        self.slack = self._slack = float(slack)
        self._n = n
        self.reset()

    @classmethod
    def of(cls, model: mujoco.MjModel, broadphase: BroadPhase, **kw: float) -> JointCoherence | None:
        live = broadphase.live
        levers = joint_levers(model, np.concatenate([broadphase.geom1[live], broadphase.geom2[live]]))
        return None if levers is None else cls(broadphase, levers, model.jnt_qposadr, **kw)

    def reset(self) -> None:
        """Forget the bounds: every live pair is a candidate at the next state."""
        self.lower = np.full(self._n, -math.inf)
        self.qprev = np.zeros(self._qadr.size)  # the joint angles at the last state (once qstate[0] is 1)
        self.qstate = np.zeros(1, dtype=np.int64)

    def candidates(self, data: mujoco.MjData) -> np.ndarray:
        """Rows of ``broadphase.live`` (ascending) whose bound is below the cut-off."""
        q = data.qpos.take(self._qadr)
        if self.qstate[0]:
            self.lower -= self._lever.dot(np.abs(q - self.qprev))  # (dot: the BLAS product of @)
        self.qprev[:] = q
        self.qstate[0] = 1
        return (self.lower < self.cutoff).nonzero()[0]

    def update(self, rows: np.ndarray, dist: list[float]) -> None:
        """The narrow phase's distances (at most :attr:`distmax`) of the candidate ``rows``."""
        if len(rows):
            self.lower[rows] = np.subtract(dist, self._slack)  # (each dist - slack, as before)
