"""The closed forms of the filter QP without bounds (one row; a few rows with one or two active) against known
answers, the KKT conditions and the backends; each as written and compiled."""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core import FilterQP, QPSolver, projection
from isf_robot.core.jit import compiled
from isf_robot.core.projection import FEW_ROWS, REL_TOL


@pytest.fixture(params=["plain", "compiled"], autouse=True)
def way(request):  # type: ignore[no-untyped-def]
    """Every test runs on the functions as written and as compiled (numba; the same source)."""
    _WAY[0] = request.param
    yield request.param


_WAY = ["plain"]


def _answer(name: str, A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, *bounds: np.ndarray):  # type: ignore[no-untyped-def]
    """``(u, A u - lb, min)`` of the projection ``name`` (as the test's way runs it), or ``None`` (no answer)."""
    fn = getattr(projection, name)
    fn = fn if _WAY[0] == "plain" else compiled(fn)
    u, res = np.empty(A.shape[1]), np.empty(A.shape[0])
    code, low = fn(np.ascontiguousarray(A, dtype=float), np.asarray(lb, dtype=float),
                   np.asarray(u_nom, dtype=float), REL_TOL, *bounds, u, res)
    return None if code < 0 else (u, res, low)


def project_few(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray):  # type: ignore[no-untyped-def]
    """``(u, A u - lb, min)`` or ``None`` (no closed-form answer)."""
    return _answer("project_few", A, lb, u_nom)


def project_few_within(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, lo: np.ndarray, hi: np.ndarray):  # type: ignore[no-untyped-def]
    """``(u, A u - lb, min)`` or ``None``: :func:`project_few`'s answer kept only within ``lo <= u <= hi``."""
    return _answer("project_few_within", A, lb, u_nom, lo, hi)


def project_active(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray):  # type: ignore[no-untyped-def]
    """``(u, A u - lb, min)`` or ``None``: the certified active-set iteration."""
    return _answer("project_active", A, lb, u_nom)


def project_row(a: np.ndarray, lb: float, u_nom: np.ndarray, feas_tol: float = 1e-7):  # type: ignore[no-untyped-def]
    fn = projection.project_row if _WAY[0] == "plain" else compiled(projection.project_row)
    u = np.empty(u_nom.shape[0])
    code, slack = fn(a, lb, u_nom, feas_tol, u)
    return code, (u_nom if code == 0 else u), slack


def _kkt(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, u: np.ndarray) -> None:
    """Primal feasibility, stationarity with multipliers >= 0 on the active rows, complementarity."""
    scale = max(1.0, float(np.abs(lb).max()), float(np.abs(u).max()))
    slack = A @ u - lb
    assert slack.min() >= -1e-12 * scale
    act = slack <= 1e-9 * scale
    if not act.any():
        np.testing.assert_array_equal(u, u_nom)
        return
    lam, *_ = np.linalg.lstsq(A[act].T, u - u_nom, rcond=None)
    assert lam.min() >= -1e-12 * max(1.0, float(np.abs(lam).max()))
    np.testing.assert_allclose(A[act].T @ lam, u - u_nom, atol=1e-12 * scale)


