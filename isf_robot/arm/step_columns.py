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
from typing import Any

import numpy as np

from .records import ArmStepRecord

__all__ = ["StepColumns"]


class StepColumns:
    """A block of consecutive control steps, one row per step (arrays of capacity ``C``).

    Attributes:
        t: Time at the start of each step [s], shape (C,).
        dt: Control period [s] (the same every step).
        q, qd, u, u_nom: Joint positions [rad], velocities, applied and nominal commands [rad/s], shape (C, n).
        on, qp_solved, fallback: Filter mode, QP solved, braking fallback applied, shape (C,) bool.
        xi_min: Smallest ``Xi_on`` the filter saw (inf for ``nominal``), shape (C,).
        dist_min: Smallest true signed distance [m] over the step's physics steps, shape (C,).
        h: Every barrier value, shape (C, k) (pairs beyond the cut-off: ``cutoff - margin``).
        ee_pos, goal_pos: End effector and goal pursued [m], shape (C, 3) (goal NaN without one).
        goal_index: Goal pursued, shape (C,) int.
        mocap_pos, mocap_quat: Mocap poses [m], (w, x, y, z), shape (C, m, 3) and (C, m, 4).
        near: Per row, the indices of the collision pairs within the cut-off (ascending).
        witness: Per row, their witness points (on the robot geom, on the other), shape (a, 2, 3).
        relaxed: Per row, the names of the barriers whose promotion was relaxed.
        events: Per row, the switch at that step or ``None``.
        names: Barrier names, length k.
        n_collision: ``k_c``.

    """

    def __init__(self, capacity: int, n: int, names: tuple[str, ...], n_collision: int, nmocap: int,
                 dt: float) -> None:
        c, k = int(capacity), len(names)
        if c < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity, self.names, self.n_collision, self.dt = c, tuple(names), int(n_collision), float(dt)
        self.size = 0
        self.t = np.zeros(c)
        self.q, self.qd, self.u, self.u_nom = (np.zeros((c, n)) for _ in range(4))
        self.on, self.qp_solved, self.fallback = (np.zeros(c, dtype=bool) for _ in range(3))
        self.xi_min, self.dist_min = np.zeros(c), np.zeros(c)
        self.h = np.zeros((c, k))
        self.ee_pos, self.goal_pos = np.zeros((c, 3)), np.zeros((c, 3))
        self.goal_index = np.zeros(c, dtype=np.int64)
        self.mocap_pos, self.mocap_quat = np.zeros((c, nmocap, 3)), np.zeros((c, nmocap, 4))
        self.near: list[np.ndarray] = [np.zeros(0, dtype=np.int64)] * c
        self.witness: list[np.ndarray] = [np.zeros((0, 2, 3))] * c
        self.relaxed: list[tuple[str, ...]] = [()] * c
        self.events: list[Any] = [None] * c

    def __len__(self) -> int:
        return self.size

    @property
    def full(self) -> bool:
        """Whether every row is written (the loop then hands the block on and clears it)."""
        return self.size >= self.capacity

    def clear(self) -> None:
        """Start the next block (the arrays are reused: observers must not keep views past ``on_steps``)."""
        self.size = 0

    @property
    def h_min(self) -> np.ndarray:
        """Smallest barrier value of each row, shape (size,)."""
        n = self.size
        return self.h[:n].min(axis=1) if self.h.shape[1] else np.full(n, math.inf)

    def write(self, t: float, step: Any, data: Any, qpos_adr: Any, dof_adr: Any, h_far: np.ndarray,
              near: Any, jh: np.ndarray, dist_min: float, ee_pos: np.ndarray, goal_index: int,
              goal_pos: np.ndarray | None) -> None:
        """Write one control step into the next row.

        Args:
            t: Time at the start of the step [s].
            step: The strategy's step (``u``, ``u_nom``, ``on``, ``xi_min``, ``qp``, ``fallback``,
                ``relaxed``, ``event``).
            data: The MuJoCo data after the step.
            qpos_adr: Addresses of the arm's joints in ``qpos`` (a slice where they are consecutive).
            dof_adr: Addresses of the arm's joints in ``qvel`` (likewise).
            h_far: Barrier value of each collision pair beyond the cut-off, shape (k_c,).
            near: The pairs within the cut-off (``rows``, ``h``, ``witness``).
            jh: Joint-limit barrier values, shape (k - k_c,).
            dist_min: Smallest true signed distance over the step's physics steps [m].
            ee_pos: End-effector position [m], shape (3,).
            goal_index: Goal pursued.
            goal_pos: Its position [m], or ``None`` (no goal: NaN).

        """
        i, nc = self.size, self.n_collision
        self.t[i] = t
        self.q[i] = data.qpos[qpos_adr]
        self.qd[i] = data.qvel[dof_adr]
        self.u[i] = step.u
        self.u_nom[i] = step.u_nom
        self.on[i] = step.on
        self.qp_solved[i] = step.qp is not None
        self.fallback[i] = step.fallback
        xi = step.xi
        self.xi_min[i] = xi.min() if xi.size else math.inf
        self.dist_min[i] = dist_min
        row = self.h[i]
        row[:nc] = h_far
        rows = near.rows
        if rows.size:
            row[rows] = near.h
        row[nc:] = jh
        self.ee_pos[i] = ee_pos
        self.goal_index[i] = goal_index
        if goal_pos is None:
            self.goal_pos[i] = math.nan
        else:
            self.goal_pos[i] = goal_pos
        if self.mocap_pos.shape[1]:
            self.mocap_pos[i] = data.mocap_pos
            self.mocap_quat[i] = data.mocap_quat
        self.near[i] = rows
        self.witness[i] = near.witness if near.witness is not None else np.zeros((0, 2, 3))
        self.relaxed[i] = tuple(step.relaxed)
        self.events[i] = step.event
        self.size = i + 1

    def closest(self, i: int, m: int = 3) -> np.ndarray:
        """Indices of the (up to) ``m`` collision pairs with the smallest ``h`` at row ``i``, closest first."""
        return np.argsort(self.h[i, :self.n_collision])[:m]

    def record(self, i: int) -> ArmStepRecord:
        """Row ``i`` as a step record (copies: the record owns its arrays)."""
        if not 0 <= i < self.size:
            raise IndexError(f"row {i} of a block of {self.size} step(s)")
        names = self.names
        return ArmStepRecord(
            t=float(self.t[i]), dt=self.dt, q=self.q[i].copy(), qd=self.qd[i].copy(), u=self.u[i].copy(),
            u_nom=self.u_nom[i].copy(), on=bool(self.on[i]),
            h_min=float(self.h[i].min()) if self.h.shape[1] else math.inf,
            xi_min=float(self.xi_min[i]), dist_min=float(self.dist_min[i]), qp_solved=bool(self.qp_solved[i]),
            h=self.h[i].copy(), names=names, closest=tuple(names[j] for j in self.closest(i).tolist()),
            witness=np.array(self.witness[i]), witness_names=tuple(names[j] for j in self.near[i].tolist()),
            mocap_pos=self.mocap_pos[i].copy(), mocap_quat=self.mocap_quat[i].copy(),
            ee_pos=self.ee_pos[i].copy(), goal_index=int(self.goal_index[i]), goal_pos=self.goal_pos[i].copy(),
            event=self.events[i], fallback=bool(self.fallback[i]), relaxed=self.relaxed[i],
        )
