"""Safety on the true geometry, checked at every physics step of an arm run.

Judged on the real MuJoCo geometry (signed distances from ``mj_geomDistance``), not on the
filter's model: ``min_h`` is the smallest ``dist - margin`` over all collision pairs and all
physics steps, ``collisions`` counts the physics steps at which some pair has
``dist - margin < 0``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from . import kernels
from .barriers import CollisionBarriers
from .narrow import pair_value, substep_distmax

if TYPE_CHECKING:
    from .actuation import Actuation

__all__ = ["SafetyMonitor"]


class SafetyMonitor:
    """True-geometry clearance of the collision pairs, checked at every physics step.

    At a control tick the collision barriers have just been evaluated: their ``h`` is the
    exact ``dist - margin`` of every pair within the cut-off (``mj_geomDistance``), and every
    other pair is at least ``cutoff - margin`` away. At the other physics steps of the control
    step, ``mj_geomDistance`` is called for the pairs that were within the cut-off at the tick,
    with ``distmax`` just above what could change the running minimum or count a collision (a
    pair beyond the cut-off, e.g. 0.25 m, cannot close that gap within one control period).
    So ``min_h`` is exact whenever it is below ``cutoff - margin`` and saturates there when
    the arm never comes within the cut-off.
    """

    def __init__(self, coll: CollisionBarriers) -> None:
        p = coll.pairs
        self.model = coll.model
        self.g1l, self.g2l = p.geom1.tolist(), p.geom2.tolist()
        self.marginl = p.margin.tolist()
        # The compiled sub-step check (isf_robot.arm.kernels), with the collision barriers' choice.
        self._kernel = kernels.monitor_kernel() if getattr(coll, "_kernel", None) is not None else None
        self._g1, self._g2 = p.geom1.astype(np.int64), p.geom2.astype(np.int64)
        self._margin = np.ascontiguousarray(p.margin, dtype=float)
        self._maddr = getattr(coll.model, "_address", 0)
        self._data: mujoco.MjData | None = None
        self._daddr = 0
        self._rows_arr: np.ndarray | None = None
        self.min_h = math.inf
        self.collisions = 0
        self.steps = 0
        self.rows: Sequence[int] = []

    def tick(self, h: np.ndarray, rows: np.ndarray) -> float:
        """Account the tick's barrier values; return the smallest barrier value of the pairs within the cut-off.

        Args:
            h: Collision barrier values at the tick, shape (k,).
            rows: Indices of the pairs within the cut-off.

        Returns:
            Their smallest ``dist - margin`` [m] (each pair's own margin); ``inf`` when none is near.

        """
        return self.tick_min(float(h.min()), rows.tolist())

    def tick_min(self, h_min: float, rows: Sequence[int], rows_array: np.ndarray | None = None) -> float:
        """:meth:`tick` given its minimum: the smallest barrier value over every pair and the pairs within the cut-off.

        ``rows``: a list or tuple, kept until the next tick; ``rows_array``: the same rows as an int64 array, if at
        hand. Returns ``h_min`` when a pair is near, else ``inf``. The loop passes the smaller of the near pairs'
        minimum and the far pairs' floor (the least ``cutoff - margin``): exact whenever some pair is below that
        floor, else the floor, a lower bound (with pairs of different margins a near pair can lie above it).
        """
        self.steps += 1
        self.rows = rows
        self._rows_arr = rows_array
        if h_min < 0.0:
            self.collisions += 1
        if h_min < self.min_h:
            self.min_h = h_min
        return h_min if rows else math.inf

    def rows_array(self) -> np.ndarray:
        """The pairs within the cut-off at the last tick (:attr:`rows`) as an int64 array (made once per tick)."""
        ra = self._rows_arr
        if ra is None:
            ra = self._rows_arr = np.array(self.rows, dtype=np.int64)
        return ra

    def substep(self, data: mujoco.MjData, bound: float = -math.inf, tracker: Actuation | None = None) -> float:
        """Check the pairs near at the last tick; return their smallest barrier value ``dist - margin``.

        Args:
            data: The MuJoCo data after ``mj_step1``.
            bound: Barrier values at or above ``bound`` [m] need not be exact (pass the control
                step's running minimum barrier to get that minimum exactly, ``-inf`` when
                only the run's minimum barrier and the collision count matter). Each pair's
                ``distmax`` is its margin above the larger of that and what could change the run's
                minimum barrier or count a collision (:func:`~isf_robot.arm.narrow.substep_distmax`),
                so ``mj_geomDistance`` can stop early.
            tracker: Then ``tracker.apply(data)`` (in the same compiled call where both have one:
                :meth:`~isf_robot.arm.lowlevel.VelocityTracker.compiled_apply`).

        Returns:
            The smallest barrier value found [m] (each pair's own margin): exact when below ``bound``
            or the run's minimum, otherwise a value at or above the larger of them (``inf`` when no
            pair is near).

        """
        self.steps += 1
        rows = self.rows
        if not rows:
            if tracker is not None:
                tracker.apply(data)
            return math.inf
        thresh = max(self.min_h, 0.0)
        fused = tracker.compiled_apply(data) if self._kernel is not None and tracker is not None and hasattr(
            tracker, "compiled_apply") else None
        if self._kernel is not None:
            if data is not self._data:
                self._data, self._daddr = data, data._address
            ra = self.rows_array()
            if fused is not None:
                k, ptrs, buf, n, nv = fused
                step_h = k["monitor_apply"](self._maddr, self._daddr, ra, self._g1, self._g2, self._margin,
                                            thresh, bound, ptrs, buf, n, nv)
            else:
                step_h = self._kernel(self._maddr, self._daddr, ra, self._g1, self._g2, self._margin, thresh, bound)
        else:
            step_h = self._substep_python(data, rows, thresh, bound)
        if tracker is not None and fused is None:
            tracker.apply(data)
        if step_h < 0.0:
            self.collisions += 1
        if step_h < self.min_h:
            self.min_h = step_h
        return step_h

    def _substep_python(self, data: mujoco.MjData, rows: Sequence[int], thresh: float, bound: float) -> float:
        """The smallest ``h`` of ``rows`` (per-pair calls; :meth:`substep` without the kernel)."""
        m, g1, g2, marg = self.model, self.g1l, self.g2l, self.marginl
        step_h = math.inf
        for i in rows:
            d = mujoco.mj_geomDistance(m, data, g1[i], g2[i], substep_distmax(thresh, marg[i], bound), None)
            step_h = min(step_h, pair_value(d, marg[i]))
        return step_h
