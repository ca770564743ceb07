"""The torque level's simulation: safety on the true geometry, torque limits, the trigger, the nominal, input errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from isf_robot.arm import load_scene
from isf_robot.arm.compare import EpisodeTask, SceneSpec, run_task, simulation_type
from isf_robot.arm.config_toml import parse_config
from isf_robot.arm.torque_sim import TorqueSimulation, resolve_torque_params
from isf_robot.core import ConfigError

D_BAR = 0.6  # [rad/s^2]: about the calibrated figure of panda_pole (0.53); passed so that no test calibrates


@pytest.fixture(scope="module")
def pole():  # type: ignore[no-untyped-def]
    return load_scene("panda_pole")


def _run(scene, strategy, seed=0, duration=2.5, **options):  # type: ignore[no-untyped-def]
    params = resolve_torque_params(scene, d_bar=options.pop("d_bar", D_BAR), **options)
    sim = TorqueSimulation(scene, strategy, seed=seed, params=params)
    return sim, sim.run(duration)


def test_nominal_collides_and_the_filters_keep_the_true_geometry_safe(pole) -> None:  # type: ignore[no-untyped-def]
    _, nom = _run(pole, "nominal")
    assert nom.collisions > 0  # the task is dangerous at the torque level too
    for strategy in ("cbf", "isf"):
        _, r = _run(pole, strategy)
        assert r.collisions == 0 and r.min_barrier > 0, strategy
        assert r.tau_peak_ratio <= 1.0 + 1e-9, strategy
        assert r.fallbacks == 0, strategy
        assert r.as_dict()["level"] == "torque" and r.d_bar == D_BAR


def test_isf_trigger_on_the_psi_rows(pole) -> None:  # type: ignore[no-untyped-def]
    """On only at some Xi_on <= 0, off only once every Xi_on >= c, and the nominal torque untouched while off."""
    sim = TorqueSimulation(pole, "isf", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR, blend=0.0))
    seen = []
    inner = sim.strategy.step_lie

    def spy(t, lie, u_nom, *args, **kw):  # type: ignore[no-untyped-def]
        step = inner(t, lie, u_nom, *args, **kw)
        xi = lie.lf + lie.lg @ u_nom - lie.grad_norm * D_BAR + sim.params.class_k(lie.h)
        seen.append((xi.min(), step.on, step.u.copy(), u_nom.copy(), step.event))
        return step

    sim.strategy.step_lie = spy  # type: ignore[method-assign]
    res = sim.run(2.5)
    assert res.on_switches >= 1 and res.collisions == 0
    was_on = False
    for xi_min, on, u, u_nom, event in seen:
        if on and not was_on:
            assert xi_min <= 0.0 and event is not None
        if was_on and not on:
            assert xi_min >= sim.params.c and event is not None
        if not on:
            np.testing.assert_array_equal(u, u_nom)
        was_on = on


def test_payload_needs_the_robust_term_and_the_calibration_covers_it(pole) -> None:  # type: ignore[no-untyped-def]
    """A payload the filter's model does not know: its model error exceeds the unloaded d_bar; calibrated on the
    loaded arm, d_bar covers it and the filter keeps the arm clear."""
    import copy

    from isf_robot.arm.torque_calibration import calibrate_torque_d_bar

    plant = copy.deepcopy(pole.model)
    plant.body_mass[pole.model.site_bodyid[pole.ee_site_id]] += PAYLOAD_KG
    bare = calibrate_torque_d_bar(pole, duration=1.0)
    loaded = calibrate_torque_d_bar(pole, plant, duration=1.0)
    assert loaded.d_bar > 5 * bare.d_bar
    runs = {}
    for label, d_bar in (("bare", bare.d_bar), ("loaded", loaded.d_bar)):
        sim = TorqueSimulation(pole, "cbf", seed=0, plant=plant, params=resolve_torque_params(pole, d_bar=d_bar))
        runs[label] = sim.run(PAYLOAD_S)
    assert runs["bare"].tracking_error_q99 > bare.d_bar  # the model error the unloaded d_bar does not cover
    assert runs["loaded"].tracking_error_q99 <= loaded.d_bar
    assert runs["loaded"].collisions == 0 and runs["loaded"].min_barrier > 0
    # (both runs' closest approach is the same state: 3.7360255464967e-2 m in each, 3e-17 apart; the strict ">" held
    # by rounding until the torque QPs' few-row closed form changed the last bits, so: no closer than the bare run)
    assert runs["loaded"].min_barrier >= runs["bare"].min_barrier - 1e-12


PAYLOAD_KG, PAYLOAD_S = 0.3, 3.0


def test_compare_task_runs_the_torque_level(pole) -> None:  # type: ignore[no-untyped-def]
    params = {"params": resolve_torque_params(pole, d_bar=D_BAR)}
    r = run_task(EpisodeTask(SceneSpec(name="panda_pole"), "isf", 0, 0.2, params, "torque"))
    assert r["level"] == "torque" and r["control_steps"] == 100
    assert simulation_type("torque") is TorqueSimulation
    with pytest.raises(ConfigError, match="valid: velocity, torque"):
        simulation_type("tork")


def test_bad_input(pole) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError, match="shooting"):
        resolve_torque_params(pole, d_bar=1.0, shoot=0.5)
    with pytest.raises(ConfigError, match="d_bar"):
        resolve_torque_params(pole, calibrate=False)
    with pytest.raises(ConfigError, match="shooting"):
        TorqueSimulation(pole, "isf", params=dataclasses.replace(resolve_torque_params(pole, d_bar=1.0), shoot=0.5))


def test_scene_level_is_validated(pole) -> None:  # type: ignore[no-untyped-def]
    from pathlib import Path

    import tomllib

    raw = tomllib.loads(Path(pole.config.source).read_text())
    raw["filter"]["level"] = "torque"
    assert parse_config(raw).level == "torque"
    raw["filter"]["level"] = "joint"
    with pytest.raises(ConfigError, match=r"\[filter\] level: unknown 'joint'; valid: velocity, torque"):
        parse_config(raw)
    assert pole.config.level == "velocity"


def test_cli_runs_the_torque_level(capsys) -> None:  # type: ignore[no-untyped-def]
    import json

    from isf_robot.cli import main

    assert main(["run", "--scene", "panda_pole", "--level", "torque", "--filter", "cbf", "--duration", "0.1",
                 "--d-bar", "0.6", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["level"] == "torque" and d["d_bar"] == 0.6 and d["d_bar_source"] == "argument"
    assert main(["run", "--scene", "panda_pole", "--level", "torque", "--shoot", "0.5", "--d-bar", "0.6"]) == 2
    assert "not available at the torque level" in capsys.readouterr().err


def test_fallback_damps_toward_rest_with_gravity_compensation(pole) -> None:  # type: ignore[no-untyped-def]
    """The infeasibility fallback: within the limits, finite, and its torque beyond gravity opposes the motion."""
    sim = TorqueSimulation(pole, "cbf", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR))
    ep = sim.episode(sim, 10)
    rng = np.random.default_rng(5)
    for _ in range(5):
        ep.data.qvel[pole.dof_adr] = rng.uniform(-1.0, 1.0, pole.n_joints)
        ep.sense(0)
        tau = sim._fallback(0.0, ep.data, None, None)  # type: ignore[arg-type]
        assert np.all(np.isfinite(tau)) and np.all(np.abs(tau) <= sim.tau_max)
        v = ep.data.qvel[pole.dof_adr]
        assert float(v @ (tau - sim.terms.hold)) < 0.0  # type: ignore[union-attr]


def test_torque_nominal_is_computed_torque_on_the_model(pole) -> None:  # type: ignore[no-untyped-def]
    """Unclipped, the nominal torque gives the model's q_ddot = kd (v_ref - q_dot) + a_ref exactly."""
    sim = TorqueSimulation(pole, "nominal", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR))
    ep = sim.episode(sim, 10)
    nom, T = sim.torque_nominal, sim.control_period
    prev = None
    for k in range(5):
        ep.sense(k)
        tau = nom(k * T, ep.data, sim.terms)
        assert np.all(np.abs(tau) < sim.tau_max)
        a_ref = np.zeros(pole.n_joints) if prev is None else (nom.v_ref - prev) / T
        want = nom.kd * (nom.v_ref - ep.data.qvel[pole.dof_adr]) + a_ref
        np.testing.assert_allclose(sim.terms.acceleration(tau), want, atol=1e-9)  # type: ignore[union-attr]
        prev = nom.v_ref.copy()
        ep.act(k, tau)


