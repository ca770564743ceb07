"""Fixtures for the arm tests: shipped scenes, finite-difference helpers, a kinematic rollout."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, Scene, load_scene


@pytest.fixture(scope="session")
def planar() -> Scene:
    return load_scene("planar")


@pytest.fixture(scope="session")
def planar_moving() -> Scene:
    return load_scene("planar_moving")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


@pytest.fixture(scope="session")
def fd_grad() -> Callable[..., np.ndarray]:
    """Central finite differences of ``f(data) -> (k,)`` w.r.t. the joints at ``qpos_adr``.

    Hinge/slide joints: the perturbation is added to qpos (``mj_integratePos`` with a unit
    velocity on one dof does the same for these joint types); kinematics are recomputed.
    """

    def fd(model: mujoco.MjModel, data: mujoco.MjData, f: Callable[[mujoco.MjData], np.ndarray],
           dof_adr: np.ndarray, eps: float = 1e-6) -> np.ndarray:
        q0 = data.qpos.copy()
        cols = []
        for dof in dof_adr:
            vals = []
            for sign in (1.0, -1.0):
                data.qpos[:] = q0
                v = np.zeros(model.nv)
                v[dof] = sign
                mujoco.mj_integratePos(model, data.qpos, v, eps)
                mujoco.mj_forward(model, data)
                vals.append(np.asarray(f(data), dtype=float))
            cols.append((vals[0] - vals[1]) / (2 * eps))
        data.qpos[:] = q0
        mujoco.mj_forward(model, data)
        return np.stack(cols, axis=1)

    return fd


@pytest.fixture(scope="session")
def nominal_rollout() -> Callable[[Scene, float], float]:
    """Kinematic rollout of the nominal reaching task, q_dot = DLS(kp (goal - ee)).

    Returns the smallest signed robot-obstacle distance seen [m]: negative means the nominal
    motion collides (every shipped scene must make the filter matter).
    """

    def run(scene: Scene, duration: float, dt: float = 0.005) -> float:
        m, g, task = scene.model, scene.config.gains, scene.config.task
        data = scene.make_data()
        cb = CollisionBarriers.from_scene(scene)
        q = scene.home.copy()
        jac = np.zeros((3, m.nv))
        goal, held, worst = 0, 0.0, np.inf
        for step in range(int(duration / dt)):
            t = step * dt
            data.qpos[scene.qpos_adr] = q
            scene.set_moving_obstacles(data, t)
            mujoco.mj_kinematics(m, data)
            mujoco.mj_comPos(m, data)
            worst = min(worst, cb.min_distance(data).distance)
            err = scene.goal_positions[goal] - scene.ee_position(data)
            if np.linalg.norm(err) < task.tolerance:
                held += dt
                if held >= scene.goal_dwell[goal]:
                    goal, held = (goal + 1) % len(scene.goal_positions), 0.0
            v = g.task_kp * err
            speed = np.linalg.norm(v)
            if speed > g.max_ee_speed:
                v *= g.max_ee_speed / speed
            scene.ee_jacobian(data, jac)
            J = jac[:, scene.dof_adr]
            u = J.T @ np.linalg.solve(J @ J.T + g.dls_damping**2 * np.eye(3), v)
            top = np.max(np.abs(u)) / g.max_joint_speed
            if top > 1:
                u /= top
            q = np.clip(q + dt * u, scene.joint_range[:, 0], scene.joint_range[:, 1])
        return worst

    return run


@pytest.fixture(scope="session")
def random_states() -> Callable[..., Any]:
    """``random_states(scene, rng, n, spread=0.6)``: one scratch MjData moved to ``n`` random joint states
    (``spread`` of the way from home to the joint limits), kinematics computed, yielded in turn."""

    def states(scene: Scene, rng: np.random.Generator, n: int, spread: float = 0.6) -> Iterator[mujoco.MjData]:
        m, d = scene.model, scene.make_data()
        lo, hi = scene.joint_range[:, 0], scene.joint_range[:, 1]
        for _ in range(n):
            d.qpos[scene.qpos_adr] = scene.home + rng.uniform(lo - scene.home, hi - scene.home) * spread
            mujoco.mj_forward(m, d)
            yield d

    return states


@pytest.fixture(scope="session")
def goal_reached_at_once() -> Callable[..., None]:
    """A rollout's ``goals`` hook: the current goal put at the end effector with a short dwell, so that an arrival
    within the horizon can advance the goal (the rollouts' compiled paths must then decline)."""

    def near_the_goal(nom: Any, data: Any, t: float) -> None:
        nom.goals.reset()
        nom.goals.dwell[:] = 0.05
        nom.goal_positions[nom.goals.index] = nom.scene.ee_position(data)

    return near_the_goal


@pytest.fixture(scope="session")
def rollout_states() -> Callable[..., Iterator[tuple[float, mujoco.MjData]]]:
    """Random states ``(t, data)`` for an isf simulation's rollout: the arm about its start, moving obstacles placed,
    a previous command for the rate limit (the controller reset first; ``goals``: a hook on the goals)."""

    def states(scene: Scene, sim: Any, count: int, goals: Callable[..., None] | None = None
               ) -> Iterator[tuple[float, mujoco.MjData]]:
        rng = np.random.default_rng(7)
        data = mujoco.MjData(scene.model)
        nom = sim.nominal
        nom.reset()
        for k in range(count):
            t = 0.2 + 0.05 * k
            data.qpos[scene.qpos_adr] = sim.setup.q0 + rng.normal(scale=0.4, size=scene.n_joints)
            scene.set_moving_obstacles(data, t + sim.setup.time_offset)
            mujoco.mj_forward(scene.model, data)
            if goals is not None:
                goals(nom, data, t)
            nom(t - 0.01, data)
            yield t, data

    return states
