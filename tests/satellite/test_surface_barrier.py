"""The surface as part of safety (issue 14, item 2): the surface-clearance barrier."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from isf_robot.core import ConfigError
from satellite.control.controller import make_controller, resolve_control
from satellite.control.surface_barrier import Superellipsoid, SurfaceBarrier, SurfaceFilter, SurfaceTriggers
from satellite.gravity.spherical import load_default_field  # the degree-8 series: these cases were chosen on it
from satellite.orbit.model import InitialOrbit, OrbitModel
from satellite.orbit.simulate import simulate
from satellite.shape.mesh_surface import load_surface


@pytest.fixture(scope="module")
def shape():  # type: ignore[no-untyped-def]
    return load_surface()


@pytest.fixture(scope="module")
def model() -> OrbitModel:
    return OrbitModel(load_default_field())


@pytest.fixture(scope="module")
def barrier(shape, model: OrbitModel) -> SurfaceBarrier:  # type: ignore[no-untyped-def]
    return SurfaceBarrier(Superellipsoid.of_surface(shape), 0.7, model.omega, 5.0)


def test_envelope_holds_the_whole_shape_and_is_smooth_and_not_absurd(shape, model: OrbitModel) -> None:  # type: ignore[no-untyped-def]
    env = Superellipsoid.of_surface(shape)
    assert env.p == 4
    assert float(env.clearance(np.asarray(shape.vertices, dtype=float).T).max()) <= 0.0  # every vertex inside
    u = np.random.default_rng(0).normal(size=(3, 20000))
    u /= np.linalg.norm(u, axis=0)
    reach = 0.0
    for lo, hi in [(0.0, 3.0 * model.R)]:  # the envelope's radius along each direction, by bisection
        a, b = np.full(u.shape[1], lo), np.full(u.shape[1], hi)
        for _ in range(60):
            m = 0.5 * (a + b)
            out = env.clearance(u * m) > 0
            a, b = np.where(out, a, m), np.where(out, m, b)
        reach = float(b.max())
    r_shape = float(np.linalg.norm(shape.vertices, axis=1).max())
    assert r_shape <= reach <= 1.15 * r_shape  # contains the tips: 2.13 R against the shape's 1.93 R


def test_gradient_and_time_derivative_match_finite_differences(barrier: SurfaceBarrier) -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        x = np.concatenate([rng.normal(size=3) * 300.0, rng.normal(size=3) * 0.05])
        t = float(rng.uniform(0, 1e5))
        g = barrier.gradient(x, t)
        fd = np.zeros(6)
        for i in range(3):
            e = np.zeros(6)
            e[i] = 1e-3
            fd[i] = (barrier.value(x + e, t) - barrier.value(x - e, t)) / 2e-3
        np.testing.assert_allclose(g, fd, atol=1e-7)
        dt = (barrier.value(x, t + 0.1) - barrier.value(x, t - 0.1)) / 0.2
        assert barrier.time_derivative(x, t) == pytest.approx(dt, abs=1e-8)
        h, lfh, gn = barrier.parts(t, x)  # dh/dt along the motion = grad . v + explicit part
        assert lfh == pytest.approx(float(g[:3] @ x[3:]) + barrier.time_derivative(x, t), abs=1e-12)
        assert gn == pytest.approx(float(np.linalg.norm(g)), rel=1e-12) and h == pytest.approx(barrier.value(x, t))


def test_xi_s_is_the_core_formula_and_its_rate_bound_holds_on_truth_arcs(barrier, model: OrbitModel) -> None:  # type: ignore[no-untyped-def]
    res = resolve_control(model)
    ctrl = make_controller(model, res)
    tr = SurfaceTriggers(barrier, ctrl.alpha, 0.0, model.accel_bound(samples=400), 2.4 * model.R, 1.05 * res.alpha_gain)
    rng = np.random.default_rng(2)
    checked = 0
    while checked < 5:
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        r = rng.uniform(1.65, 2.1) * model.R
        w = np.cross(u, rng.normal(size=3))
        w /= np.linalg.norm(w)
        y0 = np.concatenate([r * u, rng.uniform(0.8, 1.1) * math.sqrt(model.mu / r) * w])
        if tr.h(0.0, y0) < 0:
            continue
        assert tr.xi(3.0, y0) == pytest.approx(ctrl.xi(3.0, y0, barrier), rel=1e-9, abs=1e-12)
        sol = solve_ivp(model.truth_rhs, (0.0, 1200.0), y0, method="DOP853", rtol=1e-11, atol=1e-12, dense_output=True)
        ts = np.linspace(0.0, 1200.0, 4001)
        ys = sol.sol(ts)
        if np.any(tr.h_batch(ts, ys) < 0) or np.any(np.linalg.norm(ys[:3], axis=0) > 2.4 * model.R):
            continue  # the bound is stated outside the envelope, inside the band
        g = tr.xi_batch(ts, ys)
        assert float(np.max(np.abs(np.diff(g)) / np.diff(ts))) <= float(tr.xi_rate(ys[:, 0], ys[:, -1], 1200.0))
        hs = tr.h_batch(ts, ys)
        assert float(np.max(np.abs(np.diff(hs)) / np.diff(ts))) <= float(tr.h_rate(ys[:, 0], ys[:, -1], 1200.0))
        checked += 1


def test_filter_keeps_the_papers_impulse_or_meets_both_post_jump_conditions(barrier, model: OrbitModel) -> None:  # type: ignore[no-untyped-def]
    res = resolve_control(model)
    ctrl = make_controller(model, res)
    c_s = res.c / (2 * model.half_width)
    f = SurfaceFilter(ctrl.controller, ctrl.barrier, barrier, ctrl.alpha, res.c, c_s)
    rng = np.random.default_rng(3)
    kept = changed = 0
    for _ in range(400):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        x = np.concatenate([rng.uniform(1.6, 2.4) * model.R * u, rng.normal(size=3) * 0.06])
        t = float(rng.uniform(0, 1e5))
        if barrier.value(x, t) < 0:
            continue
        dv = f(t, x)
        xp = x.copy()
        xp[3:] += dv
        assert ctrl.xi(t, xp) >= res.c and ctrl.xi(t, xp, barrier) >= c_s  # both post-jump conditions
        if np.array_equal(dv, ctrl.controller(t, x)):
            kept += 1
        else:
            changed += 1
    assert kept > 50 and changed > 5 and f.filtered == changed


@dataclass(frozen=True)
class _At(InitialOrbit):
    """Start from a recorded state: post-jump state of the last impulse before a contact."""

    def state(self, model: OrbitModel) -> np.ndarray:
        # `simulate("greedy", 62.9, initial=InitialOrbit(seed=0))` (degree-8 field): impulse at
        # 58.02 h; the orbit then passes 14 m deep through the shape at 63.0 h.
        return np.array([-221.2217053380037, 52.93661612061237, -165.65521547251313,
                         -0.011962702791170041, -0.08967412729087604, -0.018908409356407092])

    def body_phase(self) -> float:
        return 5.17104460118254


def test_run_with_the_surface_barrier_avoids_the_contact_the_band_alone_allows(shape) -> None:  # type: ignore[no-untyped-def]
    kw = dict(initial=_At(seed=0), miet_samples=50, contact="count", contact_surface=shape,
              model=OrbitModel(load_default_field()))  # the state was recorded on the degree-8 field
    off = simulate("greedy", 6.0, **kw)
    assert off.contact["surface_contacts"] >= 1 and off.contact["min_pass_clearance_m"] < -1.0  # the test can fail
    on = simulate("greedy", 6.0, surface_barrier=True, **kw)
    assert on.contact["surface_contacts"] == 0
    sb = on.surface_barrier
    assert sb is not None and sb["surface_min_h_m"] >= 0.0 and on.kinds.get("surface", 0) >= 1
    assert on.min_h >= 0.0 and on.band_exits == 0
    c, c_s = on.settings["c"], sb["surface_c"]
    assert c_s == 0.01  # the default margin
    sb_run = SurfaceBarrier(Superellipsoid.of_surface(shape), _At(seed=0).body_phase(), OrbitModel(load_default_field()).omega)
    gain = on.settings["alpha_gain"]
    for e in on.events:  # the surface's post-jump condition, recomputed from the impulse's states
        h_s, lf, _ = sb_run.parts(e.t, e.x_after)
        assert h_s >= 0.0 and lf + gain * h_s >= c_s - 1e-12
    for e in on.events:
        assert e.xi_after >= c - 1e-9 and e.h_after >= 0.0
    assert sb["surface_impulses"] == on.kinds["surface"]
    with pytest.raises(ConfigError, match="greedy and maneuver"):
        simulate("periodic", 1.0, period_h=0.5, surface_barrier=True, miet_samples=20)
    with pytest.raises(ConfigError, match="clearance"):
        simulate("greedy", 1.0, surface_barrier=True, surface_clearance_m=-1.0, miet_samples=20)


def test_maneuver_run_with_the_surface_barrier(shape) -> None:  # type: ignore[no-untyped-def]
    from satellite.control.tau import TauFit

    model = OrbitModel(load_default_field())
    tau = TauFit([3000.0, 3000.0], model.h_max)  # tau_p from 50 to 100 min over the band
    kw = dict(initial=_At(seed=0), miet_samples=50, contact="count", contact_surface=shape, tau=tau)
    on = simulate("maneuver", 6.0, surface_barrier=True, **kw)
    sb = on.surface_barrier
    assert on.contact["surface_contacts"] == 0 and sb["surface_impulses"] >= 1 and sb["surface_min_h_m"] >= 0.0
    assert on.min_h >= 0.0 and set(on.kinds) <= {"greedy", "safe", "tau"}
    sb_run = SurfaceBarrier(Superellipsoid.of_surface(shape), _At(seed=0).body_phase(), model.omega)
    for e in on.events:
        h_s, lf, _ = sb_run.parts(e.t, e.x_after)
        assert h_s >= 0.0 and lf + on.settings["alpha_gain"] * h_s >= sb["surface_c"] - 1e-12
        assert e.xi_after >= on.settings["c"] - 1e-9
