"""The scalar fast path of the on trigger is the vectorised formula, row by row, to the bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import ClassK, CustomClassK, LieData, Linear, Power, xi_on
from isf_robot.core.triggers import xi_on_scalar

ALPHAS: list[ClassK] = [
    Linear(2.5e-4),
    Linear(3.0),
    Power(0.7, 0.5),
    Power(2.0, 3.0),
    CustomClassK(lambda h: math.atan(h) + 0.1 * h, name="atan"),
]


def random_lie(rng: np.random.Generator, k: int, m: int) -> LieData:
    """Lie data spanning many magnitudes and both signs of h (inside and outside the set)."""
    scale = 10.0 ** rng.uniform(-6, 6, size=k)
    return LieData(
        h=rng.normal(size=k) * scale,
        lf=rng.normal(size=k) * scale,
        lg=rng.normal(size=(k, m)) * scale[:, None],
        grad_norm=np.abs(rng.normal(size=k)) * scale,
    )


@pytest.mark.parametrize("alpha", ALPHAS, ids=repr)
@pytest.mark.parametrize("d_bar", [0.0, 1e-4, 0.7])
def test_scalar_equals_vector_row_by_row(alpha: ClassK, d_bar: float) -> None:
    rng = np.random.default_rng(11)
    for m in (1, 3, 7):
        lie = random_lie(rng, 40, m)
        u = rng.normal(size=m) * 10.0 ** rng.uniform(-3, 3)
        vec = xi_on(lie, u, alpha, d_bar)
        lg_u = lie.lg @ u  # (xi_on's product)
        scalar = np.array([
            xi_on_scalar(float(lie.lf[i]), float(lg_u[i]), float(lie.grad_norm[i]), float(lie.h[i]), alpha, d_bar)
            for i in range(lie.k)
        ])
        np.testing.assert_allclose(scalar, vec, rtol=1e-14, atol=0)  # (Power: numpy's pow and libm's, to rounding)


def test_scalar_terms_have_their_signs() -> None:
    """Each term moves the value the way the paper's formula says (not just a consistent copy)."""
    alpha = Linear(2.0)
    base = xi_on_scalar(1.0, 0.5, 3.0, 4.0, alpha, 0.25)
    assert base == pytest.approx(1.0 + 0.5 - 0.75 + 8.0)
    assert xi_on_scalar(2.0, 0.5, 3.0, 4.0, alpha, 0.25) - base == pytest.approx(1.0)  # + Lf h
    assert xi_on_scalar(1.0, 1.5, 3.0, 4.0, alpha, 0.25) - base == pytest.approx(1.0)  # + Lg h u
    assert xi_on_scalar(1.0, 0.5, 3.0, 4.0, alpha, 0.5) - base == pytest.approx(-0.75)  # - |dh/dx| d_bar
    assert xi_on_scalar(1.0, 0.5, 3.0, 5.0, alpha, 0.25) - base == pytest.approx(2.0)  # + alpha(h)
    # on the boundary with no motion and no disturbance the trigger is exactly zero
    assert xi_on_scalar(0.0, 0.0, 3.0, 0.0, alpha, 0.0) == 0.0


def test_greedy_trigger_of_the_impulsive_controller_is_the_scalar_formula() -> None:
    """``EventTriggeredImpulsiveController.xi`` (the core's greedy Xi) is ``xi_on_scalar`` with no input term."""
    from isf_robot.core import Barrier, EventTriggeredImpulsiveController

    class Disc(Barrier):
        name = "disc"

        def value(self, x: np.ndarray, t: float = 0.0) -> float:
            return 4.0 - float(x[0] ** 2 + x[1] ** 2)

        def gradient(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
            return np.array([-2.0 * x[0], -2.0 * x[1], 0.0, 0.0])

    def flow(t: float, x: np.ndarray) -> np.ndarray:
        return np.array([x[2], x[3], -x[0], -x[1]])

    alpha, d_bar = Power(0.8, 0.5), 0.3
    ctrl = EventTriggeredImpulsiveController(
        flow_model=flow, jump_map=lambda x, v: x, barrier=Disc(), controller=lambda t, x: np.zeros(2),
        alpha=alpha, c=0.1, d_bar=d_bar,
    )
    rng = np.random.default_rng(3)
    for x in rng.normal(size=(50, 4)):
        grad = ctrl.barrier.gradient(x)
        lf = float(grad @ flow(0.0, x))
        expected = xi_on_scalar(lf, 0.0, float(np.linalg.norm(grad)), ctrl.barrier.value(x), alpha, d_bar)
        assert ctrl.xi(0.0, x) == pytest.approx(expected, rel=1e-14, abs=1e-14)
