"""Orbit model: frames, spin, disturbance size, barrier, initial states."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from isf_robot.core import ConfigError
from satellite.gravity.spherical import load_default_field  # the degree-8 series: these cases were chosen on it
from satellite.orbit.elements import osculating_elements
from satellite.orbit.model import BandBarrier, InitialOrbit, OrbitModel


@pytest.fixture(scope="module")
def model() -> OrbitModel:
    return OrbitModel(load_default_field())


def test_constants_from_table(model: OrbitModel) -> None:
    assert model.R == pytest.approx(161.93, abs=0.01)
    assert model.mu == pytest.approx(2.34268, rel=1e-5)
    assert model.omega == pytest.approx(2 * math.pi / (12.1324 * 3600))
    assert OrbitModel(model.field, spin=False).omega == 0.0


def test_truth_rotates_the_body_field(model: OrbitModel) -> None:
    rng = np.random.default_rng(1)
    for _ in range(5):
        r = rng.normal(size=3) * 300
        t = rng.uniform(0, 1e5)
        th = model.body_phase + model.omega * t
        rz = np.array([[math.cos(th), -math.sin(th), 0], [math.sin(th), math.cos(th), 0], [0, 0, 1]])
        expect = rz @ model.field.acceleration(rz.T @ r)
        got = model.truth_rhs(t, np.concatenate([r, [0.1, 0.2, 0.3]]))
        np.testing.assert_allclose(got[3:], expect, rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(got[:3], [0.1, 0.2, 0.3])


def test_kepler_rhs(model: OrbitModel) -> None:
    x = np.array([300.0, -40.0, 20.0, 0.01, 0.02, 0.03])
    r = np.linalg.norm(x[:3])
    np.testing.assert_allclose(model.kepler_rhs(0.0, x)[3:], -model.mu * x[:3] / r**3, rtol=1e-14)


def test_disturbance_is_large_at_2R(model: OrbitModel) -> None:
    # REPRODUCTION.md, "When the paper's maneuver can act": about 20 % of the point-mass
    # pull at 2R (median over directions).
    rng = np.random.default_rng(0)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    ratios = [
        np.linalg.norm(model.disturbance(0.0, 2 * model.R * d)) / (model.mu / (2 * model.R) ** 2) for d in u
    ]
    assert 0.1 < float(np.median(ratios)) < 0.35


def test_jacobi_integral_conserved_with_spin(model: OrbitModel) -> None:
    # In a frame turning at omega about z, J = |v|^2 / 2 - U(r_body) - omega (x vy - y vx) is constant.
    x0 = InitialOrbit(radius_over_R=2.4, speed_factor=1.1, seed=4).state(model)

    def jacobi(t: float, x: np.ndarray) -> float:
        th = model.body_phase + model.omega * t
        c, s = math.cos(th), math.sin(th)
        rb = np.array([c * x[0] + s * x[1], c * x[1] - s * x[0], x[2]])
        return 0.5 * float(x[3:] @ x[3:]) - float(model.field.potential(rb)) - model.omega * (x[0] * x[4] - x[1] * x[3])

    sol = solve_ivp(model.truth_rhs, (0, 3600.0), x0, method="DOP853", rtol=1e-11, atol=1e-13)
    assert sol.status == 0 and np.linalg.norm(sol.y[:3], axis=0).min() > 1.6 * model.R
    j0, j1 = jacobi(0.0, x0), jacobi(sol.t[-1], sol.y[:, -1])
    assert abs(j1 - j0) < 1e-8 * abs(j0)


def test_band_barrier_values_and_gradient(model: OrbitModel) -> None:
    b = BandBarrier(model)
    d = np.array([0.6, -0.8, 0.0])
    for k, expect in ((1.6, 0.0), (2.4, 0.0), (2.0, (0.4 * model.R) ** 2)):
        assert b.value(np.concatenate([k * model.R * d, np.zeros(3)])) == pytest.approx(expect, abs=1e-8)
    rng = np.random.default_rng(3)
    for _ in range(10):
        x = np.concatenate([rng.normal(size=3) * 300, rng.normal(size=3) * 0.05])
        g = b.gradient(x)
        fd = np.array([(b.value(x + e) - b.value(x - e)) / 2e-4 for e in np.eye(6) * 1e-4])
        np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-6)


def test_initial_orbit_elements(model: OrbitModel) -> None:
    init = InitialOrbit(radius_over_R=2.1, inclination_deg=30.0, seed=7)
    x = init.state(model)
    el = osculating_elements(x, model.mu)
    assert np.linalg.norm(x[:3]) == pytest.approx(2.1 * model.R)
    assert el.e == pytest.approx(0.0, abs=1e-12)
    assert math.degrees(el.inclination) == pytest.approx(30.0)
    np.testing.assert_array_equal(x, InitialOrbit(radius_over_R=2.1, inclination_deg=30.0, seed=7).state(model))
    assert not np.allclose(x, InitialOrbit(radius_over_R=2.1, inclination_deg=30.0, seed=8).state(model))


@pytest.mark.parametrize(
    "kwargs", [{"radius_over_R": 2.5}, {"inclination_deg": -1.0}, {"speed_factor": 0.0}, {"seed": -1}]
)
def test_initial_orbit_rejects_bad_input(kwargs: dict) -> None:
    with pytest.raises(ConfigError):
        InitialOrbit(**kwargs)


def test_library_default_field_is_the_valid_one() -> None:
    """OrbitModel(), simulate() and the tau helpers default to the command line's valid field, not sh8."""
    import inspect

    from satellite.control.tau import collect_tau, time_to_trigger
    from satellite.gravity.fields import DEFAULT_GRAVITY, load_field, model_name
    from satellite.orbit.simulate import simulate

    model = OrbitModel()
    assert DEFAULT_GRAVITY == "table" and model_name(model.field) == model_name(load_field("table")) != "sh8"
    p = np.array([1.7 * model.R, 0.0, 0.0])  # inside the Brillouin sphere, where the series is invalid
    np.testing.assert_array_equal(model.field.acceleration(p), load_field("table").acceleration(p))
    res = simulate("greedy", 0.5)
    assert res.settings["gravity_model"] == model_name(model.field)
    for fn in (collect_tau, time_to_trigger):
        assert inspect.signature(fn).parameters["gravity"].default == DEFAULT_GRAVITY
