"""A block of a team run's steps: the arm loop's columns plus each arm's mode, end effector and goal.

:class:`TeamStepColumns` is the :class:`~isf_robot.arm.step_columns.StepColumns` the multi-arm loop
(:class:`~isf_robot.arm.multi_arm.MultiArmSimulation`) hands to its block observers: the Rerun recorder
derives each arm's series from it (:mod:`isf_robot.record.team`). Everything of one arm run is there
unchanged; the extra columns are written right after the step's row, by :meth:`TeamStepColumns.write_arms`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .step_columns import StepColumns

__all__ = ["TeamStepColumns"]


class TeamStepColumns(StepColumns):
    """A block of control steps of a team (capacity ``C``, ``a`` arms).

    Attributes (besides :class:`StepColumns`'):
        arm_names: The arms' names, length a.
        arm_on: Each arm's filter on at the step, shape (C, a) (centrally filtered: the one filter's mode).
        arm_qp: Each arm's filter solved a QP at the step, shape (C, a).
        arm_ee: Each arm's end effector at the tick [m], shape (C, a, 3).
        arm_goal_index: The goal each arm pursues (its own goal table's row; -1: none), shape (C, a).
        arm_goal: Those goals [m], shape (len(block), a, 3) (NaN without one; made when read).

    """

    def __init__(self, capacity: int, n: int, names: tuple[str, ...], n_collision: int, nmocap: int, dt: float,
                 arm_names: Sequence[str], h_far: np.ndarray | None = None, goals: np.ndarray | None = None,
                 nbody: int = 0) -> None:
        super().__init__(capacity, n, names, n_collision, nmocap, dt, h_far, goals, nbody)
        c, a = self.capacity, len(arm_names)
        self.arm_names = tuple(str(x) for x in arm_names)
        self.arm_on = np.zeros((c, a), dtype=bool)
        self.arm_qp = np.zeros((c, a), dtype=bool)
        self.arm_ee = np.zeros((c, a, 3))
        self.arm_goal_index = np.full((c, a), -1, dtype=np.int64)
        self._arm_goals: list[np.ndarray] = [np.zeros((0, 3))] * a
        self._arm_ee: tuple[np.ndarray, ...] | None = None

    def bind_arms(self, site_xpos: np.ndarray, ee_sites: Sequence[int], goals: Sequence[np.ndarray]) -> None:
        """Where :meth:`write_arms` reads each arm's end effector, and each arm's goal table.

        Args:
            site_xpos: The run's ``data.site_xpos`` (a view into MuJoCo's data).
            ee_sites: Each arm's end-effector site (-1: none; its ``arm_ee`` is NaN).
            goals: Each arm's goal positions [m], shape (g_i, 3).

        """
        if len(ee_sites) != len(self.arm_names) or len(goals) != len(self.arm_names):
            raise ValueError(f"one end-effector site and one goal table per arm ({len(self.arm_names)}), got "
                             f"{len(ee_sites)} and {len(goals)}")
        sites = np.asarray(ee_sites, dtype=np.intp)
        has = sites >= 0
        self.arm_ee[:, ~has] = np.nan
        self._arm_ee = (site_xpos, sites) if has.all() else (site_xpos, sites[has], np.flatnonzero(has))
        self._arm_goals = [np.asarray(g, dtype=float).reshape(-1, 3) for g in goals]

    def write_arms(self, modes: Sequence[tuple[bool, bool]], goal_index: Sequence[int]) -> None:
        """Each arm's ``(on, QP solved)`` and goal (its table's row) at the row just written (the tick's ends)."""
        i = self.size - 1
        if i < 0:
            raise IndexError("write_arms follows write: the block has no row yet")
        if self._arm_ee is None:
            raise RuntimeError("TeamStepColumns.write_arms needs bind_arms(site_xpos, ee_sites, goals) first")
        self.arm_on[i], self.arm_qp[i] = zip(*modes)
        if len(self._arm_ee) == 2:
            self.arm_ee[i] = self._arm_ee[0][self._arm_ee[1]]
        else:  # (arms without an end-effector site keep NaN)
            self.arm_ee[i, self._arm_ee[2]] = self._arm_ee[0][self._arm_ee[1]]
        self.arm_goal_index[i] = goal_index

    @property
    def arm_goal(self) -> np.ndarray:
        """The goal each arm pursues [m], shape (len(block), a, 3) (NaN without one)."""
        out = np.full((self.size, len(self.arm_names), 3), np.nan)
        for j, table in enumerate(self._arm_goals):
            gi = self.arm_goal_index[: self.size, j]
            ok = (gi >= 0) & (gi < len(table))
            out[ok, j] = table[gi[ok]]
        return out
