import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from isf_robot.core import (
    DiscObstacleBarrier,
    FunctionBarrier,
    FunctionSystem,
    HalfSpaceBarrier,
    Linear,
    SingleIntegrator,
    evaluate_barriers,
    lie_data,
    xi_on,
)


def fd_grad(fn, x, eps=1e-6):
    g = np.zeros_like(x)
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = eps
        g[i] = (fn(x + e) - fn(x - e)) / (2 * eps)
    return g


BARRIERS = [
    DiscObstacleBarrier([1.0, -0.5], 0.4),
    DiscObstacleBarrier([0.3, 0.2, -1.0], 0.7, dims=[0, 2, 3]),
    DiscObstacleBarrier([1.0, 0.0], 0.5, velocity=[-0.3, 0.2]),
    HalfSpaceBarrier([1.0, -2.0, 0.5, 0.0], 0.3),
    FunctionBarrier(lambda x, t: np.sin(x[0]) * x[1] + t * x[2] ** 2,
                    lambda x, t: np.array([np.cos(x[0]) * x[1], np.sin(x[0]), 2 * t * x[2], 0.0]),
                    lambda x, t: x[2] ** 2),
]


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000))
def test_barrier_gradients_match_finite_differences(seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=4)
    t = float(rng.uniform(0, 3))
    for b in BARRIERS:
        g = b.gradient(x, t)
        np.testing.assert_allclose(g, fd_grad(lambda y: b.value(y, t), x), atol=1e-6, rtol=1e-6)
        dt_fd = (b.value(x, t + 1e-6) - b.value(x, t - 1e-6)) / 2e-6
        assert b.time_derivative(x, t) == pytest.approx(dt_fd, abs=1e-6, rel=1e-6)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000))
def test_lie_derivatives_match_finite_differences_along_the_flow(seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(4, 4))
    B = rng.normal(size=(4, 2))
    sys = FunctionSystem(4, 2, lambda x, t: np.tanh(A @ x), lambda x, t: B * (1 + 0.1 * x[0]))
    x = rng.normal(size=4)
    u = rng.normal(size=2)
    t = 0.7
    ev = evaluate_barriers(BARRIERS, x, t)
    lie = lie_data(ev, sys.f0(x, t), sys.g(x, t))
    xdot = sys.dynamics(x, u, t)
    eps = 1e-6
    for i, b in enumerate(BARRIERS):
        # d/dt h(x(t), t) along x_dot = f0 + g u
        fd = (b.value(x + eps * xdot, t + eps) - b.value(x - eps * xdot, t - eps)) / (2 * eps)
        assert lie.lf[i] + lie.lg[i] @ u == pytest.approx(fd, rel=1e-5, abs=1e-6)
        assert lie.grad_norm[i] == pytest.approx(np.linalg.norm(fd_grad(lambda y: b.value(y, t), x)), rel=1e-5)


def test_disc_barrier_sign_inside_outside():
    b = DiscObstacleBarrier([0.0, 0.0], 1.0)
    assert b.value(np.array([2.0, 0.0])) > 0
    assert b.value(np.array([1.0, 0.0])) == pytest.approx(0.0)
    assert b.value(np.array([0.5, 0.0])) < 0


def test_xi_on_formula():
    b = DiscObstacleBarrier([1.0, 0.0], 0.5)
    x = np.array([0.0, 0.0])
    lie = lie_data(evaluate_barriers([b], x), np.zeros(2), np.eye(2))
    u = np.array([1.0, 0.0])
    # h = 1 - 0.25 = 0.75, grad = (-2, 0): Lf h(x, u) = -2; |grad| d_bar = 2 * 0.1
    assert xi_on(lie, u, Linear(3.0), 0.1)[0] == pytest.approx(-2.0 - 0.2 + 3.0 * 0.75)


def test_single_integrator_shapes():
    s = SingleIntegrator(3)
    assert s.f0(np.zeros(3)).shape == (3,)
    assert s.g(np.zeros(3)).shape == (3, 3)
