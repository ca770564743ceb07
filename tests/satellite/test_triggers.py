"""The satellite's triggers: the registry and the band trigger values against the core."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import Linear, ManeuverScheduler, UnknownNameError
from satellite.control.controller import ControlParams, make_controller, resolve_control
from satellite.control.triggers import TRIGGERS, BandTriggers, Trigger
from satellite.gravity.spherical import load_default_field  # the degree-8 series: these cases were chosen on it
from satellite.orbit.model import OrbitModel


@pytest.fixture(scope="module")
def model() -> OrbitModel:
    return OrbitModel(load_default_field())


def random_states(model: OrbitModel, n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        r = (1.6 + 0.8 * k / (n - 1)) * model.R
        out.append(np.concatenate([r * u, rng.normal(size=3) * 0.05]))
    return out


def test_registry_parses_names_and_refuses_others() -> None:
    assert TRIGGERS == ("none", "greedy", "maneuver", "periodic")
    for name in TRIGGERS:
        t = Trigger.parse(name)
        assert t is Trigger.parse(t)
        assert t == name and str(t) == name and f"{t}" == name
    assert [t.needs_tau for t in Trigger] == [False, False, True, False]
    with pytest.raises(UnknownNameError, match="greedy"):
        Trigger.parse("greed")


def test_band_triggers_equal_the_core_controller(model: OrbitModel) -> None:
    res = resolve_control(model)
    ctrl = make_controller(model, res)
    band = BandTriggers(model, Linear(res.alpha_gain), res.d_bar)
    sched = ManeuverScheduler(ctrl, lambda h: 3600.0 + h, lambda h: 0.3 + 1e-4 * h)
    xt = band.xi_tau_fn(sched.dtau_p_dh)
    for x in random_states(model, 30, seed=5):
        assert band.xi(0.0, x) == pytest.approx(ctrl.xi(0.0, x), rel=1e-10, abs=1e-12)
        assert xt(0.0, x) == pytest.approx(sched.xi_tau(0.0, x), rel=1e-10, abs=1e-12)
        assert band.h(0.0, x) == pytest.approx(ctrl.barrier.value(x, 0.0), rel=1e-12, abs=1e-9)
    ctrl_d = make_controller(model, resolve_control(model, ControlParams(d_bar=1e-4)))
    band_d = BandTriggers(model, ctrl_d.alpha, 1e-4)
    for x in random_states(model, 10, seed=6):
        assert band_d.xi(0.0, x) == pytest.approx(ctrl_d.xi(0.0, x), rel=1e-10, abs=1e-12)
        # the disturbance term lowers Xi by |dh/dx| d_bar = 2 |r - 2R| d_bar
        r = float(np.linalg.norm(x[:3]))
        drop = 2.0 * abs(r - 2.0 * model.R) * 1e-4
        band_0 = BandTriggers(model, ctrl_d.alpha, 0.0)
        assert band_0.xi(0.0, x) - band_d.xi(0.0, x) == pytest.approx(drop, rel=1e-9, abs=1e-12)


def test_band_parts_are_the_barrier_and_its_lie_derivative(model: OrbitModel) -> None:
    band = BandTriggers(model, Linear(1e-4), 0.0)
    for x in random_states(model, 10, seed=7):
        r, h, lfh = band.parts(x)
        assert r == pytest.approx(float(np.linalg.norm(x[:3])), rel=1e-14)
        assert h == pytest.approx(model.h_of_r(r), rel=1e-12, abs=1e-9)
        # LF h = dh/dt along the free flow: central difference of h along x + t v (d/dt of r only)
        eps = 1e-3
        hp = band.h(0.0, np.concatenate([x[:3] + eps * x[3:], x[3:]]))
        hm = band.h(0.0, np.concatenate([x[:3] - eps * x[3:], x[3:]]))
        assert lfh == pytest.approx((hp - hm) / (2 * eps), rel=1e-6, abs=1e-9)
        assert math.copysign(1.0, band.r_dot(0.0, x)) == math.copysign(1.0, float(x[:3] @ x[3:]))


def test_tau_slope_is_the_derivative_of_tau_p_and_within_its_bounds() -> None:
    """``dtau_dh`` (the compiled arcs' :func:`tau_slope`) against central differences of ``tau_p``; d1, d2 hold."""
    from satellite.control.tau import TauFit, tau_slope

    fit = TauFit([3600.0, -900.0, 2500.0, -1200.0], h_max=4000.0)
    d1, d2 = fit.slope_bounds
    hs = np.linspace(40.0, 3960.0, 50)
    step = 1e-3
    fd = np.array([(fit.tau_p(h + step) - fit.tau_p(h - step)) / (2 * step) for h in hs])
    slope = np.array([fit.dtau_dh(h) for h in hs])
    np.testing.assert_allclose(slope, fd, rtol=1e-6)
    assert np.all(np.abs(slope) <= d1)
    curv = np.array([(fit.dtau_dh(h + step) - fit.dtau_dh(h - step)) / (2 * step) for h in hs])
    assert np.all(np.abs(curv) <= d2 * (1 + 1e-9))
    assert fit.dtau_dh(-50.0) == fit.dtau_dh(0.0) and fit.dtau_dh(5000.0) == fit.dtau_dh(4000.0)  # held outside
    assert tau_slope(fit.packed, 1234.0) == fit.dtau_dh(1234.0)
