"""The torque level's predictive off trigger: the torque nominal's closed loop rolled forward, and what it buys."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from isf_robot.arm import load_scene
from isf_robot.arm.torque_rollout import TorqueRollout, pack_points
from isf_robot.arm.torque_sim import TorqueSimulation, resolve_torque_params
from isf_robot.core import ConfigError
from isf_robot.core.jit import compiled

D_BAR = 0.6  # [rad/s^2] (about panda_pole's calibrated figure; passed so that no test calibrates)


class ConstantReference:
    """A velocity reference that is the same everywhere, with the snapshot/restore a rollout needs."""

    def __init__(self, v: np.ndarray) -> None:
        self.v, self.calls, self.state = v, 0, 0

    def __call__(self, t: float, data: mujoco.MjData) -> np.ndarray:
        self.calls += 1
        self.state += 1
        return self.v.copy()

    def snapshot(self) -> int:
        return self.state

    def restore(self, saved: int) -> None:
        self.state = saved


@pytest.fixture(scope="module")
def pole():  # type: ignore[no-untyped-def]
    return load_scene("panda_pole")


def test_the_rollout_is_the_closed_loop_of_computed_torque(pole) -> None:  # type: ignore[no-untyped-def]
    """Known answer on the joint-limit rows: ``q_dot = v_ref + e0 exp(-kd s)``, ``q`` its Euler sum, ``psi`` and its rate.

    A joint-limit row ``h = +-q_i + offset`` has ``psi = +-q_dot_i + alpha_1 h``; with a constant reference the
    rollout's states are known in closed form, and each point's ``Lf`` is the forward difference of ``psi``.
    """
    sim = TorqueSimulation(pole, "isf", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR, horizon=0.0))
    n = pole.n_joints
    v_ref = np.linspace(-0.2, 0.3, n)
    ref = ConstantReference(v_ref)
    kd, a1, horizon = 6.0, 5.0, 0.2
    roll = TorqueRollout(pole, ref, sim.coll, sim.joints, 0.002, 0.0, horizon, kd, a1, points=10)
    data = mujoco.MjData(pole.model)
    data.qpos[pole.qpos_adr] = pole.home
    data.qvel[pole.dof_adr] = v_ref + 0.5  # (a velocity error of 0.5 rad/s on every joint)
    mujoco.mj_forward(pole.model, data)
    pts = roll(1.0, data)
    dt = roll.dt
    assert dt == pytest.approx(0.02) and len(pts) == roll.n == 10
    assert ref.state == 0  # (the reference's state put back)
    q, e = data.qpos[pole.qpos_adr].copy(), np.full(n, 0.5)
    states = []
    for _ in range(roll.n + 1):
        states.append((q.copy(), v_ref + e))
        q = q + dt * (v_ref + e)
        e = e * math.exp(-kd * dt)
    sign, offset = sim.joints.tables[1], sim.joints.tables[2]
    col = np.repeat(np.arange(n), 2)  # (every Panda joint is limited: rows j:min, j:max)
    names = sim.joints.names

    def psi(j: int) -> np.ndarray:
        qj, vj = states[j]
        return sign * vj[col] + a1 * (sign * qj[col] + offset)

    for j, (s, lie, u) in enumerate(pts):
        assert s == pytest.approx(j * dt) and not u.any() and not lie.lg.any()
        at = [lie.names.index(name) for name in names]
        np.testing.assert_allclose(lie.h[at], psi(j), rtol=0, atol=1e-12)
        np.testing.assert_allclose(lie.lf[at], (psi(j + 1) - psi(j)) / dt, rtol=0, atol=1e-9)
        np.testing.assert_allclose(lie.grad_norm[at], 1.0)


def test_rollout_input_errors(pole) -> None:  # type: ignore[no-untyped-def]
    sim = TorqueSimulation(pole, "isf", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR, horizon=0.0))
    ref = ConstantReference(np.zeros(pole.n_joints))
    with pytest.raises(ConfigError, match="horizon"):
        TorqueRollout(pole, ref, sim.coll, sim.joints, 0.002, 0.0, 0.0, 6.0, 5.0)
    with pytest.raises(ConfigError, match="kd"):
        TorqueRollout(pole, ref, sim.coll, sim.joints, 0.002, 0.0, 0.3, -1.0, 5.0)
    roll = TorqueRollout(pole, ref, sim.coll, sim.joints, 0.002, 0.0, 0.3, 6.0, 5.0)
    with pytest.raises(ConfigError, match="shooting"):
        roll(0.0, mujoco.MjData(pole.model), first=np.zeros(pole.n_joints))
    with pytest.raises(ConfigError, match="MjData"):
        roll(0.0, np.zeros(3))


def test_the_predictive_trigger_stops_the_torque_levels_chatter(pole) -> None:  # type: ignore[no-untyped-def]
    """panda_pole, torque level, seed 0: without the rollout the filter switches off for milliseconds at a time;
    with the designed horizon every off period is a real one (>= 0.25 s), the arm safe and the filter on less than
    the standard filter."""
    designed = resolve_torque_params(pole, d_bar=D_BAR)
    assert designed.horizon == pytest.approx(0.26)  # (the velocity level's rule: 0.25 + 5 x 0.002)
    runs = {name: TorqueSimulation(pole, strategy, seed=0, params=params).run(4.0).as_dict()
            for name, strategy, params in (
                ("cbf", "cbf", designed), ("isf", "isf", designed),
                ("isf without", "isf", resolve_torque_params(pole, d_bar=D_BAR, horizon=0.0)))}
    without, isf, cbf = runs["isf without"], runs["isf"], runs["cbf"]
    assert without["short_offs"] >= 1 and without["min_off_s"] < 0.05
    assert isf["short_offs"] == 0 and isf["chatter"] is None
    assert isf["collisions"] == 0 and isf["min_barrier"] > 0 and isf["tau_peak_ratio"] <= 1 + 1e-9
    assert isf["duty_cycle"] < cbf["duty_cycle"]


def test_the_default_step_is_one_control_period(pole) -> None:  # type: ignore[no-untyped-def]
    """Without ``points`` the rollout predicts at every control tick of the horizon (0.26 s: 130 points of 2 ms).

    At rest with a zero reference nothing moves: every point's rows are the state's, with a zero rate.
    """
    sim = TorqueSimulation(pole, "isf", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR, horizon=0.0))
    ref = ConstantReference(np.zeros(pole.n_joints))
    roll = TorqueRollout(pole, ref, sim.coll, sim.joints, 0.002, 0.0, 0.26, 6.0, 5.0)
    assert roll.dt == pytest.approx(0.002) and roll.n == 130
    data = mujoco.MjData(pole.model)
    data.qpos[pole.qpos_adr] = pole.home
    mujoco.mj_forward(pole.model, data)
    pts = roll(0.0, data)
    np.testing.assert_allclose([s for s, _, _ in pts], 0.002 * np.arange(130), atol=1e-12)
    first = pts[0][1]
    for _, lie, _ in pts:
        assert lie.names == first.names
        np.testing.assert_allclose(lie.h, first.h, atol=1e-12)
        np.testing.assert_allclose(lie.lf, 0.0, atol=1e-9)
    with pytest.raises(ConfigError, match="control period"):
        TorqueRollout(pole, ref, sim.coll, sim.joints, 0.0, 0.0, 0.26, 6.0, 5.0)


@pytest.mark.parametrize("name", ["panda_pole", "panda_moving"])
def test_stacked_points_are_the_points_and_start_at_the_ticks_psi(name: str) -> None:
    """The stacked arrays ``predict`` reads hold each point's Lie data (the same prediction either way, names
    included); a point's ``Lg`` is a read-only zero block; point 0's ``psi`` is the filter's own row at the state
    (moving obstacles placed on their track, ``approaching`` rows), for every row present at points 0 and 1."""
    from isf_robot.core import as_class_k
    from isf_robot.core.intermittent import StackedPoints, predict

    scene = load_scene(name)
    params = resolve_torque_params(scene, d_bar=D_BAR)
    sim = TorqueSimulation(scene, "isf", seed=0, params=params)
    roll = sim.strategy.predictor.rollout
    assert isinstance(roll, TorqueRollout)
    ep = sim.episode(sim, 10)
    rng = np.random.default_rng(2)
    data, alpha = ep.data, as_class_k(params.alpha)
    seen = 0
    for _ in range(8):
        data.qpos[scene.qpos_adr] = scene.home + rng.uniform(-0.5, 0.5, scene.n_joints)
        data.qvel[scene.dof_adr] = rng.uniform(-1.0, 1.0, scene.n_joints)
        t = float(rng.uniform(0.0, 3.0))
        lin = sim._clock(data, t) if scene.config.moving else None
        mujoco.mj_forward(scene.model, data)
        psi, _ = sim.second_order.tick(data, t, sim.dynamics.terms(data), lin)
        pts = roll(t, data)
        assert type(pts) is StackedPoints
        listed = list(pts)
        for d_bar in (0.0, 5.0):  # (5 rad/s^2: some rows predicted to fail, so their names are looked up)
            a, b = predict(pts, alpha, d_bar), predict(listed, alpha, d_bar)
            assert (a.ok, a.first_fail_s, a.failing) == (b.ok, b.first_fail_s, b.failing)
            assert a.xi_min == pytest.approx(b.xi_min, rel=1e-12, abs=1e-12)
        for j, (_, lie, u) in enumerate(listed):
            k = pts.rows[j]
            np.testing.assert_array_equal(lie.h, pts.h[j, :k])
            np.testing.assert_array_equal(lie.lf, pts.lf[j, :k])
            assert not u.any() and not lie.lg.any() and lie.lg.shape == (k, scene.n_joints)
            assert not lie.lg.flags.writeable
        at = {nm: i for i, nm in enumerate(psi.names)}
        first = listed[0][1]
        rows = [at[nm] for nm in first.names]
        np.testing.assert_allclose(first.h, psi.h[rows], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(first.grad_norm, psi.grad_norm[rows], rtol=1e-12, atol=1e-12)
        seen += len(rows)
    assert seen > 8 * 2 * scene.n_joints  # (collision rows too, not only the joint limits)


def _torque_points(roll, t, data):  # type: ignore[no-untyped-def]
    return [(s, lie.names, np.concatenate((lie.h, lie.lf, lie.grad_norm))) for s, lie, _ in roll(t, data)]


def _compare_paths(name: str, states: int, goals=None) -> tuple:  # type: ignore[no-untyped-def]
    """Torque rollouts from random states by the compiled points, the compiled Euler step alone and numpy; returns
    (rows compared, whole-path calls that finished, Euler-step calls)."""
    from isf_robot.arm import kernels

    if not kernels.available():
        pytest.skip("compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")
    scene = load_scene(name)
    sim = TorqueSimulation(scene, "isf", seed=3, params=resolve_torque_params(scene, d_bar=D_BAR))
    roll = sim.strategy.predictor.rollout
    whole, step = roll._whole, roll._step
    assert whole is not None and step is not None
    done: list[int] = []  # (per call of the kernel: 1 when it finished without touching points)
    steps: list[int] = []

    def counted_whole(*a):  # type: ignore[no-untyped-def]
        out = whole(*a)
        done.append(int(out == roll.n and not a[30][roll.n - 1, 4]))  # (a[30]: its res)
        return out

    rng = np.random.default_rng(8)
    data = mujoco.MjData(scene.model)
    nom, rows = sim.nominal, 0
    nom.reset()
    for k in range(states):
        t = 0.2 + 0.05 * k
        data.qpos[scene.qpos_adr] = sim.setup.q0 + rng.normal(scale=0.4, size=scene.n_joints)
        data.qvel[scene.dof_adr] = rng.uniform(-1.0, 1.0, scene.n_joints)
        lin = sim._clock(data, t) if scene.config.moving else None
        mujoco.mj_forward(scene.model, data)
        if goals is not None:
            goals(nom, data, t)
        nom(t - 0.002, data)  # (a previous command for the rate limit)
        before = nom.snapshot()
        roll._whole, roll._step = counted_whole, (lambda *a: steps.append(1) or step(*a))
        fast = _torque_points(roll, t, data)
        after = nom.snapshot()
        assert after[1].tolist() == before[1].tolist() and after[2] == before[2]  # (the controller put back)
        roll._whole = None
        euler = _torque_points(roll, t, data)
        roll._step = None
        slow = _torque_points(roll, t, data)
        for a, b in ((fast, slow), (euler, slow)):
            assert len(a) == len(b)
            for pa, pb in zip(a, b):
                assert pa[0] == pb[0] and pa[1] == pb[1]
                scale = max(1.0, float(np.max(np.abs(pb[2]), initial=0.0)))
                np.testing.assert_allclose(pa[2], pb[2], rtol=1e-12, atol=1e-12 * scale / roll.dt)
        rows += sum(len(p[1]) - len(sim.joints.names) for p in fast)
        assert lin is None or lin.shape == (scene.model.nmocap, 3)
    assert rows > 0  # (pairs within the cut-off were compared)
    return roll, (len(done), sum(done)), len(steps)


@pytest.mark.parametrize("name", ["panda_pole", "panda_moving"])
def test_compiled_torque_points_are_the_loops(name: str) -> None:
    """The points after the first in one compiled call (``closed_loop_points``) are the numpy loop's, to rounding (the
    rates: ``1e-12`` of the scale over ``dt``), with static and moving obstacles; the Euler-step path too."""
    roll, whole, euler = _compare_paths(name, 8)
    assert whole == (8, 8) and euler == 8 * roll.n  # (the whole path at every state; the Euler path once per point)


def test_a_goal_change_within_the_horizon_takes_the_loop(goal_reached_at_once) -> None:  # type: ignore[no-untyped-def]
    roll, whole, euler = _compare_paths("panda_pole", 4, goals=goal_reached_at_once)
    assert whole == (0, 0) and euler == 2 * 4 * roll.n  # (never the kernel: goals.steady said no)


def test_coinciding_witness_points_fall_back_to_the_loop(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Every near pair touching: the kernel stops at its first point with one, and the loop redoes the points
    after the first from the state the kernel started from (the same points as numpy's)."""
    from isf_robot.arm import narrow as narrow_module

    monkeypatch.setattr(narrow_module, "_EPS_DIST", 10.0)
    roll, whole, euler = _compare_paths("panda_pole", 4)
    assert whole == (4, 0) and euler == 2 * 4 * roll.n  # (the kernel ran at every state and stopped early)


