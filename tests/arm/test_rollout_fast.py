"""The rollout's compiled Euler step (``isf_robot.arm._rollout_jit``): the numpy step's points, bit for bit.

``NominalRollout`` advances ``q <- q + dt u``, writes it into its scratch ``MjData`` and runs the
kinematics in one compiled call where numba is available; the points (rows, names, commands) must
be those of the numpy step, with static and with moving obstacles. Skipped without numba.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from isf_robot.arm import ArmSimulation, kernels
from isf_robot.arm.params import resolve_params

pytestmark = pytest.mark.skipif(not kernels.available(), reason="numba not installed (the fast extra)")


def _points(roll, t, data):  # type: ignore[no-untyped-def]
    return [(s, lie.h.tobytes(), lie.lf.tobytes(), lie.lg.tobytes(), lie.grad_norm.tobytes(), lie.names, u.tobytes())
            for s, lie, u in roll(t, data)]


@pytest.mark.parametrize("name", ["panda_pole", "planar_moving"])
def test_compiled_euler_step_gives_the_numpy_steps_points(name) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.arm import load_scene

    scene = load_scene(name)
    params = resolve_params(scene, d_bar=0.05, horizon=0.3, calibrate=False)
    sim = ArmSimulation(scene, "isf", seed=3, params=params)
    roll = sim.strategy.predictor.rollout
    step = roll._step
    assert step is not None  # numba is here: the compiled step is used
    calls: list[int] = []
    counted = lambda *a: calls.append(1) or step(*a)  # noqa: E731
    rng = np.random.default_rng(7)
    data = mujoco.MjData(scene.model)
    nom = sim.nominal
    nom.reset()
    near = 0
    for k in range(12):
        t = 0.2 + 0.05 * k
        data.qpos[scene.qpos_adr] = sim.setup.q0 + rng.normal(scale=0.4, size=scene.n_joints)
        scene.set_moving_obstacles(data, t + sim.setup.time_offset)
        mujoco.mj_forward(scene.model, data)
        nom(t - 0.01, data)  # (a previous command for the rate limit)
        roll._step = counted
        fast = _points(roll, t, data)
        roll._step = None
        slow = _points(roll, t, data)
        assert fast == slow
        near += sum(len(p[5]) - scene.n_joints for p in fast)
    assert len(calls) == 12 * roll.n and near > 0  # every point took the compiled step; pairs were near
