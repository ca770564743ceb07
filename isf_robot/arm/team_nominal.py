"""The nominal task of a scene with several arms: each arm's reaching controller, the commands stacked."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from isf_robot.core import ConfigError

from .nominal import NominalController, ReachingController
from .one_arm import arm_scene
from .scene import Scene

__all__ = ["TeamReaching"]


class TeamReaching(NominalController):
    """Every arm's reaching controller through its own goals; the commands stacked in the scene's joint order.

    Args:
        scene: A scene with arms.
        goals: Goal positions [m] of every arm in the scene's order, shape (g, 3); default the scene's.
        **kwargs: Passed to each arm's :class:`ReachingController`.

    """

    def __init__(self, scene: Scene, goals: np.ndarray | None = None, **kwargs: Any) -> None:
        if not scene.arms:
            raise ConfigError(f"scene {scene.name!r} has one arm; TeamReaching needs [[arm]] tables")
        g = scene.goal_positions if goals is None else np.asarray(goals, dtype=float)
        self.scene, self.n = scene, scene.n_joints
        self.arms = [ReachingController(arm_scene(scene, i), goals=g[a.goals], **kwargs)
                     for i, a in enumerate(scene.arms)]
        self.slices = [a.joints for a in scene.arms]
        self.goal_positions = g

    @property
    def goal_index(self) -> int:
        """The first arm's goal index, in the scene's goal order."""
        return int(self.scene.arms[0].goals.start + self.arms[0].goal_index)

    @property
    def goals_reached(self) -> int:
        """Goal arrivals of every arm."""
        return sum(c.goals_reached for c in self.arms)

    @property
    def goals_missed(self) -> int:
        """Goals given up, every arm."""
        return sum(c.goals_missed for c in self.arms)

    @property
    def goal_times(self) -> tuple[float, ...]:
        """Every arm's arrival times, sorted."""
        return tuple(sorted(t for c in self.arms for t in c.goal_times))

    def reset(self) -> None:
        """Every arm's task from the start."""
        for c in self.arms:
            c.reset()

    def snapshot(self) -> Any:
        """Every arm's controller state."""
        return [c.snapshot() for c in self.arms]

    def restore(self, state: Any) -> None:
        """Put every arm's controller back."""
        for c, s in zip(self.arms, state):
            c.restore(s)

    def __call__(self, t: float, data: mujoco.MjData) -> np.ndarray:
        """Every arm's command at ``t``, stacked; shape (n,) [rad/s] (a fresh array).

        Fresh, not a buffer used again: the step keeps its nominal command while a rollout calls the
        controller at predicted states.
        """
        u = np.empty(self.n)
        for c, sl in zip(self.arms, self.slices):
            u[sl] = c(t, data)
        return u
