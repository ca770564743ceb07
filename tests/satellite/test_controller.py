"""Safeguarding impulsive controller: geometry of the impulse and the post-jump conditions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import ConfigError
from satellite.control.controller import (
    ControlParams,
    SafeguardingController,
    make_controller,
    resolve_control,
)
from satellite.gravity.spherical import load_default_field  # the degree-8 series: these cases were chosen on it
from satellite.orbit.elements import osculating_elements
from satellite.orbit.model import OrbitModel


@pytest.fixture(scope="module")
def model() -> OrbitModel:
    return OrbitModel(load_default_field())


def random_states(model: OrbitModel, n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        r = (1.6 + 0.8 * k / (n - 1)) * model.R
        v = rng.normal(size=3) * 0.05
        out.append(np.concatenate([r * u, v]))
    return out


def test_impulse_geometry(model: OrbitModel) -> None:
    K = SafeguardingController(model)
    R = model.R
    for x in random_states(model, 81):
        dv = K(0.0, x)
        xp = x.copy()
        xp[3:] += dv
        r = float(np.linalg.norm(x[:3]))
        rhat = x[:3] / r
        # radius unchanged: the impulse changes velocity only
        np.testing.assert_array_equal(xp[:3], x[:3])
        # plane kept, same sense of motion
        h0 = np.cross(x[:3], x[3:])
        h1 = np.cross(xp[:3], xp[3:])
        assert float(h0 @ h1) > 0
        np.testing.assert_allclose(np.cross(h0 / np.linalg.norm(h0), h1 / np.linalg.norm(h1)), 0, atol=1e-12)
        # radial velocity toward 2R
        vr = float(rhat @ xp[3:])
        if r > 2 * R + 1e-9:
            assert vr < 0
        elif r < 2 * R - 1e-9:
            assert vr > 0
        # osculating elements: intended apsis and true anomaly
        el = osculating_elements(xp, model.mu)
        r_t = 2 * R + 0.5 * (r - 2 * R)
        if r >= 2 * R:
            nu = -math.pi + 0.5 * math.pi * (r - 2 * R) / (0.4 * R)
            assert el.periapsis == pytest.approx(r_t, rel=1e-10)
        else:
            nu = 0.5 * math.pi * (2 * R - r) / (0.4 * R)
            assert el.apoapsis == pytest.approx(r_t, rel=1e-10)
        if el.e > 1e-6:
            dnu = (el.nu - nu + math.pi) % (2 * math.pi) - math.pi
            assert abs(dnu) < 1e-7
        # vis-viva
        assert float(xp[3:] @ xp[3:]) == pytest.approx(model.mu * (2 / r - 1 / el.a), rel=1e-10)


def test_radial_velocity_fallback_plane(model: OrbitModel) -> None:
    K = SafeguardingController(model)
    x = np.array([2.2 * model.R, 0.0, 0.0, 0.01, 0.0, 0.0])  # purely radial velocity
    dv = K(0.0, x)
    assert np.all(np.isfinite(dv))
    el = osculating_elements(x + np.concatenate([[0, 0, 0], dv]), model.mu)
    assert el.periapsis == pytest.approx(2.1 * model.R, rel=1e-10)


def test_post_jump_conditions_hold_across_band(model: OrbitModel) -> None:
    res = resolve_control(model)
    assert 0 < res.c < res.min_post_jump_xi
    ctrl = make_controller(model, res)
    for x in random_states(model, 201, seed=2):
        ev = ctrl.apply_jump(0.0, x, "greedy")  # raises PostJumpConditionError on failure
        assert ev.h_after >= -1e-9
        assert ev.xi_after >= res.c
        ctrl.reset()


def test_margin_check_refuses_impossible_c(model: OrbitModel) -> None:
    res = resolve_control(model)
    with pytest.raises(ConfigError, match="exceeds"):
        resolve_control(model, ControlParams(c=2 * res.min_post_jump_xi))
    with pytest.raises(ConfigError, match="no positive margin"):
        resolve_control(model, ControlParams(d_bar=1.0))
