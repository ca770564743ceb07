"""predict() of StackedPoints (one compiled pass over every point): the loop's Prediction, bit for bit.

The loop over ``(s, lie, u)`` (numpy, or the filter's kernel per point) is the reference; the stacked
way must give the same ``ok``, ``xi_min`` (the same float), ``first_fail_s``, ``failing`` and
``points``, raise on the same non-finite point, and ask for names only of failing points.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import CustomClassK, LieData, Linear, NonFiniteError, Power, ShapeError
from isf_robot.core import intermittent as im
from isf_robot.core.intermittent import StackedPoints, predict
from isf_robot.core.triggers import xi_on

pytest.importorskip("numba")
pytestmark = pytest.mark.kernels  # (skipped under ISF_ROBOT_JIT=0: tests/conftest.py)

ALPHAS = [Linear(2.0), Power(3.0, 0.7), CustomClassK(lambda h: h + h ** 3, "cubic")]


def _stacked(rng: np.random.Generator, n: int, m: int, short_names: bool = False):  # type: ignore[no-untyped-def]
    """n points with 0..K rows each in stacked arrays (as a compiled rollout lays them out), some rows exactly at Xi = 0."""
    K = int(rng.integers(1, 30))
    rows = rng.integers(0, K + 1, size=n).astype(np.int64)
    h = rng.uniform(-0.05, 0.5, (n, K))
    lf = rng.normal(scale=0.3, size=(n, K))
    g = rng.normal(size=(n, K, m)) * 10.0 ** rng.uniform(-2, 2, size=(n, K, 1))
    gn = np.linalg.norm(g, axis=2)
    zero = rng.random((n, K)) < 0.1  # rows with Xi_on exactly 0 (signed zeros: h = -0.0 too)
    h[zero], lf[zero], gn[zero], g[zero] = rng.choice([0.0, -0.0]), 0.0, 0.0, 0.0
    u = rng.normal(size=(n, m))
    lg = [g[j, :k] for j, k in enumerate(rows.tolist())]
    names = [tuple(f"r{j % 3}_{i}" for i in range(max(k - 2, 0) if short_names else k)) for j, k in enumerate(rows.tolist())]
    asked: list[int] = []

    def point(j: int) -> LieData:
        k = int(rows[j])
        return LieData._of(h[j, :k], lf[j, :k], lg[j], gn[j, :k], names[j])

    def name(j: int, rows: list[int]) -> list[str]:
        asked.append(j)
        return [names[j][i] if i < len(names[j]) else str(i) for i in rows]

    s = [0.01 * (j + 1) for j in range(n)]
    return StackedPoints(s, u, rows, h, lf, lg, gn, point, name), asked


def _same(a, b) -> bool:  # type: ignore[no-untyped-def]
    """The same prediction; the least value to rounding (1e-12 relative: the stacked pass's products may add in
    another order than numpy's)."""
    close = a.xi_min == b.xi_min or abs(a.xi_min - b.xi_min) <= 1e-12 * max(1.0, abs(b.xi_min))
    return close and (a.ok, a.first_fail_s, a.failing, a.points) == (b.ok, b.first_fail_s, b.failing, b.points)


@pytest.mark.parametrize("alpha", ALPHAS, ids=repr)
def test_stacked_points_give_the_loops_prediction(alpha, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(5)
    taken = []
    real = im._predict_stacked
    monkeypatch.setattr(im, "_predict_stacked", lambda *a: taken.append(1) or real(*a))
    kinds = set()
    for i in range(300):
        n, m = int(rng.integers(0, 12)), int(rng.integers(1, 8))
        pts, asked = _stacked(rng, n, m, short_names=i % 5 == 0)
        d_bar = float(rng.choice([0.0, 0.05, 3.0]))
        monkeypatch.setenv("ISF_ROBOT_JIT", "1")
        got = predict(pts, alpha, d_bar)
        fails = {j for j, (_, lie, u) in enumerate(zip(pts.s, [pts[j][1] for j in range(n)], pts.u))
                 if lie.k and float(np.min(xi_on(lie, u, alpha, d_bar))) <= 0}
        assert set(asked) <= fails  # names only of points predicted to fail
        ref_kernel = predict(list(pts), alpha, d_bar)  # the loop, the filter's kernel per point
        monkeypatch.setenv("ISF_ROBOT_JIT", "0")
        ref_numpy = predict(list(pts), alpha, d_bar)
        assert _same(got, ref_kernel) and _same(got, ref_numpy), (got, ref_numpy)
        kinds.add((got.ok, bool(got.failing), got.xi_min == 0.0, any(str(i) in got.failing for i in range(30))))
    assert len(taken) == 300  # the stacked way ran every time
    assert {k[0] for k in kinds} == {True, False} and any(k[2] for k in kinds) and any(k[3] for k in kinds)


def test_a_non_finite_point_raises_as_the_loop_does(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(9)
    for bad in (math.nan, math.inf, 1e308):
        pts, _ = _stacked(rng, 6, 3)
        pts.rows[:] = 4
        pts._rows = pts.rows.tolist()
        pts.lg[:] = [np.zeros((4, 3))] * 6
        pts.h[:, :4] = pts.h[:, :4] ** 2 + 1.0  # every point finite and safe ...
        pts.lf[3, :4] = [bad, bad, 0.0, 0.0]  # ... but point 3 (1e308 twice: a sum that overflows)
        pts._items[:] = [None] * 6
        msgs = []
        for jit in ("1", "0"):
            monkeypatch.setenv("ISF_ROBOT_JIT", jit)
            for p in (pts, list(pts)):
                with pytest.raises(NonFiniteError) as e:
                    predict(p, Linear(1.0), 0.1)
                msgs.append(str(e.value))
        assert len(set(msgs)) == 1 and "0.04 s ahead" in msgs[0]


def test_stacked_points_are_a_sequence_of_points_and_check_their_shapes() -> None:
    rng = np.random.default_rng(2)
    pts, asked = _stacked(rng, 4, 2)
    items = list(pts)
    assert len(pts) == 4 and pts[-1] is items[3] and pts[1:3] == items[1:3] and pts[0][0] == 0.01
    assert items[2][1].lg is pts.lg[2] and items[2][2] is not None and np.shares_memory(items[2][2], pts.u)
    with pytest.raises(IndexError):
        pts[4]
    assert pts.row_names(1, [0, 1]) == list(items[1][1].names[:2]) and asked == []  # (a built point's own names)
    good = (pts.s, pts.u, pts.rows, pts.h, pts.lf, pts.lg, pts.grad_norm, pts._point)
    for i, bad in ((1, pts.u[:3]), (2, pts.rows + pts.h.shape[1] + 1), (2, pts.rows.astype(np.int32)), (3, pts.h[:, :-1]),
                   (4, pts.lf.astype(np.float32)), (5, pts.lg[:3])):
        args = list(good)
        args[i] = bad
        with pytest.raises(ShapeError, match="stacked points"):
            StackedPoints(*args)


def _with_keys(pts: StackedPoints, rng: np.random.Generator) -> StackedPoints:
    """The same points with keys: each distinct row name under one shuffled key; columns past a point's rows garbage."""
    n, K = pts.h.shape
    per_point = [pts.row_names(j, list(range(int(pts.rows[j])))) for j in range(n)]
    distinct = sorted({name for names in per_point for name in names})
    order = rng.permutation(len(distinct)).tolist()
    key_of = {name: order[i] for i, name in enumerate(distinct)}
    key_names = [""] * len(distinct)
    for name, key in key_of.items():
        key_names[key] = name
    keys = rng.integers(-5, 10**6, size=(n, K)).astype(np.int64)  # (past a point's rows: never read)
    for j, names in enumerate(per_point):
        keys[j, :len(names)] = [key_of[x] for x in names]
    return StackedPoints(pts.s, pts.u, pts.rows, pts.h, pts.lf, pts.lg, pts.grad_norm, pts._point, None, keys,
                         tuple(key_names))


@pytest.mark.parametrize("alpha", ALPHAS[:2], ids=repr)
def test_keys_give_the_failing_names_of_the_row_names_way(alpha, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(11)
    monkeypatch.setenv("ISF_ROBOT_JIT", "1")
    failing = 0
    for i in range(200):
        n, m = int(rng.integers(0, 12)), int(rng.integers(1, 8))
        pts, _ = _stacked(rng, n, m, short_names=i % 5 == 0)
        keyed = _with_keys(pts, rng)
        d_bar = float(rng.choice([0.0, 0.05, 3.0]))
        got, ref = predict(keyed, alpha, d_bar), predict(list(pts), alpha, d_bar)
        assert _same(got, ref), (got, ref)
        failing += len(got.failing) > 1
    assert failing > 20  # (several names, each once)


def test_a_key_outside_the_key_names_is_an_error(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("ISF_ROBOT_JIT", "1")
    rng = np.random.default_rng(3)
    pts, _ = _stacked(rng, 5, 2)
    pts.rows[:] = 1
    pts._rows = pts.rows.tolist()
    pts.lg[:] = [np.zeros((1, 2))] * 5
    pts.h[:, 0], pts.lf[:, 0] = -1.0, -1.0  # every point fails its row 0
    keys = np.zeros(pts.h.shape, np.int64)
    keys[2, 0] = 7
    bad = StackedPoints(pts.s, pts.u, pts.rows, pts.h, pts.lf, pts.lg, pts.grad_norm, pts._point, None, keys, ("a", "b"))
    with pytest.raises(ShapeError, match="outside key_names"):
        predict(bad, Linear(1.0), 0.0)
    keys[2, 0] = 1
    good = StackedPoints(pts.s, pts.u, pts.rows, pts.h, pts.lf, pts.lg, pts.grad_norm, pts._point, None, keys, ("a", "b"))
    assert predict(good, Linear(1.0), 0.0).failing == {"a", "b"}
    for args in ((keys, None), (None, ("a", "b")), (keys[:, :0], ("a", "b")), (keys.astype(np.int32), ("a", "b"))):
        with pytest.raises(ShapeError, match="keys"):
            StackedPoints(pts.s, pts.u, pts.rows, pts.h, pts.lf, pts.lg, pts.grad_norm, pts._point, None, *args)


@pytest.mark.parametrize("gain", [0.0, 2.0])
def test_the_prediction_pass_compiled_as_written(gain: float) -> None:
    """``predict_pass`` as written and compiled (one source): the same values, failing rows and keys, bit for bit."""
    from isf_robot.core.jit import compiled
    from isf_robot.core.robust import predict_pass

    rng = np.random.default_rng(4)
    fast = compiled(predict_pass)
    for _ in range(30):
        n, m = int(rng.integers(1, 8)), int(rng.integers(1, 5))
        pts, _ = _stacked(rng, n, m)
        K = pts.h.shape[1]
        lg = np.zeros((n, K, m))
        for j, a in enumerate(pts.lg):
            lg[j, :a.shape[0]] = a
        keys = rng.integers(0, 40, size=(n, K)).astype(np.int64)
        outs = []
        for fn in (predict_pass, fast):
            xi, fails, nfail = np.zeros((n, K)), np.zeros((n, K), np.int64), np.zeros(n, np.int64)
            out, seen = np.zeros(n * K, np.int64), np.zeros(40, np.bool_)
            got = fn(pts.lf, lg, pts.u, pts.grad_norm, 0.1, pts.h, gain, np.tanh(pts.h), pts.rows, xi, fails, nfail,
                     keys, seen, out)
            outs.append((got, xi, [fails[j, :c].tolist() for j, c in enumerate(nfail.tolist())], out[:got[2]]))
        (ga, xa, fa, oa), (gb, xb, fb, ob) = outs
        assert ga == gb and fa == fb and oa.tolist() == ob.tolist()
        for j, k in enumerate(pts.rows.tolist()):
            assert xa[j, :k].tobytes() == xb[j, :k].tobytes()


def test_strided_points_predict_the_same_through_the_one_compiled_pass() -> None:
    """Points in strided arrays (a team's split hands such over) predict as their contiguous copies do, and the
    compiled pass is made for one layout only (numba compiled it once more for strided arrays)."""
    from isf_robot.core.jit import compiled
    from isf_robot.core.robust import predict_pass

    rng = np.random.default_rng(21)
    pts, _ = _stacked(rng, 9, 3)
    wide = lambda a: np.concatenate([a, np.zeros_like(a)], axis=1)[:, : a.shape[1]]  # noqa: E731 (a strided view)
    h, lf, gn = wide(pts.h), wide(pts.lf), wide(pts.grad_norm)
    assert not (h.flags.c_contiguous or lf.flags.c_contiguous or gn.flags.c_contiguous)
    strided = StackedPoints(pts.s, pts.u, pts.rows, h, lf, pts.lg, gn, pts._point, pts._row_names)
    kernel = compiled(predict_pass)
    for alpha in ALPHAS:
        im._predict_stacked(pts, alpha, 0.1, kernel)
    made = set(kernel.signatures)  # (contiguous points: what the pass is made for, with other tests' calls before)
    for alpha in ALPHAS:
        assert _same(im._predict_stacked(strided, alpha, 0.1, kernel), im._predict_stacked(pts, alpha, 0.1, kernel))
    assert set(kernel.signatures) == made  # (strided points compiled nothing more)
