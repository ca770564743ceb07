"""The intermittent filter's options on the arm: the rollout of the nominal on the reduced model
(against a brute-force fine-step integration), the options through resolve_params and the
simulation, and the hand-over's command-jump metric."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from isf_robot.arm import ArmSimulation, CollisionBarriers, JointLimitBarriers, ReachingController
from isf_robot.arm.params import resolve_params
from isf_robot.arm.rollout import NominalRollout
from isf_robot.core import ConfigError, Linear
from isf_robot.core.intermittent import predict


def _state(scene, sim, t: float) -> mujoco.MjData:
    data = mujoco.MjData(scene.model)
    data.qpos[scene.qpos_adr] = sim.setup.q0
    scene.set_moving_obstacles(data, t + sim.setup.time_offset)
    mujoco.mj_forward(scene.model, data)
    return data


def test_rollout_matches_a_brute_force_fine_step_integration(planar_moving):
    scene = planar_moving
    params = resolve_params(scene, d_bar=0.05, horizon=0.2, predict_every=3)
    sim = ArmSimulation(scene, "isf", seed=4, params=params)
    roll = sim.strategy.predictor.rollout
    assert isinstance(roll, NominalRollout) and roll.n * roll.dt == pytest.approx(0.2)
    t0 = 0.3
    data = _state(scene, sim, t0)
    nom = sim.nominal
    nom.reset()
    for k in range(10):  # give the rate-limited command time to build up
        nom(t0 - 0.1 + k * 0.01, data)
    before = nom.snapshot()
    pts = roll(t0, data)
    after = nom.snapshot()
    assert before[0] == after[0] and np.array_equal(before[1], after[1]) and before[2] == after[2]

    # brute force: an independent controller in the same state, Euler steps 20x finer, every pair
    ref = ReachingController(scene, goals=sim.setup.goals)
    ref.restore(before)
    coll, joints = CollisionBarriers.from_scene(scene), JointLimitBarriers.from_scene(scene)
    d = _state(scene, sim, t0)
    q = d.qpos[scene.qpos_adr].copy()
    fine = roll.dt / 20
    u = np.array(ref(t0, d))
    t, by_s = t0, {}
    for j in range(1, roll.n * 20 + 1):
        q = q + fine * u
        t = t0 + j * fine
        d.qpos[scene.qpos_adr] = q
        scene.set_moving_obstacles(d, t + sim.setup.time_offset)
        mujoco.mj_forward(scene.model, d)
        u = np.array(ref(t, d))
        if j % 20 == 0:
            lin = scene.mocap_velocities(t + sim.setup.time_offset)[0]
            by_s[round(j * fine, 9)] = (coll.evaluate(d, lin), joints.evaluate(d), u.copy())
    assert len(pts) == roll.n == len(by_s)
    for s, lie, u_pred in pts:
        cb, jb, u_ref = by_s[round(s, 9)]
        h_ref = dict(zip(cb.names + jb.names, np.concatenate((cb.h, jb.h))))
        for name, h in zip(lie.names, lie.h):
            assert h == pytest.approx(h_ref[name], abs=2e-3), (s, name)  # Euler at dt vs dt/20
        np.testing.assert_allclose(u_pred, u_ref, atol=0.05)
    p = predict(pts, Linear(params.alpha), params.d_bar)
    assert p.points == roll.n and math.isfinite(p.xi_min)


def test_rollout_rows_are_the_active_rows_of_a_full_evaluation_bit_for_bit(planar_moving):
    # The rollout builds its rows as the simulation does (CollisionBarriers.rows/lie); they are the
    # active rows of evaluate() and the joint rows, the same floats and names.
    scene = planar_moving
    sim = ArmSimulation(scene, "isf", seed=4, params=resolve_params(scene, d_bar=0.05, horizon=0.2))
    roll = sim.strategy.predictor.rollout
    rng = np.random.default_rng(0)
    data = _state(scene, sim, 0.3)
    seen_near = 0
    for _ in range(40):
        data.qpos[scene.qpos_adr] = sim.setup.q0 + rng.normal(scale=0.6, size=scene.n_joints)
        mujoco.mj_forward(scene.model, data)
        lin = scene.mocap_velocities(0.3 + sim.setup.time_offset)[0]
        lie = roll._rows(data, lin)
        cb, jb = sim.coll.evaluate(data, lin), sim.joints.evaluate(data)
        act = cb.active.nonzero()[0]
        seen_near += act.size
        assert lie.names == tuple(cb.names[i] for i in act.tolist()) + tuple(jb.names)
        g = np.concatenate((cb.grad[act], jb.grad))
        for got, want in ((lie.h, np.concatenate((cb.h[act], jb.h))), (lie.lf, np.concatenate((cb.dhdt[act], jb.dhdt))),
                          (lie.lg, g), (lie.grad_norm, np.linalg.norm(g, axis=1))):
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)  # (the same formulas, either path)
    assert seen_near > 0  # (some states with pairs within the cut-off)


def test_predictive_trigger_on_the_arm_is_safe_and_bounded(planar_moving):
    scene = planar_moving
    base = resolve_params(scene, d_bar=0.05, blend=0.0, horizon=0.0)  # (no designed options: the plain filter)
    plain = ArmSimulation(scene, "isf", seed=3, params=base).run(3.0)
    pred = resolve_params(scene, d_bar=0.05, horizon=0.15, predict_every=4)
    sim = ArmSimulation(scene, "isf", seed=3, params=pred)
    res = sim.run(3.0)
    assert res.collisions == 0 and res.min_barrier >= 0
    on_steps = round(res.duty_cycle * res.control_steps)
    roll = sim.strategy.predictor
    # rollouts only while on (the every-k-steps count is checked with a fake clock in tests/core)
    assert 0 < roll.rollouts <= on_steps and sim.strategy.predictor.rollout.calls == roll.rollouts
    assert res.on_switches <= plain.on_switches
    d = res.as_dict()
    assert d["horizon"] == 0.15 and d["predict_every"] == 4
    assert "horizon" not in plain.as_dict() and "min_off" not in plain.as_dict()


def test_blend_removes_the_command_jump_at_switches(planar):
    p0 = resolve_params(planar, d_bar=0.05, blend=0.0, horizon=0.0)
    p1 = resolve_params(planar, d_bar=0.05, blend=0.03, horizon=0.0)
    r0 = ArmSimulation(planar, "isf", seed=1, params=p0).run(3.0)
    r1 = ArmSimulation(planar, "isf", seed=1, params=p1).run(3.0)
    assert r0.on_switches > 0 and r1.on_switches > 0
    assert r1.switch_jump_max < 0.25 * r0.switch_jump_max
    assert r1.collisions == 0 and r1.min_barrier >= 0
    assert r1.as_dict()["blend"] == 0.03


def test_min_off_is_capped_at_what_a_pair_at_the_cutoff_can_reach(planar):
    p = resolve_params(planar, d_bar=0.05, min_off=0.3)
    sim = ArmSimulation(planar, "isf", seed=0, params=p)
    cutoff_h = float(np.min(sim.coll.cutoff - sim.coll.pairs.margin))
    assert sim.strategy.c_max == pytest.approx(max(p.c, p.class_k(cutoff_h)))
    cbf = ArmSimulation(planar, "cbf", seed=0, params=p)  # the options do not reach the standard filter
    assert not hasattr(cbf.strategy, "min_off")


@pytest.mark.parametrize("kw, match", [
    (dict(min_off=-1.0), "min_off"), (dict(c_max=1e-6), "c_max"), (dict(blend=-1.0), "blend"),
    (dict(horizon=math.nan), "horizon"), (dict(predict_every=0), "predict_every"),
    (dict(predict_every=1.5), "predict_every"), (dict(c_pred=0.01, horizon=0.0), "c_pred needs the predictive off"),
    (dict(c_pred=0.5, horizon=0.2), "c_pred must be <= c"), (dict(c_pred=-0.01, horizon=0.2), "c_pred"),
])
def test_bad_intermittent_options_are_refused(planar, kw, match):
    with pytest.raises(ConfigError, match=match):
        resolve_params(planar, d_bar=0.05, **kw)


def test_scene_filter_table_gives_the_defaults_and_arguments_override_them(planar):
    from isf_robot.arm import load_scene

    pole = load_scene("panda_pole")
    p = resolve_params(pole, d_bar=0.04)
    # models/panda_pole.toml names neither: designed from [gains] 1.5 / 10 and 0.25 + 5 x 0.002
    assert (p.blend, p.horizon, p.min_off) == (pytest.approx(0.15), pytest.approx(0.26), 0.0)
    q = resolve_params(pole, d_bar=0.04, blend=0.0, horizon=0.0)
    assert (q.blend, q.horizon) == (0.0, 0.0) and "horizon" not in q.as_dict()
    r = resolve_params(planar, d_bar=0.05, horizon=0.2)
    assert (r.blend, r.horizon, r.min_off) == (pytest.approx(0.2), 0.2, 0.0)  # planar: [gains] 2.0 / 10


def test_c_pred_reaches_the_filter_and_the_result_on_the_arm(planar_moving):
    p = resolve_params(planar_moving, d_bar=0.05, horizon=0.15, c_pred=0.01)
    sim = ArmSimulation(planar_moving, "isf", seed=3, params=p)
    assert sim.strategy.c_pred == 0.01 and sim.strategy.trigger.c == 0.01
    res = sim.run(2.0)
    assert res.collisions == 0 and res.min_barrier >= 0
    assert res.as_dict()["c_pred"] == 0.01
    assert not hasattr(ArmSimulation(planar_moving, "cbf", seed=3, params=p).strategy, "c_pred")
    assert "c_pred" not in resolve_params(planar_moving, d_bar=0.05).as_dict()
