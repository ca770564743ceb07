"""The rollout's prediction in one compiled call (``_rollout_jit.closed_loop_predict``): the loop's Prediction.

``NominalRollout.prediction(t, x, alpha, d_bar)`` runs the points and their ``Xi_on`` in one call; it must
give what ``predict(rollout(t, x), alpha, d_bar)`` gives from the same state: bit for bit against the
compiled rollout's stacked points, and against the numpy loop's points predicted by numpy (the plain path,
as under ``ISF_ROBOT_JIT=0``) the same ``ok``, ``first_fail_s``, ``failing`` and ``points`` with ``xi_min`` to
1e-12 relative. It leaves the controller and the episode's data as they were (it computes the command now
itself, as the controller does while its goal stays), and answers ``None`` (the off trigger then rolls out
and predicts) where its path does not serve. Skipped without numba.
"""

from __future__ import annotations

import pytest

from isf_robot.arm import ArmSimulation, kernels, load_scene
from isf_robot.arm import narrow as narrow_module
from isf_robot.arm.params import resolve_params
from isf_robot.core import Linear, Power
from isf_robot.core.intermittent import StackedPoints, predict
from isf_robot.core.robust import predict_pass

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")

RTOL = 1e-12


def _setup(name: str, seed: int = 3):  # type: ignore[no-untyped-def]
    scene = load_scene(name)
    params = resolve_params(scene, d_bar=0.05, horizon=0.3, calibrate=False)
    sim = ArmSimulation(scene, "isf", seed=seed, params=params)
    return scene, params, sim, sim.strategy.predictor.rollout


def _state_of(nom, data) -> tuple:  # type: ignore[no-untyped-def]
    goals, prev, t_prev = nom.snapshot()
    return repr(sorted(goals.items())), prev.tolist(), t_prev, data.qpos.tolist(), data.mocap_pos.tolist()


@pytest.mark.parametrize("name", ["panda_pole", "panda_moving"])
def test_the_one_call_prediction_is_the_loops(name, rollout_states) -> None:  # type: ignore[no-untyped-def]
    scene, params, sim, roll = _setup(name)
    assert roll._fused is not None
    alpha = Linear(params.alpha)
    outcomes = set()
    for t, data in rollout_states(scene, sim, 12):
        before = _state_of(sim.nominal, data)
        calls = roll.calls
        got = roll.prediction(t, data, alpha, params.d_bar)
        assert got is not None and roll.calls == calls + 1
        assert _state_of(sim.nominal, data) == before  # (the controller and the episode as they were)
        pts = roll(t, data)
        assert type(pts) is StackedPoints
        assert repr(predict(pts, alpha, params.d_bar)) == repr(got)  # (the compiled pass over the same points)
        whole, step = roll._whole, roll._step
        roll._whole = roll._step = None  # (the numpy loop's points, predicted by the pass as written)
        try:
            ref = predict(list(roll(t, data)), alpha, params.d_bar, kernel=predict_pass)
        finally:
            roll._whole, roll._step = whole, step
        assert (got.ok, got.first_fail_s, got.failing, got.points) == (ref.ok, ref.first_fail_s, ref.failing,
                                                                       ref.points)
        assert got.xi_min == pytest.approx(ref.xi_min, rel=RTOL, abs=RTOL)
        outcomes.add(got.ok)
    assert outcomes == {True, False}


def test_the_off_trigger_takes_the_one_call_prediction(rollout_states) -> None:  # type: ignore[no-untyped-def]
    scene, params, sim, roll = _setup("panda_pole")
    predictor = sim.strategy.predictor
    assert predictor._fused == roll.prediction
    (t, data), = rollout_states(scene, sim, 1)
    alpha = Linear(params.alpha)
    pred, ran = predictor.check(t, data, alpha, params.d_bar)
    assert ran and repr(pred) == repr(predict(roll(t, data), alpha, params.d_bar))


def test_where_the_one_call_does_not_serve_it_answers_none(monkeypatch, rollout_states) -> None:  # type: ignore[no-untyped-def]
    scene, params, sim, roll = _setup("panda_pole")
    (t, data), = rollout_states(scene, sim, 1)
    before = _state_of(sim.nominal, data)
    assert roll.prediction(t, data, Power(3.0, 0.7), params.d_bar) is None  # (alpha(h) not linear)
    monkeypatch.setattr(narrow_module, "_EPS_DIST", 10.0)  # every near pair counts as touching
    calls = roll.calls
    assert roll.prediction(t, data, Linear(params.alpha), params.d_bar) is None and roll.calls == calls
    assert _state_of(sim.nominal, data) == before
    # and the off trigger then rolls out (the general loop) and predicts
    pred, ran = sim.strategy.predictor.check(t, data, Linear(params.alpha), params.d_bar)
    assert ran and roll.calls == calls + 1 and pred.points == roll.n


def test_a_goal_that_may_change_from_now_takes_the_long_way(goal_reached_at_once, rollout_states) -> None:  # type: ignore[no-untyped-def]
    scene, params, sim, roll = _setup("panda_pole")
    alpha = Linear(params.alpha)
    for t, data in rollout_states(scene, sim, 3, goals=goal_reached_at_once):
        before = _state_of(sim.nominal, data)
        assert roll.prediction(t, data, alpha, params.d_bar) is None
        assert _state_of(sim.nominal, data) == before
        pred, ran = sim.strategy.predictor.check(t, data, alpha, params.d_bar)
        assert ran and repr(pred) == repr(predict(roll(t, data), alpha, params.d_bar))
        sim.strategy.predictor.idle()
    sim.nominal.reset()  # (no previous command: the rate limit's first call is the controller's own)
    assert roll.prediction(t, data, alpha, params.d_bar) is None


def test_cached_mode_without_the_fused_kernel_takes_the_points_path(monkeypatch) -> None:
    """``ISF_ROBOT_JIT=cached`` with the rollout's kernels in numba's cache but not the fused prediction: the
    rollout has no ``_fused`` (never the plain function in its place) and the run is the compiled one."""
    from isf_robot.core import jit

    scene = load_scene("panda_pole")
    params = resolve_params(scene, d_bar=0.05, horizon=0.3, calibrate=False)
    full = ArmSimulation(scene, "isf", seed=3, params=params).run(0.6)

    def held(kernels_):  # type: ignore[no-untyped-def]  (every kernel in the cache but the fused prediction)
        return (0, 1) if any(getattr(k, "__name__", "") == "closed_loop_predict" for k in kernels_) else (1, 1)

    monkeypatch.setattr(jit, "compiled_here", held)
    monkeypatch.setenv("ISF_ROBOT_JIT", jit.CACHED_ONLY)
    sim = ArmSimulation(scene, "isf", seed=3, params=params)
    rollout = sim.strategy.predictor.rollout
    assert rollout._whole is not None and rollout._fused is None
    got = sim.run(0.6)
    assert (got.on_switches, got.qp_solves) == (full.on_switches, full.qp_solves)
    assert got.duty_cycle == pytest.approx(full.duty_cycle, abs=1e-12)
