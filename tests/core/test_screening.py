"""Row screening in the core filters and switch events of the standard filter."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import ConfigError, CustomClassK, IntermittentSafetyFilter, LieData, Power, QPSolver, SafetyFilter
from isf_robot.core.qp import FilterQP


def _random_lie(rng: np.random.Generator, k: int, m: int) -> LieData:
    h = rng.uniform(0.0, 0.5, k)
    lg = rng.normal(size=(k, m))
    return LieData(h, rng.normal(scale=0.2, size=k), lg, np.linalg.norm(lg, axis=1),
                   tuple(f"b{i}" for i in range(k)))


def _walk_same_steps(short, general, seed: int) -> None:  # type: ignore[no-untyped-def]
    """600 steps of a slowly moving random state (the filter switches on and off and ramps): the closed
    forms (``short``) and the QP backend (``general``) must give every step's command to 1e-9 (the
    backend's own accuracy), the same mode and switch events, and every robust row held."""
    rng = np.random.default_rng(seed)
    lie = _random_lie(rng, 6, 8)
    for i in range(600):
        h = np.clip(lie.h + rng.normal(scale=0.02, size=6), -0.05, 0.6)
        lie = LieData(h, lie.lf + rng.normal(scale=0.05, size=6), lie.lg + rng.normal(scale=0.05, size=(6, 8)),
                      lie.grad_norm, lie.names)
        u_nom = rng.normal(size=8)
        a, b = short.step_lie(0.01 * i, lie, u_nom), general.step_lie(0.01 * i, lie, u_nom)
        np.testing.assert_allclose(a.u, b.u, rtol=1e-9, atol=1e-9)
        assert a.on == b.on and str(a.event) == str(b.event)
        assert (a.qp is None) == (b.qp is None)
        xi_u = lie.lf + lie.lg @ a.u - lie.grad_norm * short.d_bar + short.alpha.vector(lie.h)
        # every robust condition holds at the answer where h >= 0 (below, a promoted row asks b, which can be less)
        assert np.all(xi_u[lie.h >= 0.0] >= -1e-9), xi_u


@pytest.mark.parametrize("make", [
    lambda screen: SafetyFilter(Power(3.0, 0.7), 0.05, screen=screen),
    lambda screen: IntermittentSafetyFilter(Power(3.0, 0.7), 0.1, 0.05, 0.05, screen=screen),
])
def test_screening_never_changes_the_command(make) -> None:  # type: ignore[no-untyped-def]
    # tiny thresholds screen out rows the solution then needs: the re-solve must fix it
    rng = np.random.default_rng(7)
    resolves = 0
    for screen in (1e-5, 0.2, 1.0):
        full, screened = make(None), make(screen)
        for i in range(300):
            lie = _random_lie(rng, int(rng.integers(2, 9)), 3)
            u_nom = rng.normal(size=3)
            a = full.step_lie(0.01 * i, lie, u_nom)
            b = screened.step_lie(0.01 * i, lie, u_nom)
            assert a.on == b.on and (a.event is None) == (b.event is None)
            np.testing.assert_allclose(b.u, a.u, atol=1e-7)
            assert (a.qp is None) == (b.qp is None)
            resolves += b.resolved
    assert resolves > 0, "the thresholds must make some screened row necessary"


def test_screen_below_active_tol_is_rejected() -> None:
    with pytest.raises(ConfigError, match="screen"):
        SafetyFilter(1.0, screen=0.0)


def test_standard_filter_reports_switch_events_like_the_trigger() -> None:
    # one barrier h = x - 1 (x_dot = u): the filter is "on" while the constraint is active
    f = SafetyFilter(1.0, 0.0)
    events = []
    for i, (h, u_nom) in enumerate([(1.0, 0.0), (0.5, -1.0), (0.4, -1.0), (0.4, 1.0), (0.2, -1.0)]):
        lie = LieData(np.array([h]), np.zeros(1), np.ones((1, 1)), np.ones(1), ("x",))
        s = f.step_lie(float(i), lie, np.array([u_nom]))
        events.append(None if s.event is None else (s.event.kind, s.event.index, s.event.duration_s))
        assert s.on == (u_nom < -h)
    assert events == [None, ("on", 1, None), None, ("off", 1, 2.0), ("on", 2, 1.0)]


