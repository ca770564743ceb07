"""Every command a filter returns is finite and satisfies every constraint it was given (input
bounds, and the robust barrier condition of every row), or the documented infeasibility policy
applies: raise, or a marked fallback. Property tests over random rows, degenerate and
huge/tiny scales, for every solver backend and both filters, in both modes."""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from isf_robot.core import (
    InfeasibleFilterError,
    IntermittentSafetyFilter,
    IsfWarning,
    LieData,
    Linear,
    QPSolver,
    SafetyFilter,
    SolverError,
)
from isf_robot.core.qp_solver import BACKENDS

SCALES = st.sampled_from([1e-155, 1e-12, 1e-6, 1.0, 1e3, 1e9])


def _lie(rng: np.random.Generator, k: int, m: int, scale: float, degenerate: bool) -> LieData:
    lg = rng.normal(size=(k, m)) * scale
    if degenerate:
        lg[0] = 0.0 if k == 1 else lg[1]  # a zero row, or two equal rows
    h = rng.uniform(0.0, 1.0, size=k)
    lf = rng.normal(size=k)
    return LieData(h, lf, lg, np.abs(rng.normal(size=k)))


def _check(step, lie: LieData, alpha: Linear, d_bar: float, lo: np.ndarray, hi: np.ndarray,
           rows_enforced: bool) -> None:  # type: ignore[no-untyped-def]
    u = step.u
    assert np.all(np.isfinite(u)), u
    if step.fallback:
        return  # marked: a fallback is never presented as a safe answer
    assert np.all(u >= lo - 1e-9) and np.all(u <= hi + 1e-9), (u, lo, hi)
    if rows_enforced:
        slack = lie.lf + lie.lg @ u - lie.grad_norm * d_bar + alpha(lie.h)
        # rounding scale of each row over the input box (|u| <= max|hi|), not at u alone: a command near
        # zero on a row of size 1e9 carries the solver's relative tolerance times the row, not times |u|
        u_range = max(float(np.abs(u).max()), float(np.abs(hi).max()))
        scale = 1.0 + np.abs(lie.lg).sum(axis=1) * u_range + np.abs(lie.lf) + np.abs(alpha(lie.h))
        assert np.all(slack >= -1e-6 * scale), slack


@settings(max_examples=200, deadline=None, derandomize=True)  # (the same 200 cases every run)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 5), m=st.integers(1, 4), scale=SCALES,
       degenerate=st.booleans(), backend=st.sampled_from(BACKENDS), policy=st.sampled_from(["raise", "fallback"]),
       few=st.booleans())
def test_every_returned_command_is_finite_and_feasible(seed: int, k: int, m: int, scale: float, degenerate: bool,
                                                       backend: str, policy: str, few: bool) -> None:
    rng = np.random.default_rng(seed)
    lie = _lie(rng, k, m, scale, degenerate)
    lo, hi = -np.full(m, 2.0), np.full(m, 2.0)
    alpha, d_bar = Linear(2.0), 0.05
    u_nom = rng.normal(size=m) * 3.0  # often outside the bounds
    filters = [
        SafetyFilter(alpha, d_bar, u_min=lo, u_max=hi, solver=QPSolver(backend=backend, few_rows=few),
                     on_infeasible=policy),
        IntermittentSafetyFilter(alpha, 0.1, 0.05, d_bar, u_min=lo, u_max=hi,
                                 solver=QPSolver(backend=backend, few_rows=few), on_infeasible=policy),
    ]
    for f in filters:
        for t in (0.0, 0.01):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", IsfWarning)
                try:
                    step = f.step_lie(t, lie, u_nom)
                except (InfeasibleFilterError, SolverError):
                    assert policy == "raise"  # loud: the documented policy, never a silent command
                    continue
            # the standard filter and an "on" intermittent filter enforce the robust rows; an "off"
            # one passes u_nom (whose rows hold: it is off) or its bounded projection
            _check(step, lie, alpha, d_bar, lo, hi, rows_enforced=isinstance(f, SafetyFilter) or step.on)


def test_off_mode_respects_the_input_bounds() -> None:
    lie = LieData(np.array([1.0]), np.array([0.0]), np.array([[1.0, 0.0]]), np.array([1.0]))
    f = IntermittentSafetyFilter(Linear(1.0), 0.1, 0.05, u_min=[-1.0, -1.0], u_max=[1.0, 1.0])
    step = f.step_lie(0.0, lie, np.array([5.0, -3.0]))
    assert not step.on  # far from the obstacle: stays off
    np.testing.assert_allclose(step.u, [1.0, -1.0], atol=1e-9)  # the nearest command within the bounds
    inside = f.step_lie(0.01, lie, np.array([0.5, 0.2]))
    assert not inside.on and inside.qp is None and np.array_equal(inside.u, [0.5, 0.2])


def test_bounded_closed_steps_give_the_backends_commands() -> None:
    """With input bounds and ``few_rows``, the closed steps answer (within the bounds) what daqp answers."""
    rng = np.random.default_rng(4)
    alpha, d_bar = Linear(2.0), 0.05
    closed = backend = 0
    for n in range(150):
        k, m = int(rng.integers(1, 12)), int(rng.integers(2, 7))
        lie = _lie(rng, k, m, 1.0, False)
        lo, hi = -np.full(m, 2.5), np.full(m, 2.5)
        u_nom = rng.normal(size=m) * 1.5
        make = (lambda s: SafetyFilter(alpha, d_bar, u_min=lo, u_max=hi, solver=s, on_infeasible="fallback",
                                       screen=0.5)) if n % 2 else (
            lambda s: IntermittentSafetyFilter(alpha, 0.1, 0.05, d_bar, u_min=lo, u_max=hi, solver=s,
                                               on_infeasible="fallback", screen=0.5))
        fast, slow = make(QPSolver(few_rows=True)), make(QPSolver())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IsfWarning)
            a, b = fast.step_lie(0.0, lie, u_nom), slow.step_lie(0.0, lie, u_nom)
        assert a.on == b.on and a.fallback == b.fallback
        np.testing.assert_allclose(a.u, b.u, rtol=0, atol=1e-9 * max(1.0, float(np.abs(b.u).max())))
        if b.qp is not None and b.qp.status == "optimal":
            closed += fast.solver.solves < slow.solver.solves
            backend += fast.solver.solves == slow.solver.solves
    assert closed > 20 and backend > 5, (closed, backend)
