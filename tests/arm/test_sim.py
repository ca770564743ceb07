"""The arm simulation loop: safety of the filters, QP counts, metrics, observers, bad input."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import mujoco
import numpy as np
import pytest

from isf_robot.arm import (
    ArmSimulation,
    ArmStepRecord,
    CollisionBarriers,
    episode_setup,
    load_scene,
    min_distance,
    run_episode,
)
from isf_robot.arm.episode import check_control_period
from isf_robot.arm.monitor import SafetyMonitor
from isf_robot.arm.sim import PHASES
from isf_robot.core import ConfigError, Observer, Power, SwitchEvent, UnknownNameError, compute_metrics

PANDA_SCENES = ("panda_pole", "panda_shelf", "panda_moving")
SAFE_TOL = 1e-3  # [m] allowed barrier violation on the true geometry


@pytest.fixture(scope="module")
def panda() -> dict[str, Any]:
    return {name: load_scene(name) for name in PANDA_SCENES}


# ----------------------------------------------------------------------------- safety


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_planar_filters_safe_nominal_collides(planar, seed: int) -> None:  # type: ignore[no-untyped-def]
    nominal = run_episode(planar, "nominal", 4.0, seed)
    assert nominal.collisions > 0 and nominal.min_barrier < 0.0
    for strategy in ("cbf", "isf"):
        r = run_episode(planar, strategy, 4.0, seed)
        assert r.min_barrier >= -SAFE_TOL, (strategy, r.min_barrier)
        assert r.collisions == 0
        assert r.fallbacks == 0


@pytest.mark.parametrize("name", PANDA_SCENES)
def test_panda_filters_safe_nominal_collides(panda, name: str) -> None:  # type: ignore[no-untyped-def]
    scene = panda[name]
    for seed in (0, 1):
        nominal = run_episode(scene, "nominal", 3.0, seed)
        assert nominal.collisions > 0, f"{name}: the nominal task must hit an obstacle"
        cbf = run_episode(scene, "cbf", 3.0, seed)
        isf = run_episode(scene, "isf", 3.0, seed)
        for r in (cbf, isf):
            assert r.min_barrier >= -SAFE_TOL, (name, r.filter, seed, r.min_barrier)
        assert isf.qp_solves < cbf.qp_solves
        assert cbf.qp_solves == cbf.control_steps  # the standard filter solves every step


def test_moving_obstacle_planar(planar_moving) -> None:  # type: ignore[no-untyped-def]
    nominal = run_episode(planar_moving, "nominal", 6.0, 0)
    assert nominal.min_barrier < 0.0
    for strategy in ("cbf", "isf"):
        r = run_episode(planar_moving, strategy, 6.0, 0)
        assert r.min_barrier >= -SAFE_TOL


def test_isf_solves_fewer_qps_than_cbf(planar) -> None:  # type: ignore[no-untyped-def]
    cbf = run_episode(planar, "cbf", 4.0, 3)
    isf = run_episode(planar, "isf", 4.0, 3)
    assert isf.qp_solves < cbf.qp_solves
    assert isf.on_switches >= 1
    assert isf.min_off_s is None or isf.min_off_s > 0.0


class _Steps(Observer):
    def __init__(self) -> None:
        self.steps: list[Any] = []

    def on_step(self, record: Any) -> None:
        self.steps.append(record)


def test_collisions_are_counted_at_every_physics_step(planar) -> None:  # type: ignore[no-untyped-def]
    # 5 physics steps per control tick: a contact lasting several ticks must be counted on the
    # physics steps between the ticks too, not only at the ticks the observer sees.
    obs = _Steps()
    r = run_episode(planar, "nominal", 4.0, 0, control_period=0.005, observers=[obs])
    assert r.physics_steps == 5 * r.control_steps + 1
    pair = np.array(["|" in n for n in obs.steps[0].names])
    colliding_ticks = sum(int(np.min(s.h[pair]) < 0.0) for s in obs.steps)
    assert colliding_ticks >= 5, "the nominal run must collide for this test to mean anything"
    assert r.collisions <= r.physics_steps
    assert r.collisions >= 3 * colliding_ticks, (r.collisions, colliding_ticks)


# ----------------------------------------------------------------------------- metrics


def test_metrics_fields_match_compute_metrics(planar) -> None:  # type: ignore[no-untyped-def]
    obs = _Collect()
    r = run_episode(planar, "isf", 3.0, 4, observers=[obs])
    steps = obs.steps
    d = np.array([s.u - s.u_nom for s in steps])
    m = compute_metrics(np.array([s.t for s in steps]), np.array([s.dt for s in steps]),
                        np.array([s.on for s in steps]), np.einsum("ij,ij->i", d, d),
                        np.array([s.qp_solved for s in steps]))
    for key in ("duration_s", "control_steps", "duty_cycle", "on_switches", "mean_off_s",
                "min_off_s", "intervention", "qp_solves"):
        mine, ref = getattr(r, key), getattr(m, key)
        assert getattr(r.metrics, key) == mine
        if ref is None:
            assert mine is None
        else:
            assert mine == pytest.approx(ref, abs=1e-9)
    assert r.control_steps == 1500 and r.physics_steps == 3001
    flat = r.as_dict()
    assert flat["duty_cycle"] == r.metrics.duty_cycle and flat["resolves"] == r.stats.resolves
    assert flat["alpha"] == r.params.alpha and "metrics" not in flat


def test_same_seed_same_episode(planar) -> None:  # type: ignore[no-untyped-def]
    a = run_episode(planar, "isf", 2.0, 7).as_dict()
    b = run_episode(planar, "isf", 2.0, 7).as_dict()
    for d in (a, b):
        d.pop("wall_s")
        d.pop("qp_time_median_us")
        d.pop("solver_time_median_us")
    assert a == b
    c = run_episode(planar, "isf", 2.0, 8).as_dict()
    assert c["intervention"] != a["intervention"]


def test_episode_setup_is_safe_and_seeded(planar_moving) -> None:  # type: ignore[no-untyped-def]
    s1, s2 = episode_setup(planar_moving, 5), episode_setup(planar_moving, 5)
    np.testing.assert_array_equal(s1.q0, s2.q0)
    assert s1.time_offset == s2.time_offset
    data = mujoco.MjData(planar_moving.model)
    data.qpos[planar_moving.qpos_adr] = s1.q0
    planar_moving.set_moving_obstacles(data, s1.time_offset)
    mujoco.mj_forward(planar_moving.model, data)
    assert np.min(CollisionBarriers.from_scene(planar_moving).evaluate(data).h) > 0.0


def test_safety_monitor_matches_min_distance_helper(planar, rng) -> None:  # type: ignore[no-untyped-def]
    coll = CollisionBarriers.from_scene(planar)
    data = mujoco.MjData(planar.model)
    margin = coll.pairs.margin
    for _ in range(30):
        data.qpos[planar.qpos_adr] = planar.home + rng.normal(0.0, 0.4, 3)
        mujoco.mj_forward(planar.model, data)
        true = min_distance(planar.model, data, coll.pairs).distance
        mon = SafetyMonitor(coll)
        b = coll.evaluate(data)
        h_tick = mon.tick(b.h, b.active.nonzero()[0])
        h_sub = mon.substep(data, bound=1e6)  # every barrier value exact
        h_run = mon.substep(data, bound=h_tick)  # exact below the running minimum (as in runs)
        if true < coll.cutoff:
            assert h_tick == pytest.approx(true - margin[0], abs=1e-9)
            assert h_sub == pytest.approx(true - margin[0], abs=1e-9)
            assert h_run == pytest.approx(true - margin[0], abs=1e-9)
            assert mon.min_h == pytest.approx(true - margin[0], abs=1e-9)
            assert mon.collisions == (3 if true - margin[0] < 0 else 0)


@pytest.mark.parametrize("strategy", ["cbf", "isf"])
def test_row_pruning_does_not_change_the_run(planar, strategy: str) -> None:  # type: ignore[no-untyped-def]
    # a tight slack threshold prunes rows that the filter then needs: the re-solve fixes it
    full = run_episode(planar, strategy, 2.0, 1, joint_row_slack=math.inf,
                       collision_row_slack=math.inf)
    for slack in (0.0, 0.05):  # 0: only rows with slack below c stay in the QP
        pruned = run_episode(planar, strategy, 2.0, 1, joint_row_slack=max(slack, 1e-9),
                             collision_row_slack=slack)
        for key in ("duty_cycle", "on_switches", "qp_solves", "min_barrier", "intervention"):
            assert getattr(pruned, key) == pytest.approx(getattr(full, key), rel=1e-6,
                                                         abs=1e-9), key


# ----------------------------------------------------------------------------- observers


class _Collect(Observer):
    def __init__(self) -> None:
        self.info: dict[str, Any] | None = None
        self.steps: list[ArmStepRecord] = []
        self.events: list[SwitchEvent] = []
        self.summary: dict[str, Any] | None = None

    def on_start(self, info: Any) -> None:
        self.info = dict(info)

    def on_step(self, record: Any) -> None:
        self.steps.append(record)

    def on_event(self, event: Any) -> None:
        self.events.append(event)

    def on_finish(self, summary: Any) -> None:
        self.summary = dict(summary)


@pytest.mark.parametrize("strategy", ["isf", "cbf", "nominal"])
def test_observer_sees_every_step_and_event(planar, strategy: str) -> None:  # type: ignore[no-untyped-def]
    obs = _Collect()
    plain = run_episode(planar, strategy, 2.0, 2)
    r = run_episode(planar, strategy, 2.0, 2, observers=[obs])
    assert obs.info is not None and obs.info["strategy"] == strategy
    assert obs.info["control_period"] == pytest.approx(0.002) and obs.info["dt"] == 0.001
    assert len(obs.steps) == r.control_steps
    assert obs.summary is not None and obs.summary["qp_solves"] == r.qp_solves
    # watching changes nothing
    assert r.min_barrier == pytest.approx(plain.min_barrier, abs=1e-12)
    assert r.intervention == pytest.approx(plain.intervention, abs=1e-12)
    ons = [e for e in obs.events if e.kind == "on"]
    assert len(ons) == r.on_switches
    rec = obs.steps[100]
    n, k = planar.n_joints, len(rec.names)
    assert rec.q.shape == (n,) and rec.u.shape == (n,) and rec.h.shape == (k,)
    assert rec.ee_pos.shape == (3,) and rec.goal_pos.shape == (3,)
    assert rec.witness.shape[1:] == (2, 3) and len(rec.witness_names) == rec.witness.shape[0]
    assert rec.h_min == pytest.approx(float(rec.h.min()))
    # the run's minimum also covers the state after the last step (no record for it)
    nc = obs.info["n_collision"]  # (each step's true-geometry minimum: the tick's pairs, then the other physics steps)
    rec_min = min(min(s.true_min, float(s.h[:nc].min())) for s in obs.steps)
    assert rec_min >= r.min_barrier - 1e-12
    assert rec_min == pytest.approx(r.min_barrier, rel=1e-12) or r.min_barrier < rec_min  # (or the final state)
    with pytest.raises(AttributeError, match="true_min"):
        rec.dist_min  # noqa: B018 (the old name says where the value went)
    with pytest.raises(dataclasses.FrozenInstanceError):
        rec.t = 1.0  # type: ignore[misc]
    # record metrics recompute the JSON metrics
    t = np.array([s.t for s in obs.steps])
    on = np.array([s.on for s in obs.steps])
    rate = np.array([float((s.u - s.u_nom) @ (s.u - s.u_nom)) for s in obs.steps])
    solved = np.array([s.qp_solved for s in obs.steps])
    m = compute_metrics(t, np.array([s.dt for s in obs.steps]), on, rate, solved)
    assert m.duty_cycle == pytest.approx(r.duty_cycle, abs=1e-9)
    assert m.intervention == pytest.approx(r.intervention, abs=1e-9)
    assert m.on_switches == r.on_switches


# ----------------------------------------------------------------------------- bad input


def test_control_period_must_be_whole_multiple(planar) -> None:  # type: ignore[no-untyped-def]
    assert check_control_period(0.003, 0.001) == 3
    for bad in (0.0015, 0.0005, -0.002, 0.0, float("nan")):
        with pytest.raises(ConfigError):
            ArmSimulation(planar, "isf", control_period=bad, d_bar=0.1)


def test_negative_or_zero_duration_rejected(planar) -> None:  # type: ignore[no-untyped-def]
    sim = ArmSimulation(planar, "isf", d_bar=0.1)
    for bad in (-1.0, 0.0, float("inf")):
        with pytest.raises(ConfigError, match="duration"):
            sim.run(bad)


def test_unknown_strategy_lists_valid(planar) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(UnknownNameError, match="cbf, isf, nominal"):
        ArmSimulation(planar, "mpc")


@pytest.mark.parametrize("kw", [dict(alpha=-1.0), dict(c=0.0), dict(b=-0.1), dict(d_bar=-0.1)])
def test_bad_filter_parameters_rejected(planar, kw: dict) -> None:  # type: ignore[no-untyped-def]
    name = next(iter(kw))
    with pytest.raises(ConfigError, match=name):
        ArmSimulation(planar, "isf", **{"d_bar": 0.1, **kw})


def test_simulation_never_calibrates_behind_the_callers_back(planar) -> None:  # type: ignore[no-untyped-def]
    # the shipped scenes have no d_bar in their config: the caller must resolve it
    with pytest.raises(ConfigError, match="resolve_params"):
        ArmSimulation(planar, "isf")
    from isf_robot.arm.params import resolve_params

    p = resolve_params(planar, d_bar=None)
    assert p.d_bar_source == "calibration" and p.d_bar > 0
    assert ArmSimulation(planar, "isf", params=p).params is p


def test_start_info_tells_observers_what_they_draw(planar) -> None:  # type: ignore[no-untyped-def]
    obs = _Collect()
    ArmSimulation(planar, "cbf", seed=0, d_bar=0.1, observers=[obs]).run(0.01)
    info = obs.info
    assert info is not None and info["model"] is planar.model and info["strategy"] == "cbf"
    assert len(info["pair_margins"]) == info["n_collision"] == len(info["names"]) - 2 * planar.n_joints
    np.testing.assert_array_equal(info["qpos_adr"], planar.qpos_adr)
    assert info["ee_site_id"] == planar.ee_site_id and info["d_bar"] == 0.1


def test_phase_timers_cover_the_loop(planar) -> None:  # type: ignore[no-untyped-def]
    r = run_episode(planar, "isf", 1.0, 0, d_bar=0.1, timing=True)
    assert set(r.timings) == set(PHASES) and all(v > 0 for v in r.timings.values())
    assert sum(r.timings.values()) <= r.wall_s
    assert run_episode(planar, "isf", 1.0, 0, d_bar=0.1).timings == {}


def test_any_class_k_function_on_the_arm(planar) -> None:  # type: ignore[no-untyped-def]
    # the loop has no copy of Xi_on: a non-linear alpha goes through the core unchanged
    nominal = run_episode(planar, "nominal", 3.0, 0, d_bar=0.1)
    assert nominal.collisions > 0
    for strategy in ("cbf", "isf"):
        r = run_episode(planar, strategy, 3.0, 0, alpha=Power(5.0, 0.5), d_bar=0.1)
        assert r.collisions == 0 and r.min_barrier > -SAFE_TOL
        assert r.as_dict()["alpha"].startswith("Power")


def test_one_khz_control_on_panda(panda) -> None:  # type: ignore[no-untyped-def]
    r = run_episode(panda["panda_pole"], "isf", 1.0, 0, control_period=0.001)
    assert r.control_steps == 1000 and r.physics_steps == 1001
    assert math.isfinite(r.min_barrier)


def test_pruned_rows_violated_at_the_solution_are_solved_again(panda) -> None:  # type: ignore[no-untyped-def]
    # a tiny keep threshold leaves out rows that the solution then violates: the re-solve
    # with every row must give the same run as keeping every row from the start
    scene = panda["panda_pole"]
    kw = dict(c=1e-4, d_bar=0.04)
    pruned = run_episode(scene, "cbf", 4.0, 1, joint_row_slack=1e-4, collision_row_slack=1e-4,
                         **kw)
    full = run_episode(scene, "cbf", 4.0, 1, joint_row_slack=math.inf,
                       collision_row_slack=math.inf, **kw)
    assert pruned.resolves > 0 and full.resolves == 0
    for key in ("duty_cycle", "on_switches", "qp_solves", "min_barrier", "intervention"):
        assert getattr(pruned, key) == pytest.approx(getattr(full, key), rel=1e-6, abs=1e-9), key


def test_path_track_matches_scalar_path_methods(rng) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.arm import CirclePath, LinearBouncePath
    from isf_robot.arm.paths import path_track

    t = np.sort(rng.uniform(-3.0, 20.0, 200))
    paths = [CirclePath(center=(0.6, 0.0, 0.2), radius=0.25, period=6.0, phase=0.3),
             CirclePath(center=(0.1, 0.2, 0.3), radius=0.1, period=-2.0, normal=(1.0, 0.0, 0.0)),
             LinearBouncePath(start=(0.4, -0.2, 0.3), end=(0.4, -0.2, 0.8), speed=0.3,
                              phase=0.2)]
    for path in paths:
        pos, vel = path_track(path, t)
        np.testing.assert_allclose(pos, [path.position(x) for x in t], atol=1e-12)
        # the bounce path's velocity jumps at the turning points: compare away from them
        np.testing.assert_allclose(vel, [path.velocity(x) for x in t], atol=1e-12)


def test_non_finite_nominal_command_is_an_error(planar) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.arm import NominalController
    from isf_robot.arm.nominal import GoalSequence
    from isf_robot.core import NonFiniteError

    class Broken(NominalController):
        n = 3
        goals = GoalSequence(1, [0.0], 0.01)

        def reset(self) -> None:
            self.goals.reset()

        def __call__(self, t, data):  # type: ignore[no-untyped-def]
            return np.full(3, np.nan) if t > 0.1 else np.zeros(3)

    for strategy in ("cbf", "isf"):
        with pytest.raises(NonFiniteError, match="not finite"):
            run_episode(planar, strategy, 0.5, 0, nominal=Broken(), d_bar=0.1)
