"""The screened few-row step's compiled way (ShortWays._few_fast, core/_step_jit.py): the general way's numbers, bit for bit."""

from __future__ import annotations

import collections

import numpy as np
import pytest

from isf_robot.core import CustomClassK, IntermittentSafetyFilter, LieData, Linear, Power, QPSolver, SafetyFilter
from isf_robot.core.sums import matvec

pytest.importorskip("numba")
pytestmark = pytest.mark.kernels  # (skipped under ISF_ROBOT_JIT=0: tests/conftest.py)

ALPHAS = [Linear(2.0), Power(3.0, 0.7), CustomClassK(lambda h: h + h ** 3, "cubic")]


def _kernels():  # type: ignore[no-untyped-def]
    from isf_robot.core.fast import step_kernels

    kernels = step_kernels()
    assert kernels is not None, "numba is installed: the kernels must load"
    return kernels


def test_row_selection_is_numpys_mask() -> None:
    select = _kernels().select
    rng = np.random.default_rng(2)
    for i in range(3000):
        k = int(rng.integers(1, 30))
        xi = rng.normal(scale=0.3, size=k)
        tie = rng.random(k) < 0.4
        xi[tie] = rng.choice([0.0, -0.0, 0.1, 0.2], tie.sum())  # (ties with the thresholds below)
        if i % 50 == 0:
            xi[0] = np.nan
        screen = rng.choice([0.0, 0.1, 0.3, rng.uniform(-0.2, 0.5)], 1 if i % 2 else k)
        if i % 40 == 0:
            screen[-1] = np.nan  # (np.maximum and the comparison: a NaN threshold keeps no row)
        floor = float(rng.choice([0.0, -0.1, 0.2, 0.0]))
        promote = rng.random(k) < 0.2 if i % 3 else None
        thr = np.maximum(screen, floor) if floor > 0 else screen
        keep = xi < thr
        if promote is not None:
            keep |= promote
        rows = np.empty(k, np.intp)
        n = select(xi, screen, floor, np.zeros(0, bool) if promote is None else promote, rows)
        assert rows[:n].tolist() == np.flatnonzero(keep).tolist()


def _lie(rng: np.random.Generator, k: int, m: int) -> LieData:
    lg = rng.normal(size=(k, m)) * 10.0 ** rng.uniform(-1, 1, size=(k, 1))
    h = rng.uniform(-0.05, 0.5, k)
    h[rng.random(k) < 0.1] = 0.0  # (signed zeros: -alpha(0))
    return LieData(h, rng.normal(scale=0.3, size=k), lg, np.linalg.norm(lg, axis=1), tuple(f"b{i}" for i in range(k)))


_NOW: dict = {}  # the walk's current step, for the rollout


def _rollout(t: float, x) -> list:  # type: ignore[no-untyped-def]
    """Three predicted points near the current step (the same for every filter at one t), some of them failing."""
    rng = np.random.default_rng(int(round(t * 1e4)))
    lie, u = _NOW["lie"], _NOW["u"]
    return [(0.01 * (j + 1), LieData(lie.h + rng.normal(scale=0.1, size=lie.k), lie.lf - rng.uniform(0.0, 1.0, size=lie.k),
                                     lie.lg, lie.grad_norm, lie.names), u) for j in range(3)]


def _make(kind: str, alpha):  # type: ignore[no-untyped-def]
    solver = QPSolver(few_rows=True)
    if kind == "cbf":
        return SafetyFilter(alpha, 0.05, validate=False, solver=solver)
    return IntermittentSafetyFilter(alpha, 0.1, 0.05, 0.05, validate=False, blend=0.0 if kind == "isf" else 0.04,
                                    solver=solver, rollout=_rollout if kind == "isf_pred" else None, predict_every=3)


def _step_record(s) -> tuple:  # type: ignore[no-untyped-def]
    q = s.qp
    return (s.u.tobytes(), s.on, str(s.event), s.resolved, s.relaxed, s.fallback, s.held, s.rollout,
            None if q is None else (q.status, q.active.tolist(), q.iterations, q.max_violation.hex(), q.relaxed))


