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
        arm_ee: Each arm's end effector [m], shape (C, a, 3).
        arm_goal: The goal each arm pursues [m], shape (C, a, 3) (NaN without one).

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
        self.arm_goal = np.full((c, a, 3), np.nan)

    def write_arms(self, modes: Sequence[tuple[bool, bool]], ee: Sequence[np.ndarray],
                   goals: Sequence[np.ndarray | None]) -> None:
        """Each arm's ``(on, QP solved)``, end effector and goal (``None``: none) at the row just written."""
        i = self.size - 1
        if i < 0:
            raise IndexError("write_arms follows write: the block has no row yet")
        for j, ((on, qp), p, g) in enumerate(zip(modes, ee, goals)):
            self.arm_on[i, j] = on
            self.arm_qp[i, j] = qp
            self.arm_ee[i, j] = p
            self.arm_goal[i, j] = np.nan if g is None else g
