"""The team's compiled rollout (``_rollout_jit.team_points``) and its split per arm: the general loop's points.

A :class:`~isf_robot.arm.team_nominal.TeamReaching` nominal rolls out in one compiled call while every arm's goal is
steady over the horizon; its points must be those of the point-by-point loop (row names exactly, ``h``, ``Lf h``,
``Lg h``, ``|dh/dq|`` and the commands to 1e-12 relative), and a goal that can change within the horizon takes the
loop. The stacked points are split for every arm in one call (:meth:`SharedRows.split_points`): each arm's points
equal the point-by-point split (:meth:`_Involved.split`), and so does the prediction over them. Skipped without numba.
"""

from __future__ import annotations

from collections.abc import Iterator

import mujoco
import numpy as np
import pytest

from isf_robot.arm import kernels, load_scene
from isf_robot.arm.multi_arm import MultiArmSimulation
from isf_robot.arm.params import resolve_params
from isf_robot.arm.rollout import NominalRollout
from isf_robot.core import Linear
from isf_robot.core.intermittent import StackedPoints, predict
from isf_robot.core.shares import SharedRows, split_points

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")

RTOL = 1e-12


def _close(x: np.ndarray, y: np.ndarray) -> bool:
    scale = max(1.0, float(np.max(np.abs(y[np.isfinite(y)]), initial=0.0)))
    return x.shape == y.shape and bool(np.allclose(x, y, rtol=RTOL, atol=RTOL * scale))


def _flat(lie, u) -> np.ndarray:  # type: ignore[no-untyped-def]
    return np.concatenate((lie.h, lie.lf, lie.lg.ravel(), lie.grad_norm, np.asarray(u, dtype=float)))


@pytest.fixture
def team():  # type: ignore[no-untyped-def]
    """panda_pair's nominal and a rollout of it (0.3 s, 10 points); fresh per test (a test moves goals)."""
    scene = load_scene("panda_pair")
    params = resolve_params(scene, d_bar=0.05, horizon=0.3, calibrate=False)
    sim = MultiArmSimulation(scene, "isf", coordination="central", seed=3, params=params)
    roll = NominalRollout(scene, sim.nominal, sim.coll, sim.joints, sim.control_period, 0.0, 0.3)
    assert roll._team is not None and roll._whole is None
    return scene, sim, roll


def _states(scene, sim, count: int, near_goal: bool = False) -> Iterator[tuple[float, mujoco.MjData]]:  # type: ignore[no-untyped-def]
    """Random states where the arms reach toward each other (arm-arm pairs within the cut-off), each arm with a
    previous command (``near_goal``: arm 0's goal at its end effector with a short dwell, so that its goal can
    change within the horizon)."""
    rng = np.random.default_rng(7)
    data = mujoco.MjData(scene.model)
    nom = sim.nominal
    nom.reset()
    close = scene.home.copy()
    close[[0, 1, 3, 7, 8, 10]] = -1.57, 1.0, -1.0, 0.0, 1.0, -1.0  # (both shoulders forward, arm 0 turned in)
    for k in range(count):
        t = 0.2 + 0.05 * k
        data.qpos[scene.qpos_adr] = close + rng.normal(scale=0.05, size=scene.n_joints)
        mujoco.mj_forward(scene.model, data)
        if near_goal:
            arm = nom.arms[0]
            arm.goals.reset()
            arm.goals.dwell[:] = 0.05
            arm.goal_positions[arm.goals.index] = arm.scene.ee_position(data)
        nom(t - 0.01, data)
        yield t, data


def _runs(roll) -> list[int]:  # type: ignore[no-untyped-def]
    """Count the team kernel's calls (the rollout's own TeamPoints)."""
    calls: list[int] = []
    team = roll._team
    run = type(team).run
    team.run = lambda *a: calls.append(1) or run(team, *a)
    return calls


