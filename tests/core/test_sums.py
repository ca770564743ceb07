"""The written orders of :mod:`isf_robot.core.sums` (the numpy side of the compiled kernels) against plain loops.

Each function must give, bit for bit, the sum of correctly rounded products added in the order its
docstring writes, on any machine (the metrics and the satellite's orbit rely on it). The last test
shows the order matters on these draws (another order gives other bits), so the checks can fail.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core.sums import dot, norm, row_sq_sums, sq_sum


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261127)


def _draw(rng, *shape):  # type: ignore[no-untyped-def]
    x = rng.normal(size=shape) * 10.0 ** rng.uniform(-6, 6, size=shape)
    x[rng.random(shape) < 0.2] = -0.0
    x[rng.random(shape) < 0.05] = 0.0
    return x


def _bits(a) -> bytes:  # type: ignore[no-untyped-def]
    return np.asarray(a, dtype=float).tobytes()


def _loop(terms) -> float:  # type: ignore[no-untyped-def]
    s = 0.0
    for x in terms:
        s += x
    return s


@pytest.mark.parametrize("n", [1, 3, 7, 9, 17])
def test_sq_sum_and_row_sq_sums_add_the_squares_in_order(rng, n) -> None:  # type: ignore[no-untyped-def]
    g = _draw(rng, 500, n)
    want = [_loop(float(x) * float(x) for x in row) for row in g.tolist()]
    assert _bits(row_sq_sums(g)) == _bits(want)
    assert all(sq_sum(row) == _loop(x * x for x in row.tolist()) for row in g)
    assert row_sq_sums(np.zeros((4, 0))).tolist() == [0.0] * 4


def _loop_from_first(terms: list[float]) -> float:
    s = terms[0]
    for x in terms[1:]:
        s = s + x
    return s


@pytest.mark.parametrize("m", [1, 3, 6, 16])
def test_dot_and_norm_add_in_order(rng, m) -> None:  # type: ignore[no-untyped-def]
    for _ in range(200):
        a, b = _draw(rng, m), _draw(rng, m)
        assert _bits(dot(a, b)) == _bits(_loop_from_first([x * y for x, y in zip(a.tolist(), b.tolist())]))
        assert norm(a) == math.sqrt(_loop(x * x for x in a.tolist()))


def test_the_order_matters_on_these_draws(rng) -> None:  # type: ignore[no-untyped-def]
    g = _draw(rng, 2000, 7)
    reverse = [_loop(float(x) * float(x) for x in row[::-1]) for row in g.tolist()]
    assert _bits(row_sq_sums(g)) != _bits(reverse)
