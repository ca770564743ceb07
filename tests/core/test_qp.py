import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from isf_robot.core import (
    FilterQP,
    InfeasibleFilterError,
    IsfWarning,
    LieData,
    Linear,
    QPSolver,
    SafetyFilter,
    build_filter_qp,
    project_halfspace,
)

vec = st.lists(st.floats(-5, 5, allow_nan=False), min_size=3, max_size=3)


@settings(max_examples=60, deadline=None)
@given(u_nom=vec, a=vec, lb=st.floats(-5, 5))
def test_qp_equals_closed_form_projection(u_nom, a, lb):
    u_nom, a = np.array(u_nom), np.array(a)
    if np.linalg.norm(a) < 1e-2:
        a = a + np.array([0.5, 0.0, 0.0])
    qp = FilterQP(u_nom, a[None, :], np.array([lb]))
    res = QPSolver(closed_form=False).solve(qp)
    assert res.status == "optimal"
    expected = project_halfspace(u_nom, a, lb)
    np.testing.assert_allclose(res.u, expected, atol=1e-8, rtol=0)


def test_projection_known_answer():
    # min |u - (1, 0)|^2 s.t. u_x >= 3  ->  (3, 0)
    np.testing.assert_allclose(project_halfspace(np.array([1.0, 0.0]), np.array([1.0, 0.0]), 3.0), [3.0, 0.0])
    # already feasible: untouched
    np.testing.assert_allclose(project_halfspace(np.array([4.0, 2.0]), np.array([1.0, 0.0]), 3.0), [4.0, 2.0])
    # slanted: a = (1, 1), lb = 2, u_nom = 0 -> (1, 1)
    np.testing.assert_allclose(project_halfspace(np.zeros(2), np.array([1.0, 1.0]), 2.0), [1.0, 1.0])


def test_closed_form_path_used_and_agrees_with_proxqp_and_qpsolvers():
    rng = np.random.default_rng(1)
    for _ in range(20):
        u_nom = rng.normal(size=4)
        a = rng.normal(size=(1, 4))
        lb = rng.normal(size=1) + 1.0
        qp = FilterQP(u_nom, a, lb)
        r_cf = QPSolver().solve(qp)
        r_px = QPSolver(closed_form=False).solve(qp)
        r_qs = QPSolver(closed_form=False, backend="qpsolvers").solve(qp)
        assert r_cf.status == "closed_form"
        np.testing.assert_allclose(r_px.u, r_cf.u, atol=1e-8)
        np.testing.assert_allclose(r_qs.u, r_cf.u, atol=1e-7)


def test_box_bounds_known_answer_and_active_set():
    # two rows u0 >= 1, u1 >= 1 and box [-0.5, 2]: answer (1, 1), both rows active
    qp = FilterQP(np.zeros(2), np.eye(2), np.ones(2), u_min=-0.5 * np.ones(2), u_max=2 * np.ones(2))
    res = QPSolver().solve(qp)
    np.testing.assert_allclose(res.u, [1.0, 1.0], atol=1e-8)
    assert res.active.tolist() == [True, True]
    # nominal above the row bound: row inactive, bound clips
    qp = FilterQP(np.array([3.0, 1.5]), np.eye(2), np.ones(2), u_max=2 * np.ones(2))
    res = QPSolver().solve(qp)
    np.testing.assert_allclose(res.u, [2.0, 1.5], atol=1e-8)
    assert res.active.tolist() == [False, False]


def test_infeasible_qp_is_reported_not_returned_as_safe():
    qp = FilterQP(np.zeros(2), np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([1.0, 1.0]))
    res = QPSolver().solve(qp)
    assert res.status == "infeasible"
    assert not res.ok
    assert res.max_violation > 0.5


def _lie(h, lg, lf=None):
    h = np.asarray(h, float)
    lg = np.asarray(lg, float)
    return LieData(h, np.zeros_like(h) if lf is None else np.asarray(lf, float), lg, np.linalg.norm(lg, axis=1), tuple(f"b{i}" for i in range(len(h))))


