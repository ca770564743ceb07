"""The whole-rollout path hands predict() its points stacked (StackedPoints): the same Prediction as the loop.

On panda_pole, from random states: the compiled rollout returns StackedPoints whose per-point Lie data
are the stacked arrays' own memory (the very numbers), and predict() of them
equals predict() of the plain list, with the filter's kernel and with numpy. Skipped without numba.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from isf_robot.arm import ArmSimulation, kernels, load_scene
from isf_robot.arm.params import resolve_params
from isf_robot.core import Linear, Power
from isf_robot.core.intermittent import StackedPoints, predict

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")


def _ptr(a: np.ndarray) -> tuple:
    return a.__array_interface__["data"][0], a.shape, a.strides


def test_the_compiled_rollouts_stacked_points_predict_as_the_loop(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_pole")
    params = resolve_params(scene, d_bar=0.05, horizon=0.3, calibrate=False)
    sim = ArmSimulation(scene, "isf", seed=3, params=params)
    roll = sim.strategy.predictor.rollout
    rng = np.random.default_rng(7)
    data = mujoco.MjData(scene.model)
    nom = sim.nominal
    nom.reset()
    outcomes = set()
    for k in range(12):
        t = 0.2 + 0.05 * k
        data.qpos[scene.qpos_adr] = sim.setup.q0 + rng.normal(scale=0.4, size=scene.n_joints)
        mujoco.mj_forward(scene.model, data)
        nom(t - 0.01, data)  # (a previous command for the rate limit)
        pts = roll(t, data)
        assert type(pts) is StackedPoints and len(pts) == roll.n
        names = [pts.row_names(j, list(range(int(pts.rows[j]) + 2))) for j in range(len(pts))]  # (before the points are built)
        for j, (s, lie, u) in enumerate(pts):
            assert names[j] == [*lie.names, str(lie.k), str(lie.k + 1)] and s == (j + 1) * roll.dt
            kj = int(pts.rows[j])
            assert _ptr(lie.lg) == _ptr(pts.lg[j, :kj]) and _ptr(u) == _ptr(pts.u[j])  # (lg: the rollout's block)
            for a, b in ((lie.h, pts.h), (lie.lf, pts.lf), (lie.grad_norm, pts.grad_norm)):
                assert _ptr(a) == _ptr(b[j, :kj])
        assert pts._rows == pts.rows.tolist() and list(pts.s) == [s for s, _, _ in pts]  # (the unchecked build's layout)
        for alpha in (Linear(params.alpha), Power(3.0, 0.7)):
            fresh = StackedPoints(pts.s, pts.u, pts.rows, pts.h, pts.lf, pts.lg, pts.grad_norm, pts._point,
                                  pts._row_names)
            monkeypatch.setenv("ISF_ROBOT_JIT", "1")
            keyed = StackedPoints(pts.s, pts.u, pts.rows, pts.h, pts.lf, pts.lg, pts.grad_norm, pts._point,
                                  None, pts.keys, pts.key_names)  # (the failing names by the rows' keys alone)
            got, ref = predict(fresh, alpha, params.d_bar), predict(list(pts), alpha, params.d_bar)
            assert repr(predict(keyed, alpha, params.d_bar)) == repr(got)
            monkeypatch.setenv("ISF_ROBOT_JIT", "0")
            ref0 = predict(list(pts), alpha, params.d_bar)
            for other in (ref, ref0):  # (the same prediction; the least value to rounding: 1e-12 relative)
                assert (got.ok, got.first_fail_s, got.failing, got.points) == (
                    other.ok, other.first_fail_s, other.failing, other.points)
                assert got.xi_min == pytest.approx(other.xi_min, rel=1e-12, abs=1e-12)
            outcomes.add(got.ok)
    assert outcomes == {True, False}
