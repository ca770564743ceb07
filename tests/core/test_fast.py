"""The filter step's compiled kernel (isf_robot.core.fast): the numpy path's numbers, bit for bit."""

from __future__ import annotations

import collections
import math

import numpy as np
import pytest

from isf_robot.core import (
    CustomClassK,
    IntermittentSafetyFilter,
    LieData,
    Linear,
    NonFiniteError,
    Power,
    QPSolver,
    SafetyFilter,
)
from isf_robot.core.triggers import xi_on

pytest.importorskip("numba")
pytestmark = pytest.mark.kernels  # (skipped under ISF_ROBOT_JIT=0: tests/conftest.py)

ALPHAS = [Linear(2.0), Power(3.0, 0.7), CustomClassK(lambda h: h + h ** 3, "cubic")]


def _kernel():  # type: ignore[no-untyped-def]
    from isf_robot.core.fast import xi_kernel

    kernel = xi_kernel()
    assert kernel is not None, "numba is installed: the kernel must load"
    return kernel


def _lie(rng: np.random.Generator, k: int, m: int) -> LieData:
    lg = rng.normal(size=(k, m)) * 10.0 ** rng.uniform(-3, 3, size=(k, 1))
    h = rng.uniform(-0.1, 0.5, k)
    h[rng.random(k) < 0.2] = 0.0  # signed zeros and ties
    return LieData(h, rng.normal(scale=0.2, size=k), lg, np.linalg.norm(lg, axis=1), tuple(f"b{i}" for i in range(k)))


@pytest.mark.parametrize("alpha", ALPHAS, ids=repr)
def test_kernel_makes_xi_on_and_its_reductions_bit_for_bit(alpha) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.core._xi_jit import xi_plain  # (the pass without thresholds)

    kernel = _kernel()
    rng = np.random.default_rng(11)
    for _ in range(400):
        k, m = int(rng.integers(1, 40)), int(rng.integers(1, 10))
        lie, u = _lie(rng, k, m), rng.normal(size=m)
        d_bar = float(rng.choice([0.0, 0.05, 3.0]))
        ref = xi_on(lie, u, alpha, d_bar)
        gain = alpha.gain if isinstance(alpha, Linear) else 0.0  # (linear: the kernel makes gain h itself)
        for screen in (np.zeros(0), np.full(1, 0.1), rng.uniform(-0.5, 1.0, k)):
            out, rows = np.empty(k), np.full(k if screen.size else 0, -1, np.intp)
            total, low, arg, kept, first = kernel(lie.lf, lie.lg, u, lie.grad_norm, d_bar, lie.h, gain,
                                                  np.zeros(0) if gain else alpha.vector(lie.h), screen, out, rows)
            assert out.tobytes() == ref.tobytes()  # signed zeros included
            assert total == sum(ref.tolist()) and low == min(ref.tolist()) and arg == int(ref.argmin())
            below = np.flatnonzero(ref < (screen if screen.size else np.inf))
            assert kept == (below.size if screen.size else -1)
            assert first == (int(below[0]) if screen.size and below.size else -1)
            assert rows[:max(kept, 0)].tolist() == (below.tolist() if screen.size else [])
            plain = np.empty(k)
            total, low, arg = xi_plain(lie.lf, lie.lg, u, lie.grad_norm, d_bar, lie.h, gain,
                                       np.zeros(0) if gain else alpha.vector(lie.h), plain)
            assert plain.tobytes() == ref.tobytes() and total == sum(ref.tolist()) and low == min(ref.tolist())
            assert arg == int(ref.argmin())


def _run(make, jit: str, monkeypatch: pytest.MonkeyPatch, seed: int) -> list:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("ISF_ROBOT_JIT", jit)
    f = make()
    assert (f._kernel is None) == (jit == "0")
    rng = np.random.default_rng(seed)
    out = []
    for i in range(300):
        lie = _lie(rng, int(rng.integers(1, 9)), 8)  # at most as many rows as inputs: feasible
        screen = float(rng.choice([0.05, 0.3])) if i % 3 else rng.uniform(0.01, 0.5, lie.k)
        s = f.step_lie(0.01 * i, lie, rng.normal(size=8), screen=screen)
        out.append((s.u.tobytes(), s.xi.tobytes(), s.on, str(s.event), s.resolved,
                    None if s.qp is None else (s.qp.status, s.qp.active.tolist())))
    return out