@pytest.mark.parametrize("alpha", ALPHAS, ids=repr)
@pytest.mark.parametrize("kind", ["cbf", "isf", "isf_blend", "isf_pred"])
def test_the_compiled_few_row_step_equals_the_short_and_the_general_way(alpha, kind) -> None:  # type: ignore[no-untyped-def]
    # three copies of one filter on one slowly moving random walk (it switches, promotes and ramps; the
    # screening thresholds keep 0 to all of 2-12 rows, some of them needed at the answer): the compiled
    # way, the Python short way (_solve_few) and the general way (build_qp + QPSolver.solve) must give
    # every step bit for bit (command, mode, event, QP status, activity, max violation, re-solves)
    fast, short, general = _make(kind, alpha), _make(kind, alpha), _make(kind, alpha)
    short._steps = general._steps = None
    general._solve_few = lambda *a: None  # type: ignore[method-assign]
    assert fast._steps is not None
    seen: collections.Counter = collections.Counter()
    few = fast._few_fast

    def spy(lie, u_nom, xi, xs, promote, rows, n):  # type: ignore[no-untyped-def]
        got = few(lie, u_nom, xi, xs, promote, rows, n)
        seen["few" if n < xi.shape[0] else "all"] += got is not None
        seen["hold" if got is not None and got[1] else "needed"] += 1
        return got

    fast._few_fast = spy  # type: ignore[method-assign]
    rng = np.random.default_rng(17)
    m = 8
    lie = _lie(rng, 12, m)
    for i in range(900):
        if i % 150 == 0:
            k = int(rng.integers(2, 13))
            lie = _lie(rng, k, m)
        k = lie.k
        h = np.clip(lie.h + rng.normal(scale=0.02, size=k), -0.05, 0.6)
        lie = LieData(h, lie.lf + rng.normal(scale=0.05, size=k), lie.lg + rng.normal(scale=0.05, size=(k, m)),
                      lie.grad_norm, lie.names)
        u_nom = rng.normal(size=m)
        screen = float(rng.choice([0.02, 0.3, 1.0, 5.0])) if i % 4 else rng.uniform(0.01, 1.0, k)
        _NOW.update(lie=lie, u=u_nom)
        a, b, c = (f.step_lie(0.01 * i, lie, u_nom, screen=screen) for f in (fast, short, general))
        assert _step_record(a) == _step_record(b) == _step_record(c), i
        seen["held"] += a.held
    assert fast.qp_solves == short.qp_solves == general.qp_solves
    assert kind != "isf_pred" or seen["held"] > 10, seen  # (held: the predicted failures promoted)
    assert seen["few"] > 100 and seen["all"] > 20 and seen["needed"] > 5, seen


