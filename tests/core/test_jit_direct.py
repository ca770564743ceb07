"""jit.direct: a kernel's compiled code called without numba's dispatch gives the dispatching call's answers.

The filters call their passes so (``DirectPasses``) only for inputs of the types those calls were resolved
for: strided rows or commands and a non-linear class-K function take the dispatching passes, a strided screen is
made C-contiguous (the same commands, modes and switches).
"""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core import IntermittentSafetyFilter, LieData, Power, QPSolver, SafetyFilter, robust
from isf_robot.core.jit import compiled, direct

pytestmark = pytest.mark.kernels  # (skipped under ISF_ROBOT_JIT=0: tests/conftest.py)


def test_direct_is_the_function_itself_where_nothing_is_compiled() -> None:
    def f(x):  # type: ignore[no-untyped-def]
        return x

    assert direct(f, (1.0,)) is f


def test_direct_code_answers_as_the_dispatching_call() -> None:
    rng = np.random.default_rng(3)
    k, m = 9, 4
    lf, lg, u, gn, h = rng.normal(size=k), rng.normal(size=(k, m)), rng.normal(size=m), rng.uniform(0, 1, k), \
        rng.uniform(-0.1, 1.0, k)
    kernel = compiled(robust.xi_pass)

    def run(fn):  # type: ignore[no-untyped-def]
        av, xi, rows = np.zeros(k), np.zeros(k), np.zeros(k, np.intp)
        out = fn(lf, lg, u, gn, 0.1, h, 2.0, av, np.full(1, 0.3), xi, rows)
        return out, av, xi, rows

    code = direct(kernel, run(lambda *a: a)[0])  # (the argument types of the call)
    assert code is not kernel
    want, got = run(kernel), run(code)
    assert want[0] == got[0]
    for a, b in zip(want[1:], got[1:]):
        assert a.tobytes() == b.tobytes()


def _lie(rng: np.random.Generator, k: int, m: int) -> LieData:
    lg = rng.normal(size=(k, m))
    return LieData(rng.uniform(-0.05, 0.5, k), rng.normal(size=k), lg, np.linalg.norm(lg, axis=1))


@pytest.mark.parametrize("make", [lambda: SafetyFilter(2.0, 0.01, screen=0.2, on_infeasible="fallback"),
                                  lambda: IntermittentSafetyFilter(2.0, 0.05, 0.1, 0.01, screen=0.2,
                                                                   on_infeasible="fallback")])
@pytest.mark.filterwarnings("ignore::isf_robot.core.IsfWarning")
def test_filters_answer_alike_with_screens_of_every_layout(make) -> None:  # type: ignore[no-untyped-def]
    # distinct thresholds per row, strided between other values: code that read a strided screen as contiguous
    # would see the -1e9 between them and screen out rows it must keep (other solves, other answers)
    rng = np.random.default_rng(7)
    k, m, n = 6, 3, 120
    th = np.array([0.2, 0.05, 0.3, 0.02, 0.4, 0.03])
    strided = np.stack([th, np.full(k, -1e9)], 1).ravel()[::2]
    assert not strided.flags.c_contiguous and np.array_equal(strided, th)
    steps = [(_lie(rng, k, m), rng.normal(size=m)) for _ in range(n)]
    ref, mixed = make(), make()
    assert mixed._passes_for(*steps[0]) is mixed._direct  # (the direct passes answer)
    for i, (lie, u_nom) in enumerate(steps):
        want = ref.step_lie(i * 1e-3, lie, u_nom, screen=th)
        got = mixed.step_lie(i * 1e-3, lie, u_nom, screen=strided if i % 2 else th.copy())  # (resolved C first)
        np.testing.assert_allclose(got.u, want.u, rtol=1e-12, atol=1e-12)
        assert got.on == want.on and (got.event is None) == (want.event is None) and got.resolved == want.resolved
        assert (got.qp is None) == (want.qp is None)
        if got.qp is not None:
            np.testing.assert_array_equal(got.qp.active, want.qp.active)
    assert ref.qp_solves == mixed.qp_solves


@pytest.mark.parametrize("closed_form", [True, False])
@pytest.mark.filterwarnings("ignore::isf_robot.core.IsfWarning")
def test_promotable_flags_of_any_layout_and_type_answer_as_contiguous_bools(closed_form: bool) -> None:
    # an int array and a strided bool view of the same flags, after a contiguous bool array resolved the passes; on
    # the closed step and on the QP path (promote &= promotable)
    rng = np.random.default_rng(11)
    k, m, n = 6, 3, 80
    flags = np.array([True, False, True, True, False, True])
    kinds = [flags.copy(), flags.astype(np.int64), np.stack([flags, ~flags], 1).ravel()[::2]]
    steps = [(_lie(rng, k, m), rng.normal(size=m)) for _ in range(n)]

    def make() -> IntermittentSafetyFilter:
        return IntermittentSafetyFilter(2.0, 0.05, 0.1, 0.01, on_infeasible="fallback",
                                        solver=QPSolver(closed_form=closed_form))

    ref, mixed = make(), make()
    for i, (lie, u_nom) in enumerate(steps):
        want = ref.step_lie(i * 1e-3, lie, u_nom, promotable=flags)
        got = mixed.step_lie(i * 1e-3, lie, u_nom, promotable=kinds[i % 3])
        np.testing.assert_allclose(got.u, want.u, rtol=1e-12, atol=1e-12)
        assert got.on == want.on
    assert ref.qp_solves == mixed.qp_solves and ref.qp_solves > 0


def test_only_inputs_of_the_resolved_types_take_the_direct_passes() -> None:
    filt = SafetyFilter(2.0, 0.0)
    rng = np.random.default_rng(5)
    lie, u = _lie(rng, 4, 2), rng.normal(size=2)
    assert filt._passes_for(lie, u) is filt._direct
    assert filt._passes_for(lie, np.repeat(u, 2)[::2]) is filt._passes  # (a strided command)
    for field in ("h", "lf", "grad_norm"):  # (a strided row array)
        arrays = {f: getattr(lie, f) for f in ("h", "lf", "lg", "grad_norm")}
        arrays[field] = np.repeat(arrays[field], 2)[::2]
        assert filt._passes_for(LieData(**arrays), u) is filt._passes
    assert filt._passes_for(lie, u.astype(np.float32)) is filt._plain


def test_a_non_linear_class_k_function_takes_the_dispatching_passes() -> None:
    filt = SafetyFilter(Power(2.0, 0.5), 0.0)
    rng = np.random.default_rng(2)
    lie = _lie(rng, 4, 2)
    filt.step_lie(0.0, lie, rng.normal(size=2))
    assert filt._passes_for(lie, np.zeros(2)) is filt._passes
