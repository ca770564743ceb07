"""One source, two ways to run it: the filter step's passes as written (numpy) and compiled (numba) agree.

Stated tolerance: 1e-12 relative on every float a pass returns (the compiled ``Lg h u`` may add its
products in another order than numpy's BLAS), the same integers and masks; whole filters give the
same modes and switch events and commands to 1e-9. Also the formulas' own identities (known answers).
"""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core import (
    IntermittentSafetyFilter,
    LieData,
    Power,
    QPSolver,
    SafetyFilter,
    closed_step,
    handover,
    projection,
    qp_check,
    robust,
    screening,
)
from isf_robot.core.jit import compiled

pytestmark = pytest.mark.kernels  # (skipped under ISF_ROBOT_JIT=0: tests/conftest.py)

REL = 1e-12


def _close(a, b) -> None:  # type: ignore[no-untyped-def]
    np.testing.assert_allclose(a, b, rtol=REL, atol=REL)


def _data(rng: np.random.Generator, k: int, m: int):  # type: ignore[no-untyped-def]
    lg = rng.normal(size=(k, m))
    return (rng.normal(size=k), lg, rng.normal(size=m), np.linalg.norm(lg, axis=1), rng.uniform(-0.1, 1.0, k))


def test_robust_slack_row_lower_and_promotion_level_known_answers() -> None:
    # Xi = Lf h + Lg h u - |dh/dx| d_bar + alpha(h): each term with its sign
    assert robust.robust_slack(1.0, 0.0, 0.0, 5.0, 0.0) == 1.0
    assert robust.robust_slack(0.0, 2.0, 0.0, 5.0, 0.0) == 2.0
    assert robust.robust_slack(0.0, 0.0, 2.0, 0.5, 0.0) == -1.0
    assert robust.robust_slack(0.0, 0.0, 0.0, 0.5, 3.0) == 3.0
    # the row Lg h u >= lb at the robust level is Xi >= 0: Xi = Lg h u - lb
    rng = np.random.default_rng(1)
    lf, lg, u, gn, h = _data(rng, 20, 4)
    av = 2.0 * h
    xi = robust.robust_slack(lf, lg @ u, gn, 0.3, av)
    lb = robust.row_lower(-av, lf, gn, 0.3)
    _close(xi, lg @ u - lb)
    # promoted: b at w = 1 (never below -alpha(h)), the robust level at w = 0, monotone in between
    assert robust.promotion_level(0.2, 0.05, 1.0) == 0.05
    assert robust.promotion_level(-0.2, 0.05, 1.0) == 0.05  # h < 0: still b once fully promoted (eq. filter_inc)
    assert robust.promotion_level(-0.2, 0.05, 0.5) == 0.2  # ramping: never below the robust level
    assert robust.promotion_level(0.2, 0.05, 0.0) == -0.2
    levels = [robust.promotion_level(0.2, 0.05, w) for w in np.linspace(0.0, 1.0, 11)]
    assert levels == sorted(levels) and levels[5] == pytest.approx(0.5 * 0.05 - 0.5 * 0.2)


@pytest.mark.parametrize("gain", [0.0, 2.0])
def test_xi_pass_compiled_as_written(gain: float) -> None:
    rng = np.random.default_rng(2)
    fast = compiled(robust.xi_pass)
    for _ in range(200):
        k, m = int(rng.integers(1, 40)), int(rng.integers(1, 8))
        lf, lg, u, gn, h = _data(rng, k, m)
        screen = [np.zeros(0), np.full(1, 0.5), rng.uniform(0.1, 2.0, k)][int(rng.integers(0, 3))]
        outs = []
        for fn in (robust.xi_pass, fast):
            av = np.empty(k) if gain else np.tanh(h)
            xi, rows = np.empty(k), np.empty(k, np.intp)
            total, low, arg, kept = fn(lf, lg, u, gn, 0.1, h, gain, av, screen, xi, rows)
            outs.append((xi, av, total, low, int(arg), kept, rows[:max(kept, 0)].tolist()))
        (xa, aa, ta, la, ia, ka, ra), (xb, ab, tb, lb, ib, kb, rb) = outs
        _close(xa, xb)
        _close(aa, ab)
        assert ta == pytest.approx(tb, rel=REL, abs=REL) and la == pytest.approx(lb, rel=REL, abs=REL)
        assert xa[ib] == pytest.approx(xa.min(), rel=REL, abs=REL) and ka == kb
        if np.all(np.abs(xa[:, None] - screen[None, :]) > 1e-9):  # (no row on a threshold)
            assert ra == rb