@pytest.mark.parametrize("near_goal", [False, True])
def test_team_rollout_gives_the_loops_points(team, near_goal) -> None:  # type: ignore[no-untyped-def]
    scene, sim, roll = team
    calls = _runs(roll)
    compiled_team = roll._team
    pairs = 0
    try:
        for t, data in _states(scene, sim, 8, near_goal):
            roll._team = compiled_team
            fast = roll(t, data)
            roll._team = None
            slow = roll(t, data)
            assert (type(fast) is StackedPoints) is not near_goal
            assert len(fast) == len(slow) == roll.n
            for (s1, a, u1), (s2, b, u2) in zip(fast, slow):
                assert s1 == s2 and a.names == b.names
                assert _close(_flat(a, u1), _flat(b, u2))
                pairs += a.k - scene.n_joints
    finally:
        roll._team = compiled_team
    assert pairs > 0  # pairs within the cut-off, arm-arm among them, were compared
    # one compiled call per rollout while the goals are steady; none when arm 0's goal can change (the loop)
    assert len(calls) == (0 if near_goal else 8)


def test_stacked_points_split_per_arm_as_point_by_point(team) -> None:  # type: ignore[no-untyped-def]
    scene, sim, roll = team
    blocks = tuple(a.joints for a in scene.arms)
    rows = SharedRows(blocks)
    shared = fails = 0
    for t, data in _states(scene, sim, 8):
        points = roll(t, data)
        agents = rows.split_points(points)
        assert agents is not None and len(agents) == len(blocks)
        loop = [SharedRows(blocks)(lie).split(lie) for _, lie, _ in points]
        for i, b in enumerate(blocks):
            for j, (s, lie, u) in enumerate(agents[i]):
                ref = loop[j][i]
                assert s == points[j][0] and lie.names == ref.names
                np.testing.assert_array_equal(_flat(lie, u), _flat(ref, np.asarray(points[j][2])[b]))
                shared += int(SharedRows(blocks)(points[j][1]).shared.sum())
            for d_bar in (0.0, 0.3, 20.0):
                p1 = predict(agents[i], Linear(5.0), d_bar)
                p2 = predict([(s, loop[j][i], np.asarray(u)[b]) for j, (s, _, u) in enumerate(points)], Linear(5.0),
                             d_bar)
                assert (p1.ok, p1.failing, p1.first_fail_s, p1.points) == (p2.ok, p2.failing, p2.first_fail_s,
                                                                          p2.points)
                assert p1.xi_min == pytest.approx(p2.xi_min, rel=RTOL, abs=RTOL)
                fails += not p1.ok
    assert shared > 0 and fails > 0  # inter-arm rows (shared) and failing predictions were compared
    assert rows.split_points(list(points)) is None  # (points as a list: split point by point)
    plain = SharedRows(blocks)
    plain._split = split_points  # (as written: not taken, the points are split one by one)
    assert plain.split_points(points) is None
    written = split_points  # (as written it gives the same numbers)
    plain._split = lambda *a: written(*a)
    plain._split.py_func = written  # type: ignore[attr-defined]
    two = StackedPoints._of(points.s[:2], points.u[:2], points.rows[:2], points._rows[:2], points.h[:2], points.lf[:2],
                            points.lg[:2], points.grad_norm[:2], points._point, None, points.keys[:2],
                            points.key_names)  # (its first two points: the loops as written are slow)
    for a, b in zip(plain.split_points(two), agents):
        for (s1, x, u1), (s2, y, u2) in zip(a, b):
            assert s1 == s2 and x.names == y.names
            np.testing.assert_array_equal(_flat(x, u1), _flat(y, u2))


def test_kept_rollout_points_stay_and_dropped_ones_give_their_blocks_back(team) -> None:  # type: ignore[no-untyped-def]
    """The points' blocks come from a pool (:class:`~isf_robot.arm.output_blocks.BlockPool`): points kept past later
    rollouts are never written again; points dropped let the next rollouts reuse their blocks."""
    scene, sim, roll = team
    kept = []
    for i, (t, data) in enumerate(_states(scene, sim, 8)):
        points = roll(t, data)
        assert type(points) is StackedPoints
        if i % 2 == 0:
            kept.append((points, [_flat(lie, u).copy() for _, lie, u in points]))
        del points
    pool = next(p for p in sim.coll._kblocks.values() if p.count == roll.n)
    assert pool.made == 5  # (a dropped rollout's blocks serve the next rollout, which is kept: 4 kept, 1 more)
    for points, flats in kept:
        assert all(np.array_equal(_flat(lie, u), f) for (_, lie, u), f in zip(points, flats))
