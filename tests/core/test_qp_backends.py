"""QP backends (daqp default, ProxQP direct, ProxQP through qpsolvers): same answers, every answer checked."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from isf_robot.core import ConfigError, FilterQP, QPSolver, SolverError, project_halfspace
from isf_robot.core.qp_solver import BACKENDS


def _kkt_ok(qp: FilterQP, u: np.ndarray, tol: float = 1e-7) -> bool:
    """Stationarity with non-negative multipliers on the active rows (no bounds)."""
    slack = qp.A @ u - qp.lb
    if slack.min() < -tol:
        return False
    act = slack <= 1e-6
    if not act.any():
        return bool(np.allclose(u, qp.u_nom, atol=tol))
    lam, *_ = np.linalg.lstsq(qp.A[act].T, u - qp.u_nom, rcond=None)
    return bool(lam.min() >= -1e-6 and np.allclose(qp.A[act].T @ lam, u - qp.u_nom, atol=1e-6))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), m=st.integers(2, 7), k=st.integers(2, 8),
       scale=st.sampled_from([1e-3, 1.0, 1e3]))
def test_backends_agree_and_satisfy_kkt(seed: int, m: int, k: int, scale: float) -> None:
    rng = np.random.default_rng(seed)
    u_nom = rng.normal(size=m)
    A = scale * rng.normal(size=(k, m))
    x0 = rng.normal(size=m)  # a feasible point by construction
    lb = A @ x0 - rng.uniform(0.0, 1.0, k) * scale
    qp = FilterQP(u_nom, A, lb)
    results = {b: QPSolver(backend=b, closed_form=False).solve(qp) for b in BACKENDS}
    for b, r in results.items():
        assert r.status == "optimal", b
        assert np.isfinite(r.u).all() and qp.max_violation(r.u) <= 1e-7 * max(1.0, abs(lb).max())
    np.testing.assert_allclose(results["daqp"].u, results["proxsuite"].u, atol=1e-6 * max(1.0, 1 / scale))
    assert _kkt_ok(qp, results["daqp"].u, tol=1e-6 * max(1.0, 1 / scale))


@pytest.mark.parametrize("backend", BACKENDS)
def test_infeasible_problem_is_reported_not_returned_as_safe(backend: str) -> None:
    a = np.array([[1.0, 0.0], [-1.0, 0.0]])
    qp = FilterQP(np.zeros(2), a, np.array([1.0, 1.0]))  # u0 >= 1 and u0 <= -1
    r = QPSolver(backend=backend).solve(qp)
    assert r.status == "infeasible" and not r.ok and r.max_violation > 0.5


@pytest.mark.parametrize("backend", BACKENDS)
def test_bounds_are_respected(backend: str) -> None:
    qp = FilterQP(np.zeros(2), np.eye(2), np.ones(2), u_min=-0.5 * np.ones(2), u_max=2 * np.ones(2))
    r = QPSolver(backend=backend).solve(qp)
    np.testing.assert_allclose(r.u, [1.0, 1.0], atol=1e-8)
    assert r.active.all()


def test_tiny_row_never_gives_a_non_finite_command() -> None:
    # Lg h about 1e-155: the closed-form projection overflows; the answer must not be inf/nan
    qp = FilterQP(np.array([0.1, -0.2]), np.array([[1e-155, 0.0]]), np.array([1.0]))
    try:
        r = QPSolver().solve(qp)
    except SolverError:
        return
    assert r.status != "closed_form"
    assert r.status == "infeasible" or (np.isfinite(r.u).all() and qp.max_violation(r.u) <= 1e-7)


def test_solve_time_covers_the_whole_solve() -> None:
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 5))
    qp = FilterQP(rng.normal(size=5), A, A @ rng.normal(size=5) - 0.1)
    s = QPSolver(backend="proxsuite", closed_form=False)
    import time

    t0 = time.perf_counter()
    r = s.solve(qp)
    outer = time.perf_counter() - t0
    assert 0.0 < r.solve_time_s <= outer


def test_unknown_backend_lists_the_valid_ones() -> None:
    with pytest.raises(ConfigError, match="daqp, proxsuite, qpsolvers"):
        QPSolver(backend="osqp")


# Found by hypothesis in test_qp_equals_closed_form_projection: ProxQP alone stopped 1.4e-5 away
# from the optimum on this nearly degenerate row while reporting success; QPSolver's active-set
# polish (checked against the KKT conditions) makes the answer exact.
def test_proxqp_matches_projection_on_a_nearly_degenerate_row():
    u_nom = np.array([0.0, 0.0, 0.00390625])
    a = np.array([0.5, 0.0, 0.001953125])
    res = QPSolver(backend="proxsuite", closed_form=False).solve(FilterQP(u_nom, a[None, :], np.array([0.0])))
    np.testing.assert_allclose(res.u, project_halfspace(u_nom, a, 0.0), atol=1e-8, rtol=0)
    raw = QPSolver(backend="proxsuite", closed_form=False, polish=False).solve(FilterQP(u_nom, a[None, :], np.array([0.0])))
    assert raw.status == "optimal"  # the unpolished answer is what the polish exists for


def test_answer_violation_known_answers() -> None:
    """The check's two figures: the violation in the constraints' units, the distance relative to the problem."""
    from isf_robot.core.qp_check import NO_BOUND, answer_violation

    A = np.array([[3.0, 4.0], [0.0, 0.0], [1.0, 0.0]])
    u = np.array([0.5, -0.2])
    # row 0 violated by 1 (distance 1/5), the zero row by 0.3 (as it is), row 2 holds; no bounds; |u|, |u_nom| < 1
    assert answer_violation(A, np.array([-1.0, -0.3, 2.0]), u, np.zeros(2), NO_BOUND, NO_BOUND) == (1.0, 0.3)
    # every row holds: 0, 0
    assert answer_violation(A, np.array([0.0, 1.0, 2.0]), u, np.zeros(2), NO_BOUND, NO_BOUND) == (0.0, 0.0)
    # a bound violated by 0.7, the distance divided by max(1, |u|, |u_nom|) = 4
    v, d = answer_violation(A, np.ones(3), u, np.array([0.0, -4.0]), np.array([1.2, -1.0]), NO_BOUND)
    assert v == pytest.approx(0.7) and d == pytest.approx(0.7 / 4.0)
    v, d = answer_violation(A, np.ones(3), u, np.zeros(2), NO_BOUND, np.array([0.0, 0.0]))
    assert v == 0.5 and d == 0.5
    # not finite: never feasible
    for bad in (np.array([np.nan, 0.0]), np.array([np.inf, 0.0]), np.array([1e308, 1e308])):
        v, d = answer_violation(A, np.ones(3), bad, np.zeros(2), NO_BOUND, NO_BOUND)
        assert v != v and d == np.inf
    v, d = answer_violation(A, np.array([1.0, np.nan, 1.0]), u, np.zeros(2), NO_BOUND, NO_BOUND)
    assert v != v and d == np.inf
    qp = FilterQP(np.zeros(2), A, np.zeros(3))
    assert qp.max_violation(np.array([np.nan, 0.0])) != qp.max_violation(np.array([np.nan, 0.0]))


@pytest.mark.filterwarnings("ignore:invalid value encountered")
@pytest.mark.parametrize("how", ["row", "bound", "nan", "inf"])
def test_a_backend_answer_that_violates_the_constraints_is_never_returned(how: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    A = np.array([[1.0, 2.0], [0.0, 1.0]])
    qp = FilterQP(np.zeros(2), A, np.array([1.0, -5.0]), np.array([-3.0, -3.0]), np.array([3.0, 3.0]))
    s = QPSolver()
    good = s.solve(qp)
    assert good.status == "optimal" and good.max_violation <= 1e-12
    bad = {"row": good.u - 1e-3 * A[0], "bound": np.array([3.5, 0.0]), "nan": np.array([np.nan, 1.0]),
           "inf": np.array([np.inf, 1.0])}[how]
    monkeypatch.setattr(s, "_solve_daqp", lambda qp: (bad.copy(), 1, "solved"))
    with pytest.raises(SolverError, match="non-finite" if how in ("nan", "inf") else "violating the constraints"):
        s.solve(qp)
    # rounding far below feas_tol (relative to the problem's size) is accepted, and reported
    close = good.u - 1e-12 * A[0]
    monkeypatch.setattr(s, "_solve_daqp", lambda qp: (close.copy(), 1, "solved"))
    r = s.solve(qp)
    assert r.status == "optimal" and r.max_violation == pytest.approx(5e-12, rel=1e-3)
