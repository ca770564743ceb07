"""Episode setup: control timing and seeded variations.

:func:`path_track` (obstacle tracks) lives in :mod:`isf_robot.arm.paths` and is re-exported here
for the simulation loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from isf_robot.core import ConfigError

from .barriers import CollisionBarriers
from .paths import path_cycle, path_track
from .scene import Scene

__all__ = ["check_control_period", "path_track", "EpisodeSetup", "episode_setup"]


def check_control_period(period: float, timestep: float) -> int:
    """Physics steps per control step; the period must be a whole multiple of the timestep.

    Raises:
        ConfigError: ``period`` is not positive or not a whole multiple of ``timestep``.

    """
    if not (isinstance(period, (int, float)) and math.isfinite(period) and period > 0):
        raise ConfigError(f"control period must be a positive number of seconds, got {period!r}")
    ratio = period / timestep
    steps = int(round(ratio))
    if steps < 1 or abs(ratio - steps) > 1e-6 * max(1.0, ratio):
        raise ConfigError(f"control period {period} s is not a whole multiple of the physics "
                          f"timestep {timestep} s (ratio {ratio:.6g})")
    return steps


@dataclass(frozen=True)
class EpisodeSetup:
    """The seeded variation of an episode.

    Attributes:
        q0: Initial arm joint positions [rad], shape (n,).
        goals: Goal positions [m], shape (g, 3).
        time_offset: Offset of the moving obstacles' clock [s] (their position at sim time
            t is the path's position at ``t + time_offset``).

    """

    q0: np.ndarray
    goals: np.ndarray
    time_offset: float


def episode_setup(scene: Scene, seed: int, *, q_noise: float = 0.05, goal_noise: float = 0.03,
                  max_tries: int = 100) -> EpisodeSetup:
    """Draw an episode's initial configuration, goal jitter and obstacle phase from ``seed``.

    ``q0 = home + N(0, q_noise^2)`` per joint (clipped inside the joint-limit margins), goals
    jittered uniformly by ``+-goal_noise`` [m] in x and y, moving obstacles started at a random
    point of their path. Draws are repeated until every barrier (collision pairs, joint limits)
    is positive at t = 0.

    Raises:
        ConfigError: ``seed`` is not a non-negative integer, or no safe initial state was
            found in ``max_tries`` draws.

    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be a non-negative integer, got {seed!r}")
    rng = np.random.default_rng(seed)
    n = scene.n_joints
    margin = scene.config.barrier.joint_margin
    lo = scene.joint_range[:, 0] + margin
    hi = scene.joint_range[:, 1] - margin
    coll = CollisionBarriers.from_scene(scene)
    period = max([path_cycle(mv.path) for mv in scene.config.moving] or [0.0])
    for _ in range(max_tries):
        q0 = np.clip(scene.home + rng.normal(0.0, q_noise, n), lo + 1e-3, hi - 1e-3)
        goals = scene.goal_positions.copy()
        goals[:, :2] += rng.uniform(-goal_noise, goal_noise, (goals.shape[0], 2))
        offset = float(rng.uniform(0.0, period)) if period > 0 else 0.0
        data = mujoco.MjData(scene.model)
        data.qpos[scene.qpos_adr] = q0
        scene.set_moving_obstacles(data, offset)
        mujoco.mj_forward(scene.model, data)
        if float(np.min(coll.evaluate(data).h)) > 0.0:
            return EpisodeSetup(q0=q0, goals=goals, time_offset=offset)
    raise ConfigError(f"scene {scene.name!r}: no safe initial state in {max_tries} draws "
                      f"(seed {seed}); is the home configuration inside the safe set?")