def test_infeasible_filter_raises_with_evidence():
    # rows: u0 >= 1 (h=-1 with alpha gain 1 -> rhs = 1) and -u0 >= 1: impossible
    f = SafetyFilter(Linear(1.0))
    lie = _lie([-1.0, -1.0], [[1.0, 0.0], [-1.0, 0.0]])
    with pytest.raises(InfeasibleFilterError) as info:
        f.step_lie(0.5, lie, np.zeros(2), x=np.array([7.0, 8.0]))
    err = info.value
    assert err.qp is not None and err.qp.k == 2
    np.testing.assert_array_equal(err.barrier_values, [-1.0, -1.0])
    np.testing.assert_array_equal(err.state, [7.0, 8.0])
    assert err.t == 0.5


def test_infeasible_filter_fallback_is_recorded_and_warned():
    f = SafetyFilter(Linear(1.0), on_infeasible="fallback", fallback=lambda t, x, lie, res: np.zeros(2))
    lie = _lie([-1.0, -1.0], [[1.0, 0.0], [-1.0, 0.0]])
    with pytest.warns(IsfWarning):
        step = f.step_lie(0.0, lie, np.array([0.3, 0.0]))
    assert step.fallback
    assert step.qp.status == "fallback"
    np.testing.assert_array_equal(step.u, [0.0, 0.0])


def test_build_filter_qp_rows_match_robust_condition():
    lie = _lie([0.5], [[2.0, 0.0]], lf=[0.1])
    qp = build_filter_qp(np.zeros(2), lie.lf, lie.lg, lie.grad_norm, np.array([-0.5]), d_bar=0.2)
    # row: lf + lg u - |grad| d_bar >= -alpha(h)  <=>  lg u >= -alpha(h) - lf + |grad| d_bar
    np.testing.assert_allclose(qp.lb, [-0.5 - 0.1 + 2.0 * 0.2])
    assert qp.max_violation(np.array([1.0, 0.0])) == 0.0


def test_reused_warm_started_workspace_matches_fresh_solves():
    rng = np.random.default_rng(7)
    reused = QPSolver()
    for _ in range(50):
        k, m = int(rng.integers(2, 6)), 4
        A = rng.normal(size=(k, m))
        lb = A @ rng.normal(size=m) - rng.uniform(0, 0.5, k)  # feasible by construction
        u_nom = 2 * rng.normal(size=m)
        bounds = rng.random() < 0.5
        qp = FilterQP(u_nom, A, lb, u_min=-10 * np.ones(m) if bounds else None, u_max=10 * np.ones(m) if bounds else None)
        a = reused.solve(qp)
        b = QPSolver().solve(qp)
        assert a.status == b.status == "optimal"
        np.testing.assert_allclose(a.u, b.u, atol=1e-7)
        assert qp.max_violation(a.u) <= 1e-7
        # KKT: u - u_nom = A_act^T lam with lam >= 0 (no bound active at this scale)
        act = a.active
        if act.any():
            lam, *_ = np.linalg.lstsq(A[act].T, a.u - u_nom, rcond=None)
            np.testing.assert_allclose(A[act].T @ lam, a.u - u_nom, atol=1e-6)
            assert np.all(lam >= -1e-6)
        else:
            np.testing.assert_allclose(a.u, u_nom, atol=1e-8)


def test_badly_scaled_feasible_rows_are_solved_exactly_not_called_infeasible():
    # |a| ~ 1e-3 makes the optimum ~1e4 away: ProxQP stalls, the penalised phase-1 answer is
    # slightly infeasible; the active-set step must recover the exact projection.
    rng = np.random.default_rng(5)
    solver = QPSolver(closed_form=False)
    for _ in range(300):
        scale = 10 ** rng.uniform(-4, 1)
        u_nom = rng.normal(size=3) * scale
        a = rng.normal(size=3) * 10 ** rng.uniform(-3, 1)
        lb = float(rng.normal() * scale)
        exact = project_halfspace(u_nom, a, lb)
        res = solver.solve(FilterQP(u_nom, a[None, :], np.array([lb])))
        assert res.status == "optimal"
        np.testing.assert_allclose(res.u, exact, rtol=1e-8, atol=1e-8 * max(1.0, np.abs(exact).max()))