@pytest.mark.parametrize("alpha", ALPHAS, ids=repr)
def test_the_kernels_bounds_are_qp_lowers_bit_for_bit(alpha) -> None:  # type: ignore[no-untyped-def]
    # few_step: the kept rows' bounds (robust, promoted at b, or on the hand-over ramp) against the
    # general way's qp_lower on the rows taken, its products against sums' (zeros of both signs
    # everywhere: np.maximum's tie rule), its answer's residuals, activity, step and the screened
    # rows' check against the general way's numpy
    few_step = _kernels().few_step
    f = IntermittentSafetyFilter(alpha, 0.1, 0.05, 0.05, validate=False)
    rng = np.random.default_rng(4)
    zero = np.array([0.0, -0.0])
    codes = {0: 0, 1: 0}
    held = 0
    for i in range(2000):
        k, m = int(rng.integers(2, 12)), 3
        lie = _lie(rng, k, m)
        for arr in (lie.h, lie.lf, lie.grad_norm):
            pick = rng.random(k) < 0.3
            arr[pick] = rng.choice(zero, pick.sum())
        f.d_bar = float(rng.choice([0.0, 0.05]))
        f.b = float(rng.choice([0.0, -0.0, 0.05]))
        promote = rng.random(k) < 0.5 if i % 4 else None
        ramp = rng.choice([0.0, 0.3, 1.0], k) if i % 3 else None
        rows = np.flatnonzero(rng.random(k) < 0.7)
        n = rows.size
        if n == 0:
            continue
        sub = LieData(lie.h.take(rows), lie.lf.take(rows), lie.lg.take(rows, 0), lie.grad_norm.take(rows))
        ref = f.qp_lower(sub, None if promote is None else promote[rows], f.b, 1.0 if ramp is None else ramp[rows])
        gain = alpha.gain if type(alpha) is Linear else 0.0
        av = np.zeros(0) if gain else alpha.vector(sub.h)
        A = sub.lg
        u_nom = rng.normal(size=m)
        xi = rng.normal(scale=0.3, size=k)
        buf, u, active, du = np.empty((4, n)), np.empty(m), np.zeros(n, bool), np.zeros(m)
        code, low, ok_rows = few_step(rows, lie.h, lie.lf, lie.grad_norm, f.d_bar, gain, av, True,
                                      np.zeros(0, bool) if promote is None else promote,
                                      np.zeros(0) if ramp is None else ramp, f.b, lie.lg, u_nom, 1e-12, buf, u, 1e-6,
                                      active, du, xi, n < k)
        lb, r = buf[0, :n], buf[1, :n]
        assert lb.tobytes() == ref.tobytes(), i
        assert r.tobytes() == (matvec(A, u_nom) - ref).tobytes()
        if code in (0, 1):  # (an answer: its residuals, activity, step and the screened rows' check as numpy makes them)
            res = matvec(A, u) - lb
            if code == 1:
                assert buf[3, :n].tobytes() == res.tobytes() and low == res.min()
            else:
                assert u.tobytes() == u_nom.tobytes() and low == r.min()
            assert active.tolist() == ((res if code == 1 else r) <= 1e-6).tolist()
            assert du.tobytes() == (u - u_nom).tobytes()
            keep = np.zeros(k, bool)
            keep[rows] = True
            slack = xi + matvec(lie.lg, du)
            assert ok_rows == bool(slack[~keep].min() >= 1e-6 if n < k else True)
            codes[code] += 1
            held += ok_rows and n < k
    assert codes[0] > 50 and codes[1] > 200 and held > 20, (codes, held)


def test_the_screened_rows_check_is_the_general_ones() -> None:
    # slack = xi + Lg h du >= active_tol on every row not kept (a tie holds, a NaN does not)
    hold = _kernels().hold
    f = SafetyFilter(1.0)
    tol = f.solver.active_tol
    rng = np.random.default_rng(5)
    for i in range(3000):
        k = int(rng.integers(1, 20))
        xi = rng.choice([tol, 2 * tol, 0.5 * tol, 0.3, -0.1], k)
        lgdu = rng.choice([0.0, -0.0, tol, -tol, 1e-3], k)
        if i % 30 == 0:
            lgdu[rng.integers(k)] = np.nan
        keep = rng.random(k) < 0.3
        rows = np.flatnonzero(keep)
        lie = LieData(np.zeros(k), np.zeros(k), lgdu[:, None].copy(), np.zeros(k))
        assert hold(xi, lgdu, rows, rows.size, tol) == f._screened_rows_hold_mask(lie, xi, np.ones(1), keep), i


