"""The rollout's compiled paths (``isf_robot.arm._rollout_jit``): the general loop's points, to 1e-12 relative.

``NominalRollout`` runs every point in one compiled call while the goal index cannot change over the
horizon (``GoalSequence.steady``), otherwise it advances each point's Euler step and kinematics in one
compiled call; either way the points must be those of the numpy loop (names exactly; rows and
commands to ``RTOL``: the same formulas, compiled), with
static and with moving obstacles, when the goal changes within the horizon, and when witness points
coincide (the numpy narrow phase's case). Skipped without numba.
"""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.arm import ArmSimulation, kernels, load_scene
from isf_robot.arm import narrow as narrow_module
from isf_robot.arm.params import resolve_params

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")


RTOL = 1e-12


def _points(roll, t, data):  # type: ignore[no-untyped-def]
    return [(s, lie.names, np.concatenate((lie.h, lie.lf, lie.lg.ravel(), lie.grad_norm, u)))
            for s, lie, u in roll(t, data)]


def _same_points(a, b) -> bool:  # type: ignore[no-untyped-def]
    """The same times and row names, the numbers to ``RTOL`` (relative, floor ``RTOL`` times their scale)."""
    def close(x: np.ndarray, y: np.ndarray) -> bool:
        scale = max(1.0, float(np.max(np.abs(y[np.isfinite(y)]), initial=0.0)))
        return x.shape == y.shape and bool(np.allclose(x, y, rtol=RTOL, atol=RTOL * scale))

    return len(a) == len(b) and all(pa[:2] == pb[:2] and close(pa[2], pb[2]) for pa, pb in zip(a, b))


def _counted(fn, calls):  # type: ignore[no-untyped-def]
    return None if fn is None else (lambda *a: calls.append(1) or fn(*a))


def _compare(states_of, name: str, states: int, monkeypatch=None, seed: int = 3, goals=None):  # type: ignore[no-untyped-def]
    """Rollouts from random states with each path in turn; returns (points compared, whole-path calls, Euler calls)."""
    scene = load_scene(name)
    params = resolve_params(scene, d_bar=0.05, horizon=0.3, calibrate=False)
    sim = ArmSimulation(scene, "isf", seed=seed, params=params)
    roll = sim.strategy.predictor.rollout
    whole, step = roll._whole, roll._step
    assert step is not None and whole is not None
    wc: list[int] = []
    sc: list[int] = []
    near = 0
    for t, data in states_of(scene, sim, states, goals):
        roll._whole, roll._step = _counted(whole, wc), _counted(step, sc)
        fast = _points(roll, t, data)
        roll._whole = None
        euler = _points(roll, t, data)
        roll._step = None
        slow = _points(roll, t, data)
        assert _same_points(fast, slow) and _same_points(euler, slow)
        near += sum(len(p[1]) - scene.n_joints for p in fast)
    assert near > 0  # pairs within the cut-off were compared
    return roll, len(wc), len(sc)


@pytest.mark.parametrize("name", ["panda_pole", "planar_moving", "panda_moving"])
def test_compiled_paths_give_the_numpy_loops_points(name, rollout_states) -> None:  # type: ignore[no-untyped-def]
    roll, whole, euler = _compare(rollout_states, name, 10)
    # the whole rollout in one call at each state (moving obstacles placed by the kernel), then the
    # Euler-step path once per point
    assert whole == 10 and euler == 10 * roll.n
    assert roll.moving == (name != "panda_pole")


def test_a_goal_change_within_the_horizon_takes_the_general_loop(goal_reached_at_once, rollout_states) -> None:  # type: ignore[no-untyped-def]
    roll, whole, euler = _compare(rollout_states, "panda_pole", 6, goals=goal_reached_at_once)
    assert whole == 0 and euler == 2 * 6 * roll.n  # never the whole-rollout kernel (goals.steady said no)


def test_coinciding_witness_points_fall_back_to_the_general_loop(monkeypatch, rollout_states) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setattr(narrow_module, "_EPS_DIST", 10.0)  # every near pair counts as touching
    roll, whole, euler = _compare(rollout_states, "panda_pole", 4)
    assert whole == 4  # the kernel ran, stopped at the first touching point, and the general loop redid the rollout