def _figures(results):  # type: ignore[no-untyped-def]
    """A comparison's per-episode figures without the wall-clock ones."""
    drop = {"wall_s", "timings", "qp_time_median_us", "solver_time_median_us"}
    return {s: [{k: v for k, v in e.items() if k not in drop} for e in r["episodes"]] for s, r in results.items()}


def test_compare_puts_the_two_levels_side_by_side(capsys) -> None:  # type: ignore[no-untyped-def]
    """`compare --level velocity torque`: each level's figures as its own compare gives them, in one table."""
    import json

    from isf_robot.cli import main

    base = ["compare", "--scene", "panda_pole", "--episodes", "1", "--duration", "0.3", "--filters", "cbf", "isf",
            "--quiet"]
    assert main([*base, "--level", "velocity", "torque", "--json"]) == 0
    both = json.loads(capsys.readouterr().out)
    assert both["schema"].startswith("isf-robot-compare-levels/") and list(both["levels"]) == ["velocity", "torque"]
    for level in ("velocity", "torque"):
        assert main([*base, "--level", level, "--json"]) == 0
        one = json.loads(capsys.readouterr().out)
        assert _figures(both["levels"][level]["results"]) == _figures(one["results"]), level
    assert both["levels"]["torque"]["level"] == "torque" and "level" not in both["levels"]["velocity"]

    assert main([*base, "--level", "velocity", "torque"]) == 0
    table = capsys.readouterr().out.splitlines()
    rows = [line.split()[:2] for line in table if line.split()[:1] in (["velocity"], ["torque"])]
    assert rows == [["velocity", "cbf"], ["velocity", "isf"], ["torque", "cbf"], ["torque", "isf"]]
    assert any("N^2 m^2 s at the torque level" in line for line in table)