def test_non_finite_input_raises_even_without_validation() -> None:
    from isf_robot.core import NonFiniteError

    f = IntermittentSafetyFilter(1.0, 0.1, 0.1, validate=False)
    lie = LieData(np.array([0.5, math.nan]), np.zeros(2), np.eye(2), np.ones(2))
    with pytest.raises(NonFiniteError):
        f.step_lie(0.0, lie, np.zeros(2))


@pytest.mark.parametrize("alpha", [2.0, Power(3.0, 0.7), CustomClassK(lambda h: h + h ** 3, "cubic")])
@pytest.mark.parametrize("order", ["C", "F"])
def test_one_kept_row_goes_the_short_way_to_the_backends_answer(alpha, order) -> None:  # type: ignore[no-untyped-def]
    # at most one row kept (or none: the row of least slack alone) and no bounds: the filter solves
    # that row by its closed form without building the QP; the command is the QP backend's on that
    # row (daqp, to its accuracy), and the QP is built only to re-solve with every row
    rng = np.random.default_rng(3)
    f = SafetyFilter(alpha, 0.05, validate=False)
    backend = QPSolver(closed_form=False)
    built = []
    real = FilterQP._of
    short = resolves = 0
    for i in range(400):
        lie = _random_lie(rng, int(rng.integers(2, 4)), 3)  # <= 3 rows in R^3: always feasible
        lie = LieData(lie.h, lie.lf, np.asarray(lie.lg, order=order), lie.grad_norm, lie.names)
        u_nom = rng.normal(size=3)
        xi = lie.lf + lie.lg @ u_nom - lie.grad_norm * 0.05 + f.alpha.vector(lie.h)
        screen = float(np.sort(xi)[int(rng.integers(0, 2))]) + 1e-3  # keeps one or two rows
        screen = max(screen, 2e-6)
        n_built = len(built)
        FilterQP._of = lambda *a, **kw: built.append(1) or real(*a, **kw)  # type: ignore[method-assign]
        try:
            s = f.step_lie(0.01 * i, lie, u_nom, screen=screen)
        finally:
            FilterQP._of = real  # type: ignore[method-assign]
        kept = np.flatnonzero(xi < screen)
        if kept.size > 1:
            continue
        row = kept if kept.size else np.array([int(xi.argmin())])
        if s.resolved:
            resolves += 1
            full = backend.solve(f.build_qp(lie, u_nom))
            np.testing.assert_allclose(s.u, full.u, rtol=1e-9, atol=1e-9)
            continue
        short += 1
        assert len(built) == n_built, "one kept row must not build the QP"
        ref = backend.solve(f.build_qp(lie.select(row), u_nom))
        np.testing.assert_allclose(s.u, ref.u, rtol=1e-9, atol=1e-9)
        assert s.qp.status == "closed_form"
        assert s.on == bool(s.qp.active.any())
        assert np.all(lie.lf + lie.lg @ s.u - lie.grad_norm * 0.05 + f.alpha.vector(lie.h) >= -1e-9)
    assert short > 100 and resolves > 0


@pytest.mark.parametrize("cls", ["FilterStep", "LieData", "QPResult", "FilterQP"])
def test_fast_constructors_build_the_dataclass_itself(cls) -> None:  # type: ignore[no-untyped-def]
    # _of skips the frozen dataclass's __init__: its parameters must be the fields (names, order,
    # defaults), and it must build an object equal to the dataclass's own, still frozen
    import dataclasses
    import inspect

    from isf_robot.core.filter_base import FilterStep
    from isf_robot.core.qp import FilterQP, QPResult

    kind = {"FilterStep": FilterStep, "LieData": LieData, "QPResult": QPResult, "FilterQP": FilterQP}[cls]
    fields = dataclasses.fields(kind)
    params = list(inspect.signature(kind._of).parameters.values())
    assert [p.name for p in params] == [f.name for f in fields]
    for p, f in zip(params, fields):
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        assert (p.default is inspect.Parameter.empty) == (default is dataclasses.MISSING), f.name
        if default is not dataclasses.MISSING:
            assert p.default == default, f.name
    rng = np.random.default_rng(0)
    args = [rng.normal(size=3) if i % 2 else float(i) for i in range(len(fields))]
    a, b = kind(*args), kind._of(*args)
    assert vars(a).keys() == vars(b).keys()
    assert all(x is y for x, y in zip(vars(a).values(), vars(b).values()))
    with pytest.raises(dataclasses.FrozenInstanceError):
        b.u = None  # type: ignore[misc]