def test_least_violation_known_answers_and_scale_free_rows() -> None:
    """Two-stage least violation: a feasible problem's own optimum; an infeasible one's violations
    measured per row in normalised units (a row's scale does not move the answer)."""
    s = QPSolver()
    # feasible: the QP's optimum, no violation
    feas = FilterQP(np.array([0.0, 0.0]), np.array([[1.0, 0.0], [0.0, 1.0]]), np.array([1.0, -1.0]))
    viol, u = s.least_violation(feas)
    assert viol <= 1e-9 and u == pytest.approx([1.0, 0.0], abs=1e-9)
    # u >= 1 and u <= -1 on one axis, the first row 1000x larger: the middle, u = 0, either way
    for big in (1.0, 1e3, 1e-3):
        qp = FilterQP(np.array([0.7, 2.0]), np.array([[big, 0.0], [-1.0, 0.0]]), np.array([big, 1.0]))
        viol, u = s.least_violation(qp)
        assert u[0] == pytest.approx(0.0, abs=1e-7)
        assert u[1] == pytest.approx(2.0, abs=1e-7)  # the free axis keeps the nominal (stage 2)
        assert viol == pytest.approx(max(big, 1.0), rel=1e-6)
    # with input bounds that cut the middle off: the bound's side
    qp = FilterQP(np.zeros(1), np.array([[1.0], [-1.0]]), np.array([1.0, 1.0]), np.array([0.5]), np.array([2.0]))
    viol, u = s.least_violation(qp)
    assert u == pytest.approx([0.5], abs=1e-9) and viol == pytest.approx(1.5, rel=1e-9)


def test_least_violation_matches_a_brute_force_minimum() -> None:
    """Stage 1 against a dense grid: the sum of squared normalised violations is the least (random 2-D cases)."""
    rng = np.random.default_rng(5)
    s = QPSolver()
    g = np.linspace(-3.0, 3.0, 601)
    U = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    for _ in range(5):
        A = rng.normal(size=(4, 2)) * rng.choice([1e-2, 1.0, 1e2], size=(4, 1))
        lb = A @ rng.normal(size=2) + np.abs(rng.normal(size=4)) * np.linalg.norm(A, axis=1)
        qp = FilterQP(rng.normal(size=2), A, lb, np.full(2, -3.0), np.full(2, 3.0))
        _, u = s.least_violation(qp)
        n = np.linalg.norm(A, axis=1)

        def cost(v: np.ndarray) -> np.ndarray:
            return (np.maximum(lb / n - (v @ A.T) / n, 0.0) ** 2).sum(axis=-1)

        assert cost(u) <= cost(U).min() + 1e-9


def test_proxqp_work_is_bounded_on_vanishing_rows() -> None:
    """Rows of scale 1e-12 (a gradient that all but vanishes) with the bounds in play: ProxQP gives up within its
    iteration limits (its default inner limit let it run 4e5 iterations, over a second, per solve), and the
    filter's answer is the documented one: a command within the bounds meeting every row, or a marked fallback."""
    rng = np.random.default_rng(0)
    lo, hi = -np.full(3, 2.0), np.full(3, 2.0)
    solver = QPSolver(backend="proxsuite", closed_form=False)
    for _ in range(6):
        lie = LieData(rng.uniform(0, 1, 3), rng.normal(size=3), rng.normal(size=(3, 3)) * 1e-12,
                      np.abs(rng.normal(size=3)))
        f = SafetyFilter(Linear(2.0), 0.05, u_min=lo, u_max=hi, solver=solver, on_infeasible="fallback")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IsfWarning)
            step = f.step_lie(0.0, lie, rng.normal(size=3) * 3.0)
        assert step.qp is not None and step.qp.iterations <= solver.max_iter * 60
        u = step.u
        assert np.all(np.isfinite(u)) and np.all(u >= lo - 1e-9) and np.all(u <= hi + 1e-9)
        if not step.fallback:
            slack = lie.lf + lie.lg @ u - lie.grad_norm * 0.05 + 2.0 * lie.h
            assert np.all(slack >= -1e-9)