def test_known_answers() -> None:
    A = np.array([[1.0, 0.0], [0.0, 1.0]])
    u, res, rmin = project_few(A, np.array([1.0, 1.0]), np.zeros(2))  # a corner: both rows active
    np.testing.assert_allclose(u, [1.0, 1.0], atol=1e-15)
    u, res, rmin = project_few(A, np.array([1.0, -5.0]), np.zeros(2))  # one row active
    np.testing.assert_array_equal(u, [1.0, 0.0])
    np.testing.assert_array_equal(res, [0.0, 5.0])
    assert rmin == 0.0
    u_nom = np.array([3.0, 4.0])
    u, res, rmin = project_few(A, np.array([1.0, 1.0]), u_nom)  # nothing active: u_nom itself (a copy)
    np.testing.assert_array_equal(u, u_nom)
    assert u is not u_nom and rmin == 2.0
    # one row: x + y >= 2 from (0, 0) -> (1, 1); already held -> u_nom; a zero row -> no answer
    code, u, slack = project_row(np.array([1.0, 1.0]), 2.0, np.zeros(2))
    assert code == 1 and slack == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(u, [1.0, 1.0], atol=1e-15)
    code, u, slack = project_row(np.array([1.0, 1.0]), -1.0, np.array([0.5, 0.0]))
    assert code == 0 and slack == 1.5
    assert project_row(np.zeros(2), 1.0, np.zeros(2))[0] == -1
    assert project_row(np.array([1.0, 0.0]), 1.0, np.array([np.inf, 0.0]))[0] == -1
    # x + y >= 2 and x - y >= 0 from (0, 1): the corner (1, 1), multipliers 0.5 and 0.5 (KKT by hand)
    A2 = np.array([[1.0, 1.0], [1.0, -1.0]])
    u, _, _ = project_few(A2, np.array([2.0, 0.0]), np.array([0.0, 1.0]))
    np.testing.assert_allclose(u, [1.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(u - np.array([0.0, 1.0]), A2.T @ np.array([0.5, 0.5]), atol=1e-15)


def test_three_active_rows_infeasible_and_non_finite_go_to_the_backend() -> None:
    eye = np.eye(3)
    assert project_few(eye, np.ones(3), np.zeros(3)) is None  # the solution (1, 1, 1) has 3 active rows
    assert project_few(np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([1.0, 0.0]), np.zeros(2)) is None  # x>=1, x<=0
    # x >= 1 and -x + 1e-9 y >= -1 + 1e-3: both active at (1, 1e6), rows nearly parallel (det 1e-18): left alone
    assert project_few(np.array([[1.0, 0.0], [-1.0, 1e-9]]), np.array([1.0, -1.0 + 1e-3]), np.zeros(2)) is None
    assert project_few(eye[:2], np.array([np.nan, 0.0]), np.zeros(3)) is None
    with np.errstate(invalid="ignore"):
        assert project_few(eye[:2], np.ones(2), np.array([np.inf, 0.0, 0.0])) is None
    solver = QPSolver(few_rows=True)
    r = solver.solve(FilterQP(np.zeros(3), eye, np.ones(3)))
    assert r.status == "optimal" and solver.solves == 0  # (project_active's certified answer: no backend call)
    np.testing.assert_allclose(r.u, np.ones(3), atol=1e-15)
    r = solver.solve(FilterQP(np.zeros(2), np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([1.0, 0.0])))
    assert r.status == "infeasible" and not r.ok  # never presented as a safe answer


@pytest.mark.parametrize("backend", ["daqp", "proxsuite"])
def test_random_two_row_problems_agree_with_the_backends(backend: str) -> None:
    """Every feasible 2-row problem is answered here (at most two rows can be active) and equals the backend's."""
    rng = np.random.default_rng(11)
    ref, ours = QPSolver(backend=backend, closed_form=False), QPSolver(backend=backend, few_rows=True)
    kinds = {0: 0, 1: 0, 2: 0}
    for _ in range(80):
        m = int(rng.integers(2, 8))
        A = rng.normal(size=(2, m)) * rng.choice([1e-2, 1.0, 1e2])
        u_nom = rng.normal(size=m)
        lb = A @ u_nom + rng.normal(size=2) * np.abs(A).max()
        hit = project_few(A, lb, u_nom)
        assert hit is not None
        u, res, rmin = hit
        _kkt(A, lb, u_nom, u)
        np.testing.assert_allclose(res, A @ u - lb, rtol=0, atol=1e-12 * max(1.0, np.abs(lb).max()))
        assert rmin == res.min()
        kinds[int((res <= 1e-9 * max(1.0, np.abs(lb).max())).sum())] += 1
        r = ref.solve(FilterQP(u_nom, A, lb))
        np.testing.assert_allclose(u, r.u, rtol=0, atol=1e-8 * max(1.0, np.abs(r.u).max()))
        mine = ours.solve(FilterQP(u_nom, A, lb))
        assert mine.status == "optimal" and mine.iterations == 0
        np.testing.assert_allclose(mine.u, u, rtol=1e-12, atol=1e-12)
    assert ours.solves == 0 and min(kinds.values()) > 8  # no backend call; every active-set size seen


def test_random_few_row_problems_answered_or_left_to_the_backend() -> None:
    """Up to FEW_ROWS rows: an answer is the backend's (and meets KKT); a problem it leaves has >= 3 active rows."""
    rng = np.random.default_rng(5)
    daqp = QPSolver(closed_form=False)
    answered = left = 0
    for _ in range(200):
        k, m = int(rng.integers(3, FEW_ROWS + 1)), int(rng.integers(2, 8))
        A = rng.normal(size=(k, m))
        u_nom = rng.normal(size=m)
        x = rng.normal(size=m)  # a feasible point: the problem is feasible by construction
        lb = A @ x - np.abs(rng.normal(size=k)) * 0.7
        r = daqp.solve(FilterQP(u_nom, A, lb))
        hit = project_few(A, lb, u_nom)
        if hit is None:
            left += 1
            assert int(r.active.sum()) >= 3
            continue
        answered += 1
        _kkt(A, lb, u_nom, hit[0])
        np.testing.assert_allclose(hit[0], r.u, rtol=0, atol=1e-8 * max(1.0, np.abs(r.u).max()))
    assert answered > 50 and left > 5


def test_random_infeasible_two_row_problems_are_never_answered() -> None:
    rng = np.random.default_rng(2)
    solver = QPSolver()
    for n in range(40):
        m = int(rng.integers(1, 6))
        a = rng.normal(size=m)
        A = np.vstack([a, -a * rng.uniform(0.5, 2.0)])  # a u >= l1 and a u <= l2 (scaled) with l2 < l1
        u_nom = rng.normal(size=m)
        l1 = float(a @ u_nom) + rng.uniform(0.1, 1.0)
        lb = np.array([l1, -(l1 - rng.uniform(0.05, 1.0)) * (A[1, 0] / -a[0])])
        assert project_few(A, lb, u_nom) is None
        if n < 3:  # the backend proves it (slowly: the phase-1 problem)
            r = solver.solve(FilterQP(u_nom, A, lb))
            assert r.status == "infeasible" and not r.ok


def test_off_by_default_and_only_with_the_closed_forms() -> None:
    qp = FilterQP(np.zeros(2), np.eye(2), np.ones(2))
    for solver, backend_calls in ((QPSolver(), 1), (QPSolver(few_rows=True, closed_form=False), 1),
                                  (QPSolver(few_rows=True), 0)):
        r = solver.solve(qp)
        assert r.status == "optimal" and solver.solves == backend_calls
        np.testing.assert_allclose(r.u, [1.0, 1.0], atol=1e-12)


def test_bounded_few_rows_are_answered_only_within_the_bounds() -> None:
    """With input bounds: the rows' closed form is kept exactly when it satisfies every bound (then it is the bounded
    optimum: the backend's, KKT with no bound active); a problem whose optimum has a bound active goes to the backend."""
    from isf_robot.core.qp_check import NO_BOUND

    rng = np.random.default_rng(11)
    daqp, ours = QPSolver(closed_form=False), QPSolver(few_rows=True)
    seen = {"within": 0, "bound binds": 0}
    for n in range(300):
        k, m = int(rng.integers(1, FEW_ROWS + 1)), int(rng.integers(2, 8))
        A = rng.normal(size=(k, m))
        u_nom = rng.normal(size=m) * 2.0
        x = rng.uniform(-0.5, 0.5, m)  # a feasible point within the bounds: the problem is feasible
        lb = A @ x - np.abs(rng.normal(size=k)) * 0.7
        width = rng.uniform(0.6, 4.0)
        lo, hi = [(np.full(m, -width), np.full(m, width)), (np.full(m, -width), NO_BOUND),
                  (NO_BOUND, np.full(m, width))][n % 3]
        qp = FilterQP(u_nom, A, lb, None if lo is NO_BOUND else lo, None if hi is NO_BOUND else hi)
        r = daqp.solve(qp)
        hit = project_few_within(A, lb, u_nom, lo, hi)
        binds = bool((lo.size and (r.u <= lo + 1e-9).any()) or (hi.size and (r.u >= hi - 1e-9).any()))
        mine = ours.solve(qp)
        np.testing.assert_allclose(mine.u, r.u, rtol=0, atol=1e-8 * max(1.0, np.abs(r.u).max()))
        if hit is None:  # (a bound binds, or the rows' closed forms had no certified answer)
            seen["bound binds"] += binds
            continue
        seen["within"] += 1
        assert not binds
        assert (lo.size == 0 or (hit[0] >= lo).all()) and (hi.size == 0 or (hit[0] <= hi).all())
        _kkt(A, lb, u_nom, hit[0])
        np.testing.assert_allclose(hit[0], r.u, rtol=0, atol=1e-8 * max(1.0, np.abs(r.u).max()))
        np.testing.assert_array_equal(mine.u, hit[0])  # (the solver took the closed form)
    assert min(seen.values()) > 10, seen


def test_bounded_few_rows_only_with_few_rows_and_within_the_bounds() -> None:
    A, lb = np.eye(2), np.ones(2)
    for hi, few, backend_calls in ((2.0, False, 1), (2.0, True, 0), (0.5, True, 1)):
        solver = QPSolver(few_rows=few)
        qp = FilterQP(np.zeros(2), A, lb, u_max=np.full(2, hi))
        r = solver.solve(qp)
        assert solver.solves == backend_calls
        if hi > 1.0:
            assert r.status == "optimal" and r.active.all()
            np.testing.assert_allclose(r.u, [1.0, 1.0], atol=1e-12)
        else:  # (rows u >= 1 against u <= 0.5: infeasible, the backend says so)
            assert r.status == "infeasible"


def test_active_set_iteration_known_answers_and_refusals() -> None:
    eye = np.eye(3)
    u, res, low = project_active(eye, np.ones(3), np.zeros(3))  # three rows active: (1, 1, 1)
    np.testing.assert_array_equal(u, np.ones(3))
    assert low == 0.0 and np.array_equal(res, np.zeros(3))
    u, _, _ = project_active(eye, -np.ones(3), np.zeros(3))  # none violated: u_nom
    np.testing.assert_array_equal(u, np.zeros(3))
    # a row that must be dropped: x + y >= 2 first (most violated), then x >= 1.5 binds and the first row goes slack
    A = np.array([[1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])
    u, res, _ = project_active(A, np.array([2.0, 1.5, 0.7]), np.zeros(2))
    np.testing.assert_allclose(u, [1.5, 0.7], atol=1e-15)
    _kkt(A, np.array([2.0, 1.5, 0.7]), np.zeros(2), u)
    assert project_active(np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([1.0, 0.0]), np.zeros(2)) is None  # infeasible
    # three rows through one point of the plane (dependent): the answer (1, 1) on two of them, certified
    hit = project_active(np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]), np.array([1.0, 1.0, 2.0]), np.zeros(2))
    assert hit is not None
    np.testing.assert_allclose(hit[0], [1.0, 1.0], atol=1e-15)
    assert project_active(eye[:2], np.array([np.nan, 0.0]), np.zeros(3)) is None
    # a violated row so small that |a|^2 underflows: never added, never answered (found by test_filter_commands)
    assert project_active(np.array([[3.5e-156, 8.2e-156]]), np.array([1.0]), np.zeros(2)) is None


def test_random_active_sets_are_the_backends_or_left_to_it() -> None:
    """Up to FEW_ROWS rows, any number active: an answer meets the KKT conditions and equals daqp's; infeasible problems
    are never answered."""
    rng = np.random.default_rng(12)
    daqp = QPSolver(closed_form=False)
    sizes: dict[int, int] = {}
    left = 0
    for n in range(300):
        k, m = int(rng.integers(1, FEW_ROWS + 1)), int(rng.integers(2, 8))
        A = rng.normal(size=(k, m)) * rng.choice([1e-2, 1.0, 1e2])
        if k > 1 and n % 10 == 0:
            A[1] = A[0] * 2.0  # (parallel rows)
        u_nom = rng.normal(size=m)
        x = rng.normal(size=m)  # a feasible point: the problem is feasible by construction
        lb = A @ x - np.abs(rng.normal(size=k)) * np.abs(A).max() * rng.choice([0.0, 0.3])
        hit = project_active(A, lb, u_nom)
        if hit is None:
            left += 1
            continue
        u = hit[0]
        scale = max(1.0, float(np.abs(lb).max()), float(np.abs(u).max()))
        assert (A @ u - lb).min() >= -1e-12 * scale
        r = daqp.solve(FilterQP(u_nom, A, lb))
        np.testing.assert_allclose(u, r.u, rtol=0, atol=1e-8 * max(1.0, np.abs(r.u).max()))
        act = int((hit[1] <= 1e-9 * scale).sum())
        if act <= m and n % 10:  # (independent active rows: their least-squares multipliers are the multipliers)
            _kkt(A, lb, u_nom, u)
        sizes[act] = sizes.get(act, 0) + 1
    assert sum(v for a, v in sizes.items() if a >= 3) > 30 and left < 60, (sizes, left)
    for _ in range(40):  # infeasible: a u >= l1 and a u <= l2 < l1 among other rows
        m = int(rng.integers(2, 6))
        a = rng.normal(size=m)
        A = np.vstack([a, -a, rng.normal(size=(int(rng.integers(0, 4)), m))])
        u_nom = rng.normal(size=m)
        l1 = float(a @ u_nom) + rng.uniform(0.1, 1.0)
        lb = np.concatenate(([l1, -(l1 - rng.uniform(0.05, 1.0))], np.full(A.shape[0] - 2, -1e3)))
        assert project_active(A, lb, u_nom) is None


def test_within_bounds_known_answers() -> None:
    from isf_robot.core.qp_check import NO_BOUND

    fn = projection.within_bounds if _WAY[0] == "plain" else compiled(projection.within_bounds)
    lo, hi = np.array([-1.0, -2.0]), np.array([1.0, 2.0])
    assert fn(np.array([1.0, -2.0]), lo, hi)  # (on the bounds: within)
    assert not fn(np.array([1.0 + 1e-15, 0.0]), lo, hi) and not fn(np.array([0.0, -2.5]), lo, hi)
    assert fn(np.array([5.0, -5.0]), NO_BOUND, NO_BOUND)
    assert fn(np.array([5.0, 0.0]), lo, NO_BOUND) and not fn(np.array([5.0, 0.0]), NO_BOUND, hi)
    assert not fn(np.array([np.nan, 0.0]), lo, hi)
    assert not fn(np.array([0.0]), lo, hi) and not fn(np.array([0.0, 0.0, 0.0]), lo, NO_BOUND)  # (not u's length)


def test_bounds_not_of_the_commands_length_are_refused_on_every_path() -> None:
    """A bound of another length than the command is a shape error, whichever path would answer the problem."""
    from isf_robot.core import SafetyFilter, ShapeError
    from isf_robot.core.system import LieData

    qp = FilterQP._of(np.zeros(2), np.eye(2), np.ones(2), np.full(3, -5.0), np.full(3, 5.0))
    for solver in (QPSolver(few_rows=True), QPSolver()):
        with pytest.raises(ShapeError, match="u_min has shape"):
            solver.solve(qp)
    lie = LieData(h=np.array([0.01]), lf=np.array([-1.0]), lg=np.array([[1.0, 0.5]]), grad_norm=np.array([1.0]))
    for few in (True, False):
        filt = SafetyFilter(alpha=1.0, u_min=np.full(3, -5.0), u_max=np.full(3, 5.0), solver=QPSolver(few_rows=few))
        with pytest.raises(ShapeError):
            filt.step_lie(0.0, lie, np.zeros(2))