@pytest.mark.parametrize("extra, what", [
    (["--d-bar", "0.1"], "--d-bar with two levels"),
    (["--rrd", "out"], "recording compares one level at a time"),
])
def test_compare_two_levels_refuses_what_has_a_level_of_its_own(capsys, extra, what) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    assert main(["compare", "--scene", "panda_pole", "--level", "velocity", "torque", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and what in err[0]


def test_the_torque_levels_trigger_with_a_fake_clock(pole) -> None:  # type: ignore[no-untyped-def]
    """The torque level's own filter (its wiring, torque limits and options), driven by hand at irregular times.

    One ``psi`` row whose ``Xi_on`` under the nominal torque is set by its drift term: on at the first tick
    with ``Xi_on <= 0``, off at the first tick with ``Xi_on >= c``, the nominal torque untouched while off,
    every switch stamped with the fake clock and the periods' lengths taken from it, the robust condition
    met while on.
    """
    from isf_robot.core import LieData

    # (no predictive off trigger: its rollout needs the episode's state; the trigger alone is tested here)
    sim = TorqueSimulation(pole, "isf", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR, horizon=0.0))
    f, p = sim.strategy, sim.params
    f.reset(0.0)
    n = pole.n_joints
    lg = np.zeros((1, n))
    lg[0, 0] = 1.0 / 40.0  # (the row's Lg psi: a joint's inverse inertia, [m/s^2 per N m])
    u_nom = np.full(n, 2.0)
    psi = 0.05
    base = float((lg @ u_nom)[0]) - D_BAR * 1.0 + float(p.class_k(np.array([psi]))[0])  # Xi_on with lf = 0
    times = np.cumsum(np.r_[0.0, np.random.default_rng(3).uniform(0.002, 0.012, 74)])  # irregular ticks [s]
    wanted = np.r_[np.full(10, 0.3), np.full(15, -0.2), np.full(10, 0.5 * p.c), np.full(10, 2.0 * p.c),
                   np.full(30, 0.4)]  # Xi_on at each tick: safe, needs the filter, between 0 and c, above c
    events, was_on, last_off = [], False, -np.inf
    for t, xi in zip(times, wanted):
        lie = LieData(h=np.array([psi]), lf=np.array([xi - base]), lg=lg, grad_norm=np.array([1.0]))
        step = f.step_lie(float(t), lie, u_nom)
        if step.event is not None:
            events.append(step.event)
            last_off = t if step.event.kind == "off" else last_off
        if not step.on and t - last_off >= p.blend:  # (after the hand-over back to the nominal)
            np.testing.assert_array_equal(step.u, u_nom)
        else:  # the robust condition at the command applied
            assert float(lie.lf[0] + lie.lg[0] @ step.u - D_BAR + p.class_k(lie.h)[0]) >= -1e-9
            assert np.all(np.abs(step.u) <= sim.tau_max + 1e-9)
        assert step.on == (xi <= 0.0 if not was_on else xi < p.c), (t, xi, was_on)
        was_on = step.on
    t_on, t_off = float(times[10]), float(times[35])
    assert [(e.kind, e.t) for e in events] == [("on", t_on), ("off", t_off)]
    assert times[-1] - t_off > p.blend  # (the last ticks checked the nominal torque exactly)
    assert events[1].duration_s == pytest.approx(t_off - t_on, abs=1e-12)


def test_torque_nominal_owns_its_reference(pole) -> None:  # type: ignore[no-untyped-def]
    """A velocity nominal may hand back the same buffer at every call (NominalController's contract): ``a_ref`` is
    still the change of the reference between ticks, and ``v_ref`` is not changed by later calls (a rollout's)."""
    from isf_robot.arm.dynamics import ArmDynamics
    from isf_robot.arm.torque_nominal import TorqueNominal, computed_torque

    class Reusing:
        def __init__(self, values):  # type: ignore[no-untyped-def]
            self.values, self.buf, self.k = values, np.zeros(pole.n_joints), 0

        def __call__(self, t, data):  # type: ignore[no-untyped-def]
            self.buf[:] = self.values[min(self.k, len(self.values) - 1)]
            self.k += 1
            return self.buf

        def reset(self) -> None:
            self.k = 0

    v1, v2, T, kd = np.full(pole.n_joints, 0.1), np.linspace(-0.3, 0.3, pole.n_joints), 0.002, 10.0
    ref = Reusing([v1, v2, np.full(pole.n_joints, 9.0)])
    tau_max = np.full(pole.n_joints, 1e6)
    nom = TorqueNominal(ref, pole.dof_adr, tau_max, T, kd)  # type: ignore[arg-type]
    data = pole.make_data()
    terms = ArmDynamics(pole.model, pole.dof_adr).terms(data)
    q_dot = data.qvel[pole.dof_adr]
    np.testing.assert_array_equal(nom(0.0, data, terms), computed_torque(terms, v1, 0 * v1, q_dot, kd, tau_max))
    np.testing.assert_allclose(nom(T, data, terms), computed_torque(terms, v2, (v2 - v1) / T, q_dot, kd, tau_max),
                               rtol=1e-12)
    ref(2 * T, data)  # (the reference called again, as a rollout does, between two ticks)
    np.testing.assert_array_equal(nom.v_ref, v2)
    nom.reset()
    np.testing.assert_array_equal(nom(0.0, data, terms), computed_torque(terms, v1, 0 * v1, q_dot, kd, tau_max))


def test_start_check_uses_the_rows_far_value(pole) -> None:  # type: ignore[no-untyped-def]
    """The intermittent filter's start check reads ``alpha`` of the torque rows' far value ``alpha_1 (cutoff -
    margin)``, not of ``h``'s: a ``c`` between the two raises at the level whose far value is the smaller only."""
    from isf_robot.arm import ArmSimulation

    base = resolve_torque_params(pole, d_bar=D_BAR)
    unit = TorqueSimulation(pole, "isf", seed=0, params=base, alpha_1=1.0)
    h_far = float(np.min(unit.coll.cutoff - unit.coll.pairs.margin))
    assert unit.far_value() == pytest.approx(h_far) and h_far > 0
    alpha = base.class_k
    assert alpha(h_far) > base.c  # (the shipped settings pass at either level)
    # alpha_1 = 0.2: the psi rows' far value is a fifth of h's; a c between them is too large for the torque rows
    c = 0.5 * (alpha(0.2 * h_far) + alpha(h_far))
    params = dataclasses.replace(base, c=c, c_max=max(base.c_max, c))
    ArmSimulation(pole, "isf", seed=0, params=params)  # (the velocity level's rows reach c)
    with pytest.raises(ConfigError, match=r"alpha\(alpha_1 \(cutoff - margin\)\) = .* < c = ") as err:
        TorqueSimulation(pole, "isf", seed=0, params=params, alpha_1=0.2)
    assert "\n" not in str(err.value)
    TorqueSimulation(pole, "cbf", seed=0, params=params, alpha_1=0.2)  # (not intermittent: no check)
    # alpha_1 = 10: the psi rows reach a c that h's far value does not
    c = 0.5 * (alpha(h_far) + alpha(10.0 * h_far))
    params = dataclasses.replace(base, c=c, c_max=max(base.c_max, c))
    with pytest.raises(ConfigError, match=r"alpha\(cutoff - margin\) = .* < c = "):
        ArmSimulation(pole, "isf", seed=0, params=params)
    assert TorqueSimulation(pole, "isf", seed=0, params=params, alpha_1=10.0).far_value() == pytest.approx(10 * h_far)


def test_the_torque_level_builds_only_its_own_strategy(pole, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """No velocity-level strategy, rollout or tracker is built on the way (and a tracker is refused)."""
    import isf_robot.arm.params as params_mod
    import isf_robot.arm.sim as sim_mod
    import isf_robot.arm.torque_sim as torque_mod
    from isf_robot.arm.torque_rollout import TorqueRollout

    made = []

    def count(make):  # type: ignore[no-untyped-def]
        def wrapped(*args, **kwargs):  # type: ignore[no-untyped-def]
            made.append(kwargs.get("fallback"))
            return make(*args, **kwargs)
        return wrapped

    def refuse(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise AssertionError("a velocity-level part was built")

    monkeypatch.setattr(sim_mod, "make_strategy", count(sim_mod.make_strategy))
    monkeypatch.setattr(torque_mod, "make_strategy", count(torque_mod.make_strategy))
    monkeypatch.setattr(sim_mod, "make_actuation", refuse)
    monkeypatch.setattr(params_mod, "NominalRollout", refuse)
    sim = TorqueSimulation(pole, "isf", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR))
    assert len(made) == 1 and made[0] == sim._fallback
    assert isinstance(sim.strategy.predictor.rollout, TorqueRollout) and sim.tracker is None
    assert sim.run(0.05).collisions == 0  # (an episode runs without a tracker)
    with pytest.raises(ConfigError, match="takes no tracker"):
        TorqueSimulation(pole, "isf", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR), tracker=object())


def test_compiled_torque_nominal_agrees_with_the_plain_function(pole) -> None:  # type: ignore[no-untyped-def]
    """The compiled tick of the torque nominal (``nominal_torque`` by numba) equals the plain function on numpy.

    On the ticks of a nominal episode (``a_ref`` from the last reference), and on the same ticks with a twentieth of
    the torque limits (the clip active): the same operations (the product ``M x`` by BLAS on both); tolerance 1e-12
    relative, with a floor of 1e-12 times the torque limits.
    """
    from isf_robot.arm import kernels
    from isf_robot.arm.torque_nominal import nominal_torque

    if not kernels.available():
        pytest.skip("compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")
    sim = TorqueSimulation(pole, "nominal", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR))
    ep = sim.episode(sim, 200)
    nom, T = sim.torque_nominal, sim.control_period
    assert nom._step is not nominal_torque  # (the compiled one)
    clipped, low = 0, nom.tau_max / 20
    for k in range(200):
        ep.sense(k)
        prev, first = nom.v_ref.copy(), nom._first
        tau = nom(k * T, ep.data, sim.terms)
        v, terms, atol = nom.v_ref.copy(), sim.terms, 1e-12 * float(nom.tau_max.max())
        assert terms is not None and tau.dtype is np.dtype(np.float64)  # (numpy's own: the core tests the dtype so)
        want, tight = np.empty_like(tau), np.empty_like(tau)
        nominal_torque(terms.mass, terms.hold, v, prev.copy(), first, T, ep.data.qvel, nom.dof, nom.kd, nom.tau_max,
                       want)
        np.testing.assert_allclose(tau, want, rtol=1e-12, atol=atol)
        nom._step(terms.mass, terms.hold, v, prev.copy(), first, T, ep.data.qvel, nom.dof, nom.kd, low, tight)
        nominal_torque(terms.mass, terms.hold, v, prev.copy(), first, T, ep.data.qvel, nom.dof, nom.kd, low, want)
        np.testing.assert_allclose(tight, want, rtol=1e-12, atol=atol)
        clipped += int(np.any(np.abs(tight) >= low))
        ep.act(k, tau)
    assert clipped > 0  # (the clip was exercised)