def test_bounds_screening_and_hand_over_compiled_as_written() -> None:
    rng = np.random.default_rng(3)
    bounds, kept, hold, promote = (compiled(f) for f in (robust.row_bounds, screening.kept_rows,
                                                         screening.others_hold, handover.promote_rows))
    none_b, none_f = np.zeros(0, bool), np.zeros(0)
    for _ in range(300):
        k, m = int(rng.integers(2, 30)), int(rng.integers(1, 7))
        lf, lg, u, gn, h = _data(rng, k, m)
        av, xi = np.tanh(h), rng.normal(size=k)
        rows = np.flatnonzero(rng.random(k) < 0.5)
        prom = rng.random(k) < 0.4 if rng.random() < 0.7 else none_b
        ramp = rng.uniform(0.0, 1.0, k) if rng.random() < 0.5 else none_f
        _close(robust.row_bounds(rows, lf, gn, 0.2, av, prom, ramp, 0.05),
               bounds(rows, lf, gn, 0.2, av, prom, ramp, 0.05))
        screen = np.full(1, 0.3) if rng.random() < 0.5 else rng.uniform(0.1, 1.0, k)
        ra, rb = np.empty(k, np.intp), np.empty(k, np.intp)
        na = screening.kept_rows(xi, screen, 0.1, prom, ra)
        assert na == kept(xi, screen, 0.1, prom, rb) and ra[:na].tolist() == rb[:na].tolist()
        du = rng.normal(size=m) * 0.01
        assert screening.others_hold(xi, lg, du, ra[:na], 1e-6) == hold(xi, lg, du, ra[:na], 1e-6)
        ids = rng.integers(0, 5, k).astype(np.intp)
        states = [(rng.uniform(-0.2, 1.0, 8), rng.random(8) < 0.5)]
        states.append((states[0][0].copy(), states[0][1].copy()))
        results = []
        for fn, (w, inw) in zip((handover.promote_rows, promote), states):
            mask, weights = np.empty(k, bool), np.empty(k)
            fn(xi, 0.2, none_b, True, ids, w, inw, 0.3, mask, weights)
            results.append((mask.tolist(), weights.copy(), w, inw.tolist()))
        assert results[0][0] == results[1][0] and results[0][3] == results[1][3]
        _close(results[0][1], results[1][1])
        _close(results[0][2], results[1][2])


def _walk(make, seed: int):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    k, m = 7, 6
    lg = rng.normal(size=(k, m))
    lie = LieData(rng.uniform(0.0, 0.5, k), rng.normal(scale=0.2, size=k), lg, np.linalg.norm(lg, axis=1),
                  tuple(f"b{i}" for i in range(k)))
    f = make()
    out = []
    for i in range(500):
        h = np.clip(lie.h + rng.normal(scale=0.02, size=k), 0.0, 0.6)
        lie = LieData(h, lie.lf + rng.normal(scale=0.05, size=k), lie.lg + rng.normal(scale=0.05, size=(k, m)),
                      lie.grad_norm, lie.names)
        s = f.step_lie(0.01 * i, lie, rng.normal(size=m))
        out.append((s.u.copy(), s.on, str(s.event), s.qp is None))
    return out