def test_pack_points_known_answer_and_compiled_as_written() -> None:
    """The rollout's tables packed per point: the rows present at j and j + 1, ascending keys, psi's difference."""
    psi = np.array([[1.0, 2.0, 3.0], [1.5, 9.0, 2.0], [0.0, 4.0, 1.0]])
    gn = np.arange(9.0).reshape(3, 3)
    present = np.array([[True, False, True], [True, True, True], [False, True, True]])
    h, lf, g, keys, rows = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3), np.int64), \
        np.empty(2, np.int64)
    pack_points(psi, gn, present, 0.5, h, lf, g, keys, rows)
    assert rows.tolist() == [2, 2]
    np.testing.assert_array_equal(h, [[1.0, 3.0, 0.0], [9.0, 2.0, 0.0]])
    np.testing.assert_array_equal(lf, [[1.0, -2.0, 0.0], [-10.0, -2.0, 0.0]])
    np.testing.assert_array_equal(g, [[0.0, 2.0, 0.0], [4.0, 5.0, 0.0]])
    np.testing.assert_array_equal(keys, [[0, 2, 0], [1, 2, 0]])
    rng = np.random.default_rng(0)
    fast = compiled(pack_points)
    for _ in range(50):
        n, K = int(rng.integers(1, 30)), int(rng.integers(1, 60))
        psi, gn, present = rng.normal(size=(n + 1, K)), rng.uniform(size=(n + 1, K)), rng.random((n + 1, K)) < 0.6
        outs = []
        for fn in (pack_points, fast):
            out = (np.zeros((n, K)), np.zeros((n, K)), np.zeros((n, K)), np.zeros((n, K), np.int64),
                   np.empty(n, np.int64))
            fn(psi, gn, present, 0.01, *out)
            outs.append(out)
        for a, b in zip(*outs):
            np.testing.assert_array_equal(a, b)  # (the same operations in the same order: the same bits)
