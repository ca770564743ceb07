"""The arm loop's control steps in columns: what a block observer (the Rerun recorder) receives.

The loop writes each control step into row ``i`` of preallocated arrays (:meth:`StepColumns.write`),
and hands the whole block to observers that take blocks (:meth:`Observer.on_steps
<isf_robot.core.hooks.Observer.on_steps>`) when it is full, when the run ends and when it stops
early. No per-step object is built for them and nothing is transposed back into columns: a
recorder sends ``block.t[:n]``, ``block.q[:n]``, ... as they are. Observers that want one record
per step (a live viewer, a video) still get an :class:`~isf_robot.arm.records.ArmStepRecord`
at every step; :meth:`StepColumns.record` builds the same record from a row.

Shapes: ``n`` arm joints, ``k`` barriers (the collision pairs first, then the joint-limit rows;
``k_c`` collision pairs), ``m`` mocap bodies, ``C`` the block's capacity.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from .records import ArmStepRecord

__all__ = ["StepColumns", "TickValues"]


class TickValues(NamedTuple):
    """The barrier values of one control tick that a step's record keeps (made fresh at every tick).

    Attributes:
        rows: Indices of the collision pairs within the cut-off, ascending, shape (j,) int64.
        h: The tick's barrier values: those pairs' ``dist - margin``, then the joint limits', shape (j + k - k_c,).
        witness: The pairs' witness points, ``witness[:, 0]`` on the robot geom and ``witness[:, 1]`` on
            the other [m], shape (j, 2 or more, 3), or ``None``.

    """

    rows: np.ndarray
    h: np.ndarray
    witness: np.ndarray | None


class StepColumns:
    """A block of consecutive control steps, one row per step (capacity ``C``).

    The loop calls :meth:`write` per step and :meth:`seal` before handing the block on; after
    :meth:`seal` the attributes below hold the block's first ``len(block)`` rows.

    Attributes:
        t: Time at the start of each step [s], shape (C,).
        dt: Control period [s] (the same every step).
        q, qd, u, u_nom: Joint positions [rad], velocities, applied and nominal commands [rad/s], shape (C, n).
        on, qp_solved, fallback: Filter mode, QP solved, braking fallback applied, shape (C,) bool.
        xi_min: Smallest ``Xi_on`` the filter saw (inf for ``nominal``), shape (C,).
        dist_min: Smallest true signed distance [m] over the step's physics steps, shape (C,).
        h: Every barrier value, shape (C, k) (pairs beyond the cut-off: ``cutoff - margin``).
        h_min: Smallest barrier value of each row, shape (C,).
        ee_pos, goal_pos: End effector and goal pursued [m], shape (C, 3) (goal NaN without one).
        goal_index: Goal pursued, shape (C,) int.
        mocap_pos, mocap_quat: Mocap poses [m], (w, x, y, z), shape (C, m, 3) and (C, m, 4).
        near: Per row, the indices of the collision pairs within the cut-off (ascending).
        witness: Per row, their witness points (on the robot geom, on the other), shape (a, 2, 3).
        relaxed: Per row, the names of the barriers whose promotion was relaxed.
        events: Per row, the switch at that step or ``None``.
        names: Barrier names, length k.
        n_collision: ``k_c``.

    Cost: a step's vectors that live in MuJoCo's data or may be reused by their owner (``q``,
    ``qd``, ``u``, ``u_nom``, the end effector, the goal, mocap poses) are copied into their row;
    its scalars go to lists, and the arrays the loop makes fresh at every step (``Xi_on``, the
    near pairs' ``h``, indices and witness points, the joint rows' ``h``) are kept by reference.
    :meth:`seal` turns lists and references into the block's arrays in one pass. A step inside a
    control loop costs far more per NumPy call than the same call in a tight loop, so the
    per-step part makes as few as it can.

    """

    def __init__(self, capacity: int, n: int, names: tuple[str, ...], n_collision: int, nmocap: int,
                 dt: float, h_far: np.ndarray | None = None, goals: np.ndarray | None = None) -> None:
        c, k = int(capacity), len(names)
        if c < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity, self.names, self.n_collision, self.dt = c, tuple(names), int(n_collision), float(dt)
        self.h_far = (np.full(self.n_collision, np.inf) if h_far is None
                      else np.asarray(h_far, dtype=float).reshape(self.n_collision))
        self.size = 0
        self.q, self.qd, self.u, self.u_nom = (np.zeros((c, n)) for _ in range(4))
        self.ee_pos, self.goal_pos = np.zeros((c, 3)), np.zeros((c, 3))
        self.mocap_pos, self.mocap_quat = np.zeros((c, nmocap, 3)), np.zeros((c, nmocap, 4))
        self._moving = nmocap > 0
        self._goals = None if goals is None else np.asarray(goals, dtype=float).reshape(-1, 3).copy()
        self.t, self.on, self.qp_solved, self.fallback = np.zeros(c), *(np.zeros(c, dtype=bool) for _ in range(3))
        self.xi_min, self.dist_min, self.h_min = np.zeros(c), np.zeros(c), np.zeros(c)
        self.goal_index = np.zeros(c, dtype=np.int64)
        self.h = np.zeros((c, k))
        self._scalars: list[tuple[float, bool, bool, bool, float, int]] = []
        self._xi: list[np.ndarray] = []
        self._tick_h: list[np.ndarray] = []
        self._witness: list[np.ndarray | None] = []
        self.near: list[np.ndarray] = []
        self.witness: list[np.ndarray] = []
        self.relaxed: list[tuple[str, ...]] = []
        self.events: list[Any] = []
        self.sealed = 0

    def __len__(self) -> int:
        return self.size

    @property
    def full(self) -> bool:
        """Whether every row is written (the loop then seals it, hands it on and clears it)."""
        return self.size >= self.capacity

    def clear(self) -> None:
        """Start the next block (the arrays are reused: observers must not keep views past ``on_steps``)."""
        self.size = self.sealed = 0
        for rows in (self._scalars, self._xi, self._tick_h, self._witness, self.near, self.witness, self.relaxed,
                     self.events):
            rows.clear()

    def write(self, t: float, step: Any, data: Any, qpos_adr: Any, dof_adr: Any, values: TickValues,
              dist_min: float, ee_pos: np.ndarray, goal_index: int) -> None:
        """Write one control step into the next row.

        Args:
            t: Time at the start of the step [s].
            step: The strategy's step (``u``, ``u_nom``, ``on``, ``xi``, ``qp``, ``fallback``,
                ``relaxed``, ``event``).
            data: The MuJoCo data after the step.
            qpos_adr: Addresses of the arm's joints in ``qpos`` (a slice where they are consecutive).
            dof_adr: Addresses of the arm's joints in ``qvel`` (likewise).
            values: The tick's barrier values (made for this step: kept by reference).
            dist_min: Smallest true signed distance over the step's physics steps [m].
            ee_pos: End-effector position [m], shape (3,).
            goal_index: Goal pursued (its position: the block's goal table, NaN without one).

        """
        i = self.size
        if i >= self.capacity:
            raise IndexError(f"the block is full ({self.capacity} steps)")
        self.q[i] = data.qpos[qpos_adr]
        self.qd[i] = data.qvel[dof_adr]
        self.u[i] = step.u
        self.u_nom[i] = step.u_nom
        self.ee_pos[i] = ee_pos
        if self._moving:
            self.mocap_pos[i] = data.mocap_pos
            self.mocap_quat[i] = data.mocap_quat
        self._scalars.append((t, step.on, step.qp is not None, step.fallback, dist_min, goal_index))
        self._xi.append(step.xi)
        rows, h, w = values
        self._tick_h.append(h)
        self.near.append(rows)
        self._witness.append(w)
        self.relaxed.append(tuple(step.relaxed))
        self.events.append(step.event)
        self.size = i + 1

    def seal(self) -> None:
        """Fill the block's arrays from the rows written since the last :meth:`seal` (or :meth:`clear`)."""
        a, b = self.sealed, self.size
        if b <= a:
            return
        t, on, qp, fallback, dist, goal = zip(*self._scalars[a:b])
        self.t[a:b], self.on[a:b], self.qp_solved[a:b] = t, on, qp
        self.fallback[a:b], self.dist_min[a:b], self.goal_index[a:b] = fallback, dist, goal
        xi = self._xi[a:b]
        sizes = np.fromiter((x.size for x in xi), dtype=np.int64, count=b - a)
        mins = np.full(b - a, math.inf)
        if sizes.any():
            flat = np.concatenate(xi)
            nz = np.flatnonzero(sizes)
            mins[nz] = np.minimum.reduceat(flat, (np.cumsum(sizes) - sizes)[nz])
        self.xi_min[a:b] = mins
        nc = self.n_collision
        h = self.h[a:b]
        h[:, :nc] = self.h_far
        rows, tick_h = self.near[a:b], self._tick_h[a:b]
        counts = np.fromiter((r.size for r in rows), dtype=np.int64, count=b - a)
        if counts.any():  # (every row's near pairs in one scatter)
            h[np.repeat(np.arange(b - a), counts), np.concatenate(rows)] = np.concatenate(
                [th[:c] for th, c in zip(tick_h, counts.tolist())])
        if h.shape[1] > nc:
            h[:, nc:] = [th[c:] for th, c in zip(tick_h, counts.tolist())]
        self.witness[a:b] = [_NO_WITNESS if w is None else w[:, :2] for w in self._witness[a:b]]
        goals, gi = self._goals, self.goal_index[a:b]
        ok = (gi >= 0) & (gi < (0 if goals is None else len(goals)))
        self.goal_pos[a:b] = math.nan
        if goals is not None and ok.any():
            self.goal_pos[a:b][ok] = goals[gi[ok]]
        self.h_min[a:b] = h.min(axis=1) if h.shape[1] else math.inf
        self.sealed = b

    def closest(self, i: int, m: int = 3) -> np.ndarray:
        """Indices of the (up to) ``m`` collision pairs with the smallest ``h`` at (sealed) row ``i``, closest first."""
        return np.argsort(self.h[i, :self.n_collision])[:m]

    def record(self, i: int) -> ArmStepRecord:
        """Row ``i`` as a step record (copies: the record owns its arrays)."""
        if not 0 <= i < self.size:
            raise IndexError(f"row {i} of a block of {self.size} step(s)")
        self.seal()
        names = self.names
        return ArmStepRecord(
            t=float(self.t[i]), dt=self.dt, q=self.q[i].copy(), qd=self.qd[i].copy(), u=self.u[i].copy(),
            u_nom=self.u_nom[i].copy(), on=bool(self.on[i]), h_min=float(self.h_min[i]),
            xi_min=float(self.xi_min[i]), dist_min=float(self.dist_min[i]), qp_solved=bool(self.qp_solved[i]),
            h=self.h[i].copy(), names=names, closest=tuple(names[j] for j in self.closest(i).tolist()),
            witness=np.array(self.witness[i]), witness_names=tuple(names[j] for j in self.near[i].tolist()),
            mocap_pos=self.mocap_pos[i].copy(), mocap_quat=self.mocap_quat[i].copy(),
            ee_pos=self.ee_pos[i].copy(), goal_index=int(self.goal_index[i]), goal_pos=self.goal_pos[i].copy(),
            event=self.events[i], fallback=bool(self.fallback[i]), relaxed=self.relaxed[i],
        )


_NO_WITNESS = np.zeros((0, 2, 3))
_NO_WITNESS.flags.writeable = False