@pytest.mark.parametrize("alpha", ALPHAS, ids=repr)
@pytest.mark.parametrize("kind", ["cbf", "isf", "cbf_few", "isf_few"])
def test_filters_give_the_same_steps_with_and_without_the_kernel(alpha, kind, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    def make():  # type: ignore[no-untyped-def]
        solver = QPSolver(few_rows=kind.endswith("_few"))  # (built here: it reads ISF_ROBOT_JIT)
        if kind.startswith("cbf"):
            return SafetyFilter(alpha, 0.05, validate=False, solver=solver)
        return IntermittentSafetyFilter(alpha, 0.1, 0.05, 0.05, validate=False, blend=0.03, solver=solver)

    steps = _run(make, "1", monkeypatch, 5)
    assert steps == _run(make, "0", monkeypatch, 5)
    assert any(s[2] for s in steps) and any(s[5] is not None and s[5][0] == "closed_form" for s in steps)


def test_non_finite_data_and_bad_shapes_are_refused_as_without_the_kernel() -> None:
    f = SafetyFilter(1.0, 0.1, validate=False)
    assert f._kernel is not None
    lie = LieData(np.array([0.5, 0.2]), np.array([0.0, math.inf]), np.eye(2), np.ones(2))
    with pytest.raises(NonFiniteError):
        f.step_lie(0.0, lie, np.zeros(2), screen=0.2)
    long = LieData(np.array([0.5, 0.2]), np.zeros(3), np.eye(2), np.ones(2))  # lf one row too many
    with pytest.raises(ValueError):  # numpy's broadcasting error, never the kernel reading 2 of 3 rows
        f.step_lie(0.0, long, np.zeros(2), screen=0.2)


@pytest.mark.parametrize("alpha", ALPHAS, ids=repr)
def test_predict_gives_the_same_prediction_with_and_without_the_kernel(alpha, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.core.intermittent import predict

    rng = np.random.default_rng(21)
    cases = []
    for _ in range(200):
        m = int(rng.integers(1, 8))
        pts = [(0.01 * (j + 1), _lie(rng, int(rng.integers(0, 12)), m), rng.normal(size=m))
               for j in range(int(rng.integers(0, 6)))]
        cases.append((pts, float(rng.choice([0.0, 0.05, 3.0]))))

    def run(jit: str) -> list:  # type: ignore[no-untyped-def]
        monkeypatch.setenv("ISF_ROBOT_JIT", jit)
        return [predict(pts, alpha, d) for pts, d in cases]

    got, ref = run("1"), run("0")
    assert [repr(p) for p in got] == [repr(p) for p in ref]  # (xi_min as repr: the same float, bit for bit)
    assert any(p.ok for p in ref) and any(not p.ok and p.failing for p in ref)
    bad = [(0.1, LieData(np.array([0.5, 0.2]), np.array([0.0, math.nan]), np.eye(2), np.ones(2), ("a", "b")),
            np.zeros(2))]
    for jit in ("1", "0"):
        monkeypatch.setenv("ISF_ROBOT_JIT", jit)
        with pytest.raises(NonFiniteError):
            predict(bad, alpha, 0.1)


def _few_problems(rng: np.random.Generator, n: int):  # type: ignore[no-untyped-def]
    """Few-row problems with 0, 1, 2 and more active rows, nearly parallel rows and non-finite data."""
    for i in range(n):
        k, m = int(rng.integers(2, 9)), int(rng.integers(1, 8))
        A = rng.normal(size=(k, m)) * 10.0 ** rng.uniform(-3, 3, size=(k, 1))
        lb = rng.normal(size=k) * 10.0 ** rng.uniform(-2, 2)
        u_nom = rng.normal(size=m)
        if i % 7 == 0:
            A[1] = A[0] * (1.0 + 1e-9 * rng.random())  # nearly parallel
        if i % 11 == 0:
            lb[rng.integers(k)] = 0.0
            A[rng.integers(k)] = 0.0  # a zero row
        if i % 97 == 0:
            (A if i % 2 else lb).flat[0] = rng.choice([np.nan, np.inf])
        yield A, lb, u_nom


def _same(a, b) -> bool:  # type: ignore[no-untyped-def]
    if a is None or b is None:
        return a is b
    return a[0].tobytes() == b[0].tobytes() and a[1].tobytes() == b[1].tobytes() and a[2] == b[2]


def test_few_row_kernels_give_project_few_bit_for_bit() -> None:
    from isf_robot.core.fast import few_kernels
    from isf_robot.core.qp_small import project_few

    kernels = few_kernels()
    assert kernels is not None, "numba is installed: the kernels must load"
    active = collections.Counter()
    for A, lb, u_nom in _few_problems(np.random.default_rng(3), 6000):
        ref = project_few(A, lb, u_nom)
        assert _same(project_few(A, lb, u_nom, kernels=kernels), ref)
        active["none" if ref is None else int((ref[1] <= 1e-9).sum())] += 1
    assert min(active["none"], active[0], active[1], active[2]) > 100, active  # every case was met
    # a candidate that fails its confirmation on the rows: the Python path decides (the same answer)
    refuse = (kernels[0], lambda res, u, tol: (False, 0.0))
    for A, lb, u_nom in _few_problems(np.random.default_rng(4), 500):
        assert _same(project_few(A, lb, u_nom, kernels=refuse), project_few(A, lb, u_nom))