def test_the_one_row_step_is_numpys() -> None:
    # one_step (the closed form of one kept row and the check of every other row) against the numpy way of
    # _one_row on the same filter: the same answer bit for bit (u_nom itself when the row holds there), the
    # same activity and check, no answer in the same cases (a zero row, an overflow); rows of either memory order
    kernels = _kernels()
    rng = np.random.default_rng(6)
    fast, slow = SafetyFilter(1.0, d_bar=0.05), SafetyFilter(1.0, d_bar=0.05)
    slow._steps = None
    fast._steps = kernels
    tol = fast.solver.active_tol
    seen = collections.Counter()
    for i in range(3000):
        m, k = int(rng.integers(1, 9)), int(rng.integers(1, 12))
        lg = np.asarray(rng.normal(size=(k, m)) * 10.0 ** rng.uniform(-3, 3), order="F" if i % 2 else "C")
        row = int(rng.integers(k))
        if i % 3 == 0:
            lg[[j for j in range(k) if j != row], :] = 0.0  # (the other rows' slack = xi exactly)
        if i % 97 == 0:
            lg[row] = 0.0  # (no closed form)
        if i % 89 == 0:
            lg[row] *= 1e160  # (|u|^2 overflows)
        h = rng.uniform(-0.2, 0.5, k)
        with np.errstate(over="ignore"):  # (the overflowing rows)
            lie = LieData(h, rng.normal(scale=0.5, size=k), lg, np.linalg.norm(lg, axis=1))
        u_nom = rng.normal(size=m)
        xi = rng.choice([tol, 2 * tol, 0.5 * tol, 0.3, -0.1], k)  # (ties at active_tol)
        if i % 50 == 0:
            xi[rng.integers(k)] = np.nan
        with np.errstate(over="ignore", invalid="ignore"):
            a, b = fast._one_row(lie, u_nom, row, xi, None), slow._one_row(lie, u_nom, row, xi, None)
        assert (a is None) == (b is None), i
        if a is None:
            seen["none"] += 1
            continue
        assert a[0].u.tobytes() == b[0].u.tobytes() and a[0].active.tolist() == b[0].active.tolist(), i
        assert a[1] == b[1] and (a[0].u is u_nom) == (b[0].u is u_nom), i
        seen["at u_nom" if a[0].u is u_nom else "moved"] += 1
        seen["held" if a[1] else "not held"] += 1
    assert min(seen.values()) > 20, seen


@pytest.mark.parametrize("kind", ["cbf", "isf"])
def test_strided_arrays_take_the_compiled_steps_with_numpys_numbers(kind, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    # a caller's u_nom and Lg h may be views with strides (a column of a larger array, Fortran order):
    # the compiled one-row and few-row steps take them as they are (no reshape of the caller's arrays)
    # and give the numpy path's numbers
    def make():  # type: ignore[no-untyped-def]
        if kind == "cbf":
            return SafetyFilter(2.0, d_bar=0.05, validate=False, screen=0.3, solver=QPSolver(few_rows=True))
        return IntermittentSafetyFilter(2.0, 0.1, 0.05, 0.05, validate=False, screen=0.3, solver=QPSolver(few_rows=True))

    fast = make()
    monkeypatch.setenv("ISF_ROBOT_JIT", "0")
    slow = make()
    monkeypatch.delenv("ISF_ROBOT_JIT")
    assert fast._steps is not None and slow._steps is None
    rng = np.random.default_rng(8)
    kinds = collections.Counter()
    for i in range(600):
        k, m = int(rng.integers(2, 4)), 3  # (at most 3 rows in R^3: always feasible)
        lie = _lie(rng, k, m)
        lg = np.asfortranarray(lie.lg)
        lie = LieData(lie.h, lie.lf, lg, lie.grad_norm, lie.names)
        u_nom = rng.normal(size=(m, 3))[:, 1]  # (strided)
        assert not u_nom.flags.c_contiguous and not lg.flags.c_contiguous
        a, b = fast.step_lie(0.01 * i, lie, u_nom), slow.step_lie(0.01 * i, lie, u_nom)
        assert np.asarray(a.u).tobytes() == np.asarray(b.u).tobytes() and a.on == b.on, i
        if a.qp is not None:
            kinds[a.qp.status] += 1
    assert kinds["closed_form"] > 20 and kinds["optimal"] > 20, kinds  # (one-row and few-row steps both ran)
