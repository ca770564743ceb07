"""The written orders of :mod:`isf_robot.core.sums` (the numpy side of the compiled kernels) against plain loops.

Each function must give, bit for bit, the sum of correctly rounded products added in the order its
docstring writes, on any machine: the kernels make those operations in that order, and
``tests/arm/test_kernels.py`` / ``test_step_kernels.py`` compare whole rows and commands. The last test
shows the order matters on these draws (another order gives other bits), so the checks can fail.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core.sums import combine3, dot, dots3, gram, norm, row_norms, sq_sum


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
def test_sq_sum_and_row_norms_add_the_squares_in_order(rng, n) -> None:  # type: ignore[no-untyped-def]
    g = _draw(rng, 500, n)
    want = [math.sqrt(_loop(float(x) * float(x) for x in row)) for row in g.tolist()]
    assert _bits(row_norms(g)) == _bits(want)
    assert all(sq_sum(row) == _loop(x * x for x in row.tolist()) for row in g)
    assert row_norms(np.zeros((4, 0))).tolist() == [0.0] * 4


def test_dots3_and_combine3_add_from_zero_in_order(rng) -> None:  # type: ignore[no-untyped-def]
    a, b = _draw(rng, 800, 3), _draw(rng, 800, 3)
    want = [((0.0 + x[0] * y[0]) + x[1] * y[1]) + x[2] * y[2] for x, y in zip(a.tolist(), b.tolist())]
    assert _bits(dots3(a, b)) == _bits(want)
    jac = _draw(rng, 200, 3, 9)
    got = combine3(a[:200], jac)
    assert got.shape == (200, 9)
    for k in range(200):
        w, j = a[k].tolist(), jac[k].tolist()
        assert _bits(got[k]) == _bits([((0.0 + w[0] * j[0][c]) + w[1] * j[1][c]) + w[2] * j[2][c] for c in range(9)])
    assert _bits(combine3(a[0], jac[0])) == _bits(got[0])  # one vector and one block: the same numbers


@pytest.mark.parametrize("n", [1, 6, 7, 12])
def test_gram_adds_each_entry_in_column_order(rng, n) -> None:  # type: ignore[no-untyped-def]
    for _ in range(200):
        jac = _draw(rng, 3, n)
        rows = jac.tolist()
        want = [[_loop_from_first([rows[a][k] * rows[b][k] for k in range(n)]) for b in range(3)] for a in range(3)]
        got = gram(jac)
        assert _bits(got) == _bits(want) and _bits(got) == _bits(got.T)


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
    assert gram(np.zeros((2, 0))).shape == (2, 2)


def test_the_order_matters_on_these_draws(rng) -> None:  # type: ignore[no-untyped-def]
    g = _draw(rng, 2000, 7)
    reverse = np.sqrt([_loop(float(x) * float(x) for x in row[::-1]) for row in g.tolist()])
    assert _bits(row_norms(g)) != _bits(reverse)
    a, b = _draw(rng, 2000, 3), _draw(rng, 2000, 3)
    other = [(x[0] * y[0] + x[2] * y[2]) + x[1] * y[1] for x, y in zip(a.tolist(), b.tolist())]
    assert _bits(dots3(a, b)) != _bits(other)