def test_compiled_act_arithmetic_agrees_with_the_plain_function(pole) -> None:  # type: ignore[no-untyped-def]
    """``held_torque`` compiled (the act phase's) and as written, on the ticks of a cbf episode and on commands beyond
    the limits: the clipped torque and the velocities equal, the peak, the reference error and the model's
    acceleration to 1e-12 relative (the product ``Minv tau`` by BLAS on both); a non-finite command gives a non-finite
    peak on both."""
    from isf_robot.arm import kernels
    from isf_robot.arm.torque_sim import held_torque
    from isf_robot.core.jit import compiled

    fast = compiled(held_torque)
    if not kernels.available() or fast is held_torque:
        pytest.skip("compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")
    sim = TorqueSimulation(pole, "cbf", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR))
    ep = sim.episode(sim, 100)
    T, n, dof = sim.control_period, pole.n_joints, np.asarray(pole.dof_adr, dtype=np.int64)
    rng = np.random.default_rng(3)
    for k in range(100):
        t = k * T
        ep.sense(k)
        _, lie = ep.barriers()
        u = ep.strategy(t, lie, ep.nominal(t)).u
        terms = sim.terms
        assert terms is not None
        for cmd in (u, u * rng.uniform(0.0, 3.0, n)):  # (the second beyond the limits at some joints)
            got = [np.empty(n) for _ in range(3)]
            want = [np.empty(n) for _ in range(3)]
            a = fast(cmd, sim.tau_max, got[0], ep.data.qvel, dof, sim.torque_nominal.v_ref, terms.a0, terms.minv,
                     got[1], got[2])
            b = held_torque(cmd, sim.tau_max, want[0], ep.data.qvel, dof, sim.torque_nominal.v_ref, terms.a0,
                            terms.minv, want[1], want[2])
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])
            np.testing.assert_allclose(got[2], want[2], rtol=1e-12, atol=1e-12 * float(np.abs(want[2]).max()))
            np.testing.assert_allclose(a, b, rtol=1e-12)
        ep.act(k, u)
    bad = np.full(n, 0.5)
    bad[2] = np.nan
    out = [np.empty(n) for _ in range(3)]
    for f in (fast, held_torque):
        peak, _ = f(bad, sim.tau_max, out[0], ep.data.qvel, dof, sim.torque_nominal.v_ref, sim.terms.a0,  # type: ignore[union-attr]
                    sim.terms.minv, out[1], out[2])  # type: ignore[union-attr]
        assert not np.isfinite(peak)


def test_a_non_finite_torque_command_is_refused(pole) -> None:  # type: ignore[no-untyped-def]
    """act raises NonFiniteError on a command with a NaN or an infinity (the peak ratio is not finite)."""
    from isf_robot.core import NonFiniteError

    sim = TorqueSimulation(pole, "nominal", seed=0, params=resolve_torque_params(pole, d_bar=D_BAR))
    ep = sim.episode(sim, 10)
    ep.sense(0)
    for bad in (np.nan, np.inf):
        u = np.zeros(pole.n_joints)
        u[1] = bad
        with pytest.raises(NonFiniteError, match="not finite"):
            ep.act(0, u)
