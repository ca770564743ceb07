"""The arm's control laws as formulas: known answers and invariants (:mod:`isf_robot.arm.reaching_law`,
:mod:`isf_robot.arm.tracking_law`).

These are the functions both the numpy paths and the compiled kernels call; a wrong sign or a
dropped term here must fail a test of what the formula is for, not only an equivalence test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.arm.reaching_law import (
    cap_speed,
    damped_least_squares,
    ee_distance,
    ee_gain,
    peak_abs,
    peak_change,
    rate_limit,
)
from isf_robot.arm.tracking_law import (
    command_feedforward,
    desired_acceleration,
    motor_ctrl,
    reference_error,
    tracking_error,
)


def test_damped_least_squares_known_answer() -> None:
    # J = [e1, e2] in R^3: J J^T + I = diag(2, 2, 1); y = (1, 2, 6); u = J^T y = (1, 2)
    jac = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    u = damped_least_squares(jac, np.array([2.0, 4.0, 6.0]), 1.0, np.empty(2))
    np.testing.assert_allclose(u, [1.0, 2.0], rtol=1e-15)


@pytest.mark.parametrize("n,lam2", [(1, 1e-4), (3, 0.01), (7, 0.01), (7, 1.0)])
def test_damped_least_squares_is_the_regularised_normal_equations(rng, n, lam2) -> None:  # type: ignore[no-untyped-def]
    for _ in range(20):
        jac, v = rng.normal(size=(3, n)), rng.normal(size=3)
        u = damped_least_squares(jac, v, lam2, np.empty(n))
        np.testing.assert_allclose(u, jac.T @ np.linalg.solve(jac @ jac.T + lam2 * np.eye(3), v), rtol=1e-9,
                                   atol=1e-12)
        # and u minimises |J u - v|^2 + lam2 |u|^2: its gradient J^T (J u - v) + lam2 u vanishes
        np.testing.assert_allclose(jac.T @ (jac @ u - v) + lam2 * u, 0.0, atol=1e-9 * (1 + np.abs(v).max()))


def test_ee_gain_caps_the_task_speed() -> None:
    for dist in (0.0, 0.01, 0.1, 1.0):
        err = np.array([dist, 0.0, 0.0])
        g = ee_gain(ee_distance(err), 2.0, 0.25)
        assert math.isclose(g * dist, min(2.0 * dist, 0.25), rel_tol=1e-15, abs_tol=1e-300)
    assert ee_distance(np.array([3.0, 4.0, 12.0])) == 13.0


def test_cap_speed_keeps_the_direction_and_the_limit(rng) -> None:  # type: ignore[no-untyped-def]
    np.testing.assert_allclose(cap_speed(np.array([0.5, -1.5, 0.3]), 1.0), [1 / 3, -1.0, 0.2], rtol=1e-15)
    assert np.array_equal(cap_speed(np.array([0.5, -1.0, 0.3]), 1.0), [0.5, -1.0, 0.3])  # at the cap: untouched
    for scale in (0.1, 0.5, 1.0, 10.0):
        u = rng.normal(scale=scale, size=7)
        before = u.copy()
        out = cap_speed(u, 1.0)
        assert out is u  # in place
        assert np.max(np.abs(u)) <= 1.0 * (1 + 1e-15)
        if np.max(np.abs(before)) <= 1.0:
            assert np.array_equal(u, before)  # within the cap: untouched
        else:
            assert math.isclose(np.max(np.abs(u)), 1.0, rel_tol=1e-15)
            np.testing.assert_allclose(u * (np.max(np.abs(before))), before, rtol=1e-14)  # same direction


def test_rate_limit_invariants(rng) -> None:  # type: ignore[no-untyped-def]
    for _ in range(50):
        prev, u = rng.normal(size=5), rng.normal(scale=3.0, size=5)
        want, p = u.copy(), prev.copy()
        out = rate_limit(u, p, True, 0.01, 10.0)
        change = out - prev
        assert np.max(np.abs(change)) <= 0.1 * (1 + 1e-12)
        if np.max(np.abs(want - prev)) > 0.1:  # limited: the change keeps its direction, at the limit
            assert math.isclose(np.max(np.abs(change)), 0.1, rel_tol=1e-12)
            np.testing.assert_allclose(change / 0.1, (want - prev) / np.max(np.abs(want - prev)), atol=1e-12)
        else:
            assert np.array_equal(out, want)
        assert np.array_equal(p, out)  # the previous command becomes this one
    u, p = np.ones(3), np.full(3, 5.0)
    assert not rate_limit(u, p, False, 0.01, 10.0).any() and not p.any()  # first call: at rest
    u, p = np.full(3, 2.0), np.zeros(3)
    assert np.array_equal(rate_limit(u, p, True, -1.0, 10.0), np.zeros(3))  # time going back: no change allowed
    u, p = np.full(3, 7.0), np.zeros(3)
    assert np.array_equal(rate_limit(u, p, True, 1e-6, math.inf), np.full(3, 7.0))  # a_max = inf: no limit


def test_tracking_law_known_answers() -> None:
    # reference: clip(ref + u dt - q) to +-e_max
    assert reference_error(1.0, 2.0, 0.5, 1.5, 1.0) == 0.5
    assert reference_error(0.0, 10.0, 1.0, 0.0, 0.05) == 0.05 and reference_error(0.0, -10.0, 1.0, 0.0, 0.05) == -0.05
    e = reference_error(np.zeros(3), np.array([1.0, -1.0, 0.0]), 0.1, np.zeros(3), 0.05)
    assert np.array_equal(e, [0.05, -0.05, 0.0])  # arrays, element by element
    # acceleration: kd (u - qd) + kp e + a_ff
    assert desired_acceleration(1.0, 0.5, 0.1, 20.0, 100.0, 3.0) == 20.0 * 0.5 + 100.0 * 0.1 + 3.0
    # control: clip((tau + bias - passive + friction) / gear)
    assert motor_ctrl(2.0, 1.0, 0.5, 0.5, 0.5, -10.0, 10.0) == 1.5
    assert motor_ctrl(100.0, 0.0, 0.0, 0.0, 1.0, -10.0, 10.0) == 10.0
    assert motor_ctrl(-100.0, 0.0, 0.0, 0.0, 1.0, -10.0, 10.0) == -10.0
    assert command_feedforward(1.0, 0.5, 1000.0) == 500.0
    assert tracking_error(np.array([3.0, 0.0]), np.array([0.0, 4.0])) == 5.0


def test_a_nan_command_is_not_hidden_by_the_caps() -> None:
    u = np.array([0.1, np.nan, 3.0])
    assert math.isnan(peak_abs(u)) and math.isnan(peak_change(u, np.zeros(3)))
    assert math.isnan(cap_speed(u.copy(), 1.0)[1])  # (the NaN stays visible to the filter's input checks)
    assert peak_abs(np.zeros(0)) == 0.0