def test_backend_answers_are_judged_by_their_distance_to_the_feasible_set() -> None:
    # a backend's answer is checked in solve(): a violation of 1e-3 is refused, rounding is not,
    # and a row scaled by 1e9 is judged by the distance to its half-space, not by its residual
    from isf_robot.core import QPSolver, SolverError
    from isf_robot.core.qp import FilterQP

    solver = QPSolver(closed_form=False)  # every problem to the (fake) backend, none to the closed forms
    answer: list[np.ndarray] = []
    solver._solve_daqp = lambda qp: (answer[0], 3, "solved")  # type: ignore[method-assign]
    qp = FilterQP(np.zeros(2), np.eye(2), np.ones(2))
    for u, ok in (([1.0, 1.0 - 1e-3], False), ([1.0, 1.0 - 1e-12], True), ([math.nan, 1.0], False)):
        answer[:] = [np.array(u)]
        if ok:
            res = solver.solve(qp)
            assert res.status == "optimal" and res.active.tolist() == [True, True]
            assert res.max_violation == pytest.approx(1e-12, rel=1e-3)
        else:
            with pytest.raises(SolverError):
                solver.solve(qp)
    big = FilterQP(np.zeros(2), np.diag([1e9, 1.0]), np.array([1e9, 1.0]))
    answer[:] = [np.array([1.0 - 1e-10, 1.0])]  # residual -0.1, distance 1e-10: accepted
    assert solver.solve(big).max_violation == pytest.approx(0.1, rel=1e-3)
    answer[:] = [np.array([1.0 - 1e-4, 1.0])]  # distance 1e-4: refused
    with pytest.raises(SolverError):
        solver.solve(big)


@pytest.mark.parametrize("alpha", [2.0, Power(3.0, 0.7)])
@pytest.mark.parametrize("blend", [0.0, 0.04])
def test_the_one_row_closed_form_gives_the_backends_steps_on_and_off(alpha, blend) -> None:  # type: ignore[no-untyped-def]
    # the intermittent filter's one kept row (robust, or promoted at b or on its hand-over ramp) goes
    # to its closed form; the same filter with the closed forms off (every row to daqp) must give
    # every step to the backend's accuracy, with the same modes and switches
    def make(closed: bool):  # type: ignore[no-untyped-def]
        return IntermittentSafetyFilter(alpha, 0.1, 0.05, 0.05, validate=False, blend=blend, screen=0.15,
                                        solver=QPSolver(closed_form=closed))

    short, general = make(True), make(False)
    _walk_same_steps(short, general, 8)
    assert short.qp_solves == general.qp_solves
    assert general.solver.solves - short.solver.solves > 50, "one-row problems must go the closed form"


@pytest.mark.parametrize("alpha", [2.0, Power(3.0, 0.7)])
@pytest.mark.parametrize("kind", ["cbf", "isf"])
def test_the_few_row_closed_form_gives_the_backends_steps(alpha, kind) -> None:  # type: ignore[no-untyped-def]
    # with QPSolver(few_rows=True), 2 to FEW_ROWS kept rows without bounds go to project_few
    # without a FilterQP; the same filter sending them to daqp must give every step to its accuracy
    def make(few: bool):  # type: ignore[no-untyped-def]
        solver = QPSolver(few_rows=few)
        if kind == "cbf":
            return SafetyFilter(alpha, 0.05, validate=False, screen=0.3, solver=solver)
        return IntermittentSafetyFilter(alpha, 0.1, 0.05, 0.05, validate=False, blend=0.04, screen=0.3, solver=solver)

    short, general = make(True), make(False)
    _walk_same_steps(short, general, 9)
    assert short.qp_solves == general.qp_solves
    assert general.solver.solves - short.solver.solves > 50, "few-row problems must go the closed form"