@pytest.mark.parametrize("kind", ["cbf", "isf", "isf-blend"])
def test_filters_compiled_and_as_written_give_the_same_steps(kind: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    def make():  # type: ignore[no-untyped-def]
        solver = QPSolver(few_rows=True)
        if kind == "cbf":
            return SafetyFilter(Power(3.0, 0.7), 0.05, screen=0.3, solver=solver)
        return IntermittentSafetyFilter(2.0, 0.1, 0.05, 0.05, screen=0.3, solver=solver,
                                        blend=0.04 if kind == "isf-blend" else 0.0)

    fast = _walk(make, 4)
    monkeypatch.setenv("ISF_ROBOT_JIT", "0")
    plain = _walk(make, 4)
    switches = 0
    for (ua, oa, ea, na), (ub, ob, eb, nb) in zip(fast, plain):
        np.testing.assert_allclose(ua, ub, rtol=1e-9, atol=1e-9)
        assert (oa, ea, na) == (ob, eb, nb)
        switches += ea != "None"
    assert switches > 5


def _bounds(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Input bounds for a closed step: none (length 0), or a box that the answer may or may not leave."""
    w = float(rng.uniform(0.3, 3.0))
    return [(qp_check.NO_BOUND, qp_check.NO_BOUND), (np.full(m, -w), np.full(m, w)), (qp_check.NO_BOUND, np.full(m, w)),
            (np.full(m, -w), qp_check.NO_BOUND)][int(rng.integers(0, 4))]


def test_the_fused_closed_steps_are_their_parts_composed_compiled_and_as_written() -> None:
    """``xi_closed_step`` = xi_pass, solved_rows, closed_step; ``screened_closed_step`` = screened_rows, closed_step."""
    rng = np.random.default_rng(5)
    none_b, none_f = np.zeros(0, bool), np.zeros(0)
    fused_xi, fused_screened = compiled(closed_step.xi_closed_step), compiled(closed_step.screened_closed_step)
    for _ in range(300):
        k, m = int(rng.integers(1, 12)), int(rng.integers(1, 7))
        lf, lg, u_nom, gn, h = _data(rng, k, m)
        lf -= 1.5  # (some rows violated at u_nom)
        screen = [np.zeros(0), np.full(1, 0.4), rng.uniform(0.1, 2.0, k)][int(rng.integers(0, 3))]
        few = bool(rng.random() < 0.8)
        lo, hi = _bounds(rng, m)
        outs = []
        for fn in (closed_step.xi_closed_step, fused_xi, None):
            av, xi, rows, u, res = np.empty(k), np.empty(k), np.empty(k, np.intp), np.zeros(m), np.zeros(8)
            if fn is None:  # (the parts, one by one)
                total, low, arg, kept = robust.xi_pass(lf, lg, u_nom, gn, 0.1, h, 2.0, av, screen, xi, rows)
                n = screening.solved_rows(kept, arg, k, rows)
                got = (total, low, arg, kept, n, *closed_step.closed_step(rows[:n], lf, gn, 0.1, av, none_b, none_f,
                                                                          0.0, lg, u_nom, xi, 1e-9, 1e-9, few, lo, hi, u,
                                                                          res))
                got += (sum(1 << i for i in range(n) if res[i] <= 1e-9) if got[5] >= 0 else 0,)
            else:
                got = fn(lf, lg, u_nom, gn, 0.1, h, 2.0, av, screen, xi, rows, none_b, none_f, 1e-9, 1e-9, few, lo, hi,
                         u, res)
            outs.append((got, rows[:got[4]].tolist(), u.copy(), xi.copy()))
        for got, rows, u, xi in outs[1:]:
            assert got[2:6] == outs[0][0][2:6] and got[7:] == outs[0][0][7:] and rows == outs[0][1]
            _close(np.array([got[0], got[1], got[6]]), np.array(outs[0][0][:2] + (outs[0][0][6],)))
            _close(u, outs[0][2])
            _close(xi, outs[0][3])
        prom = rng.random(k) < 0.3 if rng.random() < 0.5 else none_b
        ramp = rng.uniform(0.0, 1.0, k) if prom.shape[0] and rng.random() < 0.5 else none_f
        xi = rng.normal(size=k)
        arg = int(np.argmin(xi)) if rng.random() < 0.5 else -1
        outs = []
        for fn in (closed_step.screened_closed_step, fused_screened):
            rows, u, res = np.empty(k, np.intp), np.zeros(m), np.zeros(8)
            got = fn(xi, screen, 0.2, prom, arg, rows, lf, gn, 0.1, np.tanh(h), ramp, 0.05, lg, u_nom, 1e-9, 1e-9,
                     few, lo, hi, u, res)
            n = screening.screened_rows(xi, screen, 0.2, prom, arg, np.empty(k, np.intp))
            assert got[0] == n and (n == k if not screen.shape[0] else True)
            outs.append((got, rows[:n].tolist(), u.copy()))
        (ga, ra, ua), (gb, rb, ub) = outs
        assert ga[:2] == gb[:2] and ga[3:] == gb[3:] and ra == rb
        _close(ga[2], gb[2])
        _close(ua, ub)


@pytest.mark.parametrize("name, seed, k_min, bounded", [
    ("project_few", 8, 2, False),  # (what QPSolver(few_rows=True) sends 2 to FEW_ROWS rows to, either way)
    ("project_few_within", 10, 1, True),  # (the torque level's bounded few-row problems)
    ("project_active", 13, 1, False),  # (the few-row problems with three or more active rows)
])
def test_the_few_row_projections_compiled_as_written(name: str, seed: int, k_min: int, bounded: bool) -> None:
    """Each few-row projection compiled and as written: the same codes, the same floats to the tolerance."""
    rng = np.random.default_rng(seed)
    plain = getattr(projection, name)
    fast = compiled(plain)
    codes = set()
    for _ in range(400):
        k, m = int(rng.integers(k_min, projection.FEW_ROWS + 1)), int(rng.integers(1, 8))
        A = rng.normal(size=(k, m)) * rng.choice([1e-2, 1.0, 1e2])
        u_nom = rng.normal(size=m)
        lb = A @ u_nom + rng.normal(size=k) * np.abs(A).max()
        bounds: tuple[np.ndarray, ...] = ()
        if bounded:
            w = rng.uniform(0.2, 3.0)
            lo = qp_check.NO_BOUND if rng.random() < 0.3 else np.full(m, -w)
            hi = qp_check.NO_BOUND if rng.random() < 0.3 else np.full(m, w)
            bounds = (lo, hi)
        outs = []
        for fn in (plain, fast):
            u, res = np.zeros(m), np.zeros(k)
            code, low = fn(A, lb, u_nom, projection.REL_TOL, *bounds, u, res)
            outs.append((code, low, u, res))
        (ca, la, ua, ra), (cb, lb_, ub, rb) = outs
        assert ca == cb
        codes.add(ca)
        if ca >= 0:
            _close(la, lb_)
            _close(ua, ub)
            _close(ra, rb)
    assert codes == {-1, 0, 1}


def test_the_answer_check_compiled_as_written() -> None:
    """``answer_violation`` (every QP answer's check, either way): the same figures, feasible or not, bounds or none."""
    rng = np.random.default_rng(9)
    fast = compiled(qp_check.answer_violation)
    seen = set()
    for _ in range(400):
        k, m = int(rng.integers(0, 60)), int(rng.integers(1, 8))
        A = rng.normal(size=(k, m)) * rng.choice([1e-6, 1.0, 1e6])
        if k and rng.random() < 0.2:
            A[int(rng.integers(0, k))] = 0.0  # (a zero row: its absolute violation)
        u, u_nom = rng.normal(size=m) * rng.choice([0.1, 10.0]), rng.normal(size=m) * rng.choice([0.1, 10.0])
        res = rng.normal(size=k) * rng.choice([1e-12, 1e-3, 1.0])
        if rng.random() < 0.5:
            res = np.abs(res)  # (every row holds)
        lo = qp_check.NO_BOUND if rng.random() < 0.3 else u - rng.uniform(-1e-3, 1.0, m)
        hi = qp_check.NO_BOUND if rng.random() < 0.3 else u + rng.uniform(-1e-3, 1.0, m)
        if rng.random() < 0.05:
            u[int(rng.integers(0, m))] = rng.choice([np.nan, np.inf])
        if k and rng.random() < 0.05:
            res[int(rng.integers(0, k))] = np.nan
        (va, da), (vb, db) = (fn(A, res, u, u_nom, lo, hi) for fn in (qp_check.answer_violation, fast))
        assert (va == vb or (va != va and vb != vb)) and (da == db or abs(da - db) <= REL * abs(da))
        seen.add("nan" if va != va else "feasible" if da == 0.0 else "violated")
    assert seen == {"nan", "feasible", "violated"}


def test_the_fused_on_step_is_its_parts_composed_compiled_and_as_written() -> None:
    """``promoted_closed_step`` = promote_rows, the promotable rows, screened_closed_step (floor c): same state after."""
    rng = np.random.default_rng(6)
    none_b, none_f, none_i = np.zeros(0, bool), np.zeros(0), np.zeros(0, np.intp)
    fused = compiled(closed_step.promoted_closed_step)
    promoted = 0
    for _ in range(300):
        k, m = int(rng.integers(1, 12)), int(rng.integers(1, 7))
        lf, lg, u_nom, gn, h = _data(rng, k, m)
        lf -= 1.5
        xi = rng.normal(size=k)
        c = float(rng.uniform(0.0, 1.0))
        failing = rng.random(k) < 0.2 if rng.random() < 0.3 else none_b
        ramp_on = bool(rng.random() < 0.6)
        nid = k + 3
        ids = rng.permutation(nid)[:k].astype(np.intp) if ramp_on else none_i
        w0, inw0 = rng.uniform(-0.2, 1.0, nid), rng.random(nid) < 0.5
        rate = float(rng.uniform(0.0, 0.5)) if ramp_on else 0.0
        promotable = rng.random(k) < 0.7 if rng.random() < 0.4 else none_b
        screen = [np.zeros(0), np.full(1, 0.4), rng.uniform(0.1, 2.0, k)][int(rng.integers(0, 3))]
        arg = int(np.argmin(xi))
        few = bool(rng.random() < 0.8)
        lo, hi = _bounds(rng, m)
        outs = []
        for fn in (closed_step.promoted_closed_step, fused, None):
            W, inw = w0.copy(), inw0.copy()
            mask, weights = np.empty(k, bool), np.empty(k) if ramp_on else none_f
            rows, u, res = np.empty(k, np.intp), np.zeros(m), np.zeros(8)
            if fn is None:  # (the parts, one by one)
                handover.promote_rows(xi, c, failing, ramp_on, ids, W, inw, rate, mask, weights)
                if promotable.shape[0]:
                    mask &= promotable
                got = closed_step.screened_closed_step(xi, screen, c, mask, arg, rows, lf, gn, 0.1, np.tanh(h),
                                                       weights, 0.05, lg, u_nom, 1e-9, 1e-9, few, lo, hi, u,
                                                       res)
            else:
                got = fn(xi, c, failing, ramp_on, ids, W, inw, rate, mask, weights, promotable, screen, arg, rows, lf,
                         gn, 0.1, np.tanh(h), 0.05, lg, u_nom, 1e-9, 1e-9, few, lo, hi, u, res)
            outs.append((got, rows[:got[0]].tolist(), u.copy(), mask.copy(), weights.copy(), W, inw))
        base = outs[-1]
        promoted += int(base[3].sum())
        for got, rows, u, mask, weights, W, inw in outs[:-1]:
            assert got[:2] == base[0][:2] and got[3:] == base[0][3:] and rows == base[1]
            _close(got[2], base[0][2])
            _close(u, base[2])
            assert mask.tolist() == base[3].tolist() and inw.tolist() == base[6].tolist()
            _close(weights, base[4])
            _close(W, base[5])
    assert promoted > 100
