"""Designed off periods, the predictive off trigger and the smooth hand-over of the intermittent
filter (core/intermittent.py), driven by a fake clock and scripted barrier data."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from isf_robot.core import ConfigError, IntermittentSafetyFilter, IsfWarning, LieData, Linear, SafetyFilter
from isf_robot.core.intermittent import FallRateBound, OffPredictor, predict
from isf_robot.core.triggers import OnOffTrigger, xi_on

DT = 0.01


def _one_row(xi: float, name: str = "a") -> LieData:
    """A 1-D row whose Xi_on under u_nom = 0 (alpha 1, d_bar 0) is ``xi``: h = xi, Lf h = 0."""
    return LieData(np.array([xi]), np.zeros(1), np.array([[1.0]]), np.ones(1), (name,))


def test_fall_rate_is_measured_over_off_intervals_only():
    fr = FallRateBound(forget_s=math.inf)
    t = 0.0
    for xi in (1.0, 0.9, 0.8):  # off: falls 10 per s
        fr.observe(t, xi, off=True)
        t += DT
    assert fr.rate == pytest.approx(10.0)
    fr.observe(t, 0.0, off=False)  # the interval before was on: a fall of 80 per s is not counted
    assert fr.rate == pytest.approx(10.0)
    assert fr.samples == 2
    assert fr.margin(0.25, 0.05, 1.0) == pytest.approx(1.0)  # 2.5 capped at c_max
    assert fr.margin(0.05, 0.05, 1.0) == pytest.approx(0.5)
    assert fr.margin(0.001, 0.05, 1.0) == pytest.approx(0.05)  # never below c
    assert fr.bound_s(0.5) == pytest.approx(0.05)


def test_fall_rate_forgets_with_its_time_constant():
    fr = FallRateBound(forget_s=1.0)
    fr.observe(0.0, 1.0, True)
    fr.observe(0.1, 0.9, True)
    assert fr.rate == pytest.approx(1.0)
    fr.observe(1.1, 0.9, True)  # flat for 1 s
    assert fr.rate == pytest.approx(math.exp(-1.0))


def test_trigger_margin_and_allow_off():
    trig = OnOffTrigger(c=0.1)
    assert trig.update(0.0, -1.0) is not None and trig.on
    assert trig.update(0.1, 0.5, margin=1.0) is None and trig.on  # below the designed margin
    assert trig.update(0.2, 2.0, margin=1.0, allow_off=False) is None and trig.on  # held
    assert trig.update(0.3, 0.05, margin=0.01) is None  # a margin below c is raised to c
    ev = trig.update(0.4, 1.0, margin=1.0)
    assert ev is not None and ev.kind == "off"
    assert trig.update(0.5, 0.0, allow_off=False) is not None and trig.on  # on is never delayed


def _drive(filt, xis, t0=0.0):
    t, steps = t0, []
    for xi in xis:
        steps.append(filt.step_lie(t, _one_row(xi), np.zeros(1)))
        t += DT
    return steps


def test_min_off_designs_the_margin_from_the_measured_fall_rate():
    f = IntermittentSafetyFilter(Linear(1.0), c=0.01, b=0.1, min_off=0.2, c_max=10.0, fall_rate_forget=math.inf)
    # off, Xi falling at 5 per s to 0: the filter turns on
    steps = _drive(f, [0.5, 0.45, 0.4, 0.35, 0.3, 0.25, 0.2, 0.15, 0.1, 0.05, 0.0])
    assert steps[-1].event is not None and steps[-1].event.kind == "on"
    assert f.fall_rate.rate == pytest.approx(5.0)
    assert f.margin() == pytest.approx(1.0)  # 0.2 s x 5 per s
    # the measured rate is 5 per s up to rounding (the margin is 1.0 + a few ulp): step past it
    more = _drive(f, [0.2, 0.5, 0.99, 1.001], t0=11 * DT)
    assert [s.on for s in more] == [True, True, True, False]  # off only at Xi >= 1.0, not at c = 0.01
    assert more[-1].off_bound_s == pytest.approx(0.2)
    assert more[-1].margin == pytest.approx(1.0)


def test_without_options_the_margin_is_c_and_the_bound_uses_the_measured_rate():
    f = IntermittentSafetyFilter(Linear(1.0), c=0.1, b=0.1, fall_rate_forget=math.inf)
    steps = _drive(f, [0.3, 0.2, 0.1, 0.0, 0.05, 0.1])
    assert [s.on for s in steps] == [False, False, False, True, True, False]
    assert steps[-1].off_bound_s == pytest.approx(0.1 / 10.0)


class ScriptedRollout:
    def __init__(self, outcomes):
        self.outcomes = list(outcomes)
        self.calls = []

    def __call__(self, t, x=None):
        self.calls.append(t)
        xi_pred = self.outcomes.pop(0)
        return [(0.1, _one_row(xi_pred, "a"), np.zeros(1)), (0.2, _one_row(1.0, "b"), np.zeros(1))]


def test_predictive_off_waits_for_a_good_prediction_every_k_steps():
    roll = ScriptedRollout([-0.5, -0.2, 0.3])
    f = IntermittentSafetyFilter(Linear(1.0), c=0.1, b=0.1, rollout=roll, predict_every=3)
    steps = _drive(f, [0.0] + [0.5] * 7)
    # t=0: on. From t=0.01 the off condition holds; rollouts at 0.01, 0.04, 0.07 (every 3 steps)
    assert roll.calls == pytest.approx([0.01, 0.04, 0.07])
    assert [s.rollout for s in steps] == [False, True, False, False, True, False, False, True]
    assert [s.on for s in steps] == [True] * 7 + [False]
    assert [s.held for s in steps] == [False] + [True] * 6 + [False]
    assert f.predictor.rollouts == 3


def test_prediction_never_delays_switching_on_and_restarts_when_the_condition_breaks():
    roll = ScriptedRollout([-1.0, 1.0])
    f = IntermittentSafetyFilter(Linear(1.0), c=0.1, b=0.1, rollout=roll, predict_every=100)
    steps = _drive(f, [0.0, 0.5, 0.05, 0.5])
    assert len(roll.calls) == 2  # the break at 0.05 (below c) forces a fresh rollout at the next step
    assert [s.on for s in steps] == [True, True, True, False]
    steps = _drive(f, [0.2, -0.01], t0=1.0)  # off; Xi <= 0 turns it on with no rollout at all
    assert [s.on for s in steps] == [False, True] and len(roll.calls) == 2


def test_held_steps_promote_the_rows_predicted_to_fail():
    seen = []

    def roll(t, x=None):
        seen.append(x)
        return [(0.1, LieData(np.array([-0.1]), np.zeros(1), np.array([[0.0, 1.0]]), np.ones(1), ("far",)),
                 np.zeros(2))]

    f = IntermittentSafetyFilter(Linear(1.0), c=0.1, b=0.5, rollout=roll)
    lie = LieData(np.array([0.0, 2.0]), np.zeros(2), np.eye(2), np.ones(2), ("near", "far"))
    f.step_lie(0.0, lie, np.zeros(2))  # on (near: Xi = 0)
    lie2 = LieData(np.array([1.0, 2.0]), np.zeros(2), np.eye(2), np.ones(2), ("near", "far"))
    step = f.step_lie(DT, lie2, np.zeros(2), x=np.array([7.0]))
    assert step.on and step.held
    assert len(seen) == 1 and seen[0] is not None and seen[0][0] == 7.0  # the state reaches the rollout
    assert step.qp is not None
    assert step.u[1] == pytest.approx(0.5, abs=1e-6)  # "far" promoted: dh/dt >= b
    assert step.u[0] == pytest.approx(0.0, abs=1e-6)  # "near" robust only (Xi >= c)


def test_predict_matches_a_direct_evaluation():
    rng = np.random.default_rng(3)
    alpha = Linear(2.0)
    pts = []
    for s in (0.05, 0.1, 0.15):
        lie = LieData(rng.uniform(0, 1, 4), rng.normal(size=4), rng.normal(size=(4, 3)), np.ones(4),
                      tuple("abcd"))
        pts.append((s, lie, rng.normal(size=3)))
    p = predict(pts, alpha, 0.1)
    xis = [xi_on(lie, u, alpha, 0.1) for _, lie, u in pts]
    assert p.xi_min == pytest.approx(min(float(x.min()) for x in xis))
    assert p.ok == all(float(x.min()) > 0 for x in xis)
    bad = {n for (_, lie, _), x in zip(pts, xis) for n, v in zip(lie.names, x) if v <= 0}
    assert p.failing == bad


def test_bad_options_are_refused():
    with pytest.raises(ConfigError, match="min_off"):
        IntermittentSafetyFilter(1.0, 0.1, 0.1, min_off=-1.0)  # (0: none, the fixed margin)
    with pytest.raises(ConfigError, match="c_max"):
        IntermittentSafetyFilter(1.0, 0.1, 0.1, c_max=0.01)
    with pytest.raises(ConfigError, match="blend"):
        IntermittentSafetyFilter(1.0, 0.1, 0.1, blend=-1.0)
    with pytest.raises(ConfigError, match="predict_every"):
        OffPredictor(lambda t, x: [], every=0)


def test_off_switch_hands_over_without_a_step():
    f = IntermittentSafetyFilter(Linear(1.0), c=0.1, b=1.0, blend=0.05)
    lie_on = LieData(np.array([0.0]), np.zeros(1), np.array([[1.0, 0.0]]), np.ones(1), ("a",))
    on = f.step_lie(0.0, lie_on, np.array([0.0, 0.3]))
    assert on.on and on.u[0] == pytest.approx(0.0)  # first on step: the robust condition only
    on2 = f.step_lie(0.02, lie_on, np.array([0.0, 0.3]))
    assert on2.u[0] > 0.0 and on2.u[0] < 1.0  # promotion level ramping toward b
    far = LieData(np.array([5.0]), np.zeros(1), np.array([[1.0, 0.0]]), np.ones(1), ("a",))
    u_nom = np.array([-1.0, 0.3])
    u_last = f.step_lie(0.05, lie_on, np.array([0.0, 0.3])).u
    off = [f.step_lie(0.06 + i * DT, far, u_nom) for i in range(8)]
    assert off[0].event is not None and off[0].event.kind == "off"
    np.testing.assert_allclose(off[0].u, u_last)  # no step at the switch
    jumps = [np.linalg.norm(b.u - a.u) for a, b in zip(off, off[1:])]
    assert max(jumps) <= np.linalg.norm(u_last - u_nom) * DT / 0.05 + 1e-12
    np.testing.assert_allclose(off[-1].u, u_nom)  # the nominal after the blend


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 4), st.integers(0, 2))
def test_blend_never_violates_the_robust_condition(seed: int, k: int, extra: int):
    # m >= k inputs: a random Lg has full row rank, so every robust condition can be met (the
    # infeasibility proof behind a fallback costs ~0.1 s a step and proves nothing about the blend)
    m = k + extra
    rng = np.random.default_rng(seed)
    alpha, d_bar = Linear(float(rng.uniform(0.5, 5))), float(rng.uniform(0, 0.2))
    f = IntermittentSafetyFilter(alpha, c=0.05, b=float(rng.uniform(0.01, 1)), d_bar=d_bar, blend=0.1,
                                 on_infeasible="fallback")
    cbf = SafetyFilter(alpha, d_bar, on_infeasible="fallback")
    t = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IsfWarning)
        for _ in range(40):
            lg = rng.normal(size=(k, m))
            lie = LieData(rng.uniform(0, 1, k), rng.normal(size=k), lg, np.linalg.norm(lg, axis=1))
            u_nom = rng.normal(size=m)
            step = f.step_lie(t, lie, u_nom)
            t += DT
            if step.fallback:
                continue
            slack = lie.lf + lg @ step.u - lie.grad_norm * d_bar + alpha.vector(lie.h)
            assert slack.min() >= -1e-7, (step.on, slack)
            if step.event is not None and step.event.kind == "on":  # the on step: what safety requires
                ref = cbf.step_lie(t, lie, u_nom)
                if not ref.fallback:
                    np.testing.assert_allclose(step.u, ref.u, atol=1e-6)


def test_a_row_promoted_while_on_ramps_in_instead_of_stepping():
    f = IntermittentSafetyFilter(Linear(1.0), c=0.5, b=1.0, blend=0.04)
    lg = np.eye(2)

    def lie(h_a, h_b):
        return LieData(np.array([h_a, h_b]), np.zeros(2), lg, np.ones(2), ("a", "b"))

    assert f.step_lie(0.0, lie(0.0, 2.0), np.zeros(2)).on  # "a" triggers; "b" far (Xi = 2 >= c)
    f.step_lie(DT, lie(0.1, 2.0), np.zeros(2))
    # "b" falls below c while on: promoted, its level ramps from -alpha(h) = -0.3 toward b = 1
    ub = [f.step_lie((2 + i) * DT, lie(0.1, 0.3), np.zeros(2)).u[1] for i in range(6)]
    assert ub[0] == pytest.approx(0.0, abs=1e-9)  # ramp 0: the robust condition, met by u_nom
    assert ub[1] == pytest.approx(0.25 * 1.0 + 0.75 * -0.3, abs=1e-6)
    assert ub[4] == pytest.approx(1.0, abs=1e-6) and ub[5] == pytest.approx(1.0, abs=1e-6)
    assert all(b - a <= 0.33 + 1e-9 for a, b in zip(ub, ub[1:]))  # no step beyond the ramp's


def test_a_row_leaving_the_promotion_set_ramps_down_instead_of_dropping():
    f = IntermittentSafetyFilter(Linear(1.0), c=0.5, b=1.0, blend=0.04)
    lie_a = LieData(np.array([0.0, 0.1]), np.zeros(2), np.eye(2), np.ones(2), ("a", "b"))
    lie_b = LieData(np.array([0.0, 0.9]), np.zeros(2), np.eye(2), np.ones(2), ("a", "b"))  # "b": Xi 0.9 >= c
    f.step_lie(0.0, lie_a, np.zeros(2))  # on; both rows promoted, weights 0
    ub = [f.step_lie((1 + i) * DT, lie_a, np.zeros(2)).u[1] for i in range(4)]
    assert ub[-1] == pytest.approx(1.0, abs=1e-6)  # fully ramped: dh_b/dt >= b
    down = [f.step_lie((5 + i) * DT, lie_b, np.zeros(2)).u[1] for i in range(6)]
    assert down[0] == pytest.approx(0.75 * 1.0 + 0.25 * -0.9, abs=1e-6)  # one step of 0.25 down, not 0
    assert down[-1] == pytest.approx(0.0, abs=1e-9)  # released: u_nom meets the robust condition
    assert all(a - b <= 0.25 * 1.9 + 1e-9 for a, b in zip([ub[-1]] + down, down))


def _ramp_reference(state: dict, t: float, names: tuple, promote: np.ndarray, blend: float) -> tuple:
    """The hand-over ramp as written before its per-names cache: a dict of the rows' flags per step."""
    w = state["w"]
    k = promote.size
    keys = names if len(names) == k else range(k)
    rate = (t - state["t"]) / blend if state["t"] is not None else 0.0
    state["t"] = t
    now = dict(zip(keys, promote.tolist()))
    for n in list(w):
        if not now.get(n, False):
            w[n] -= rate
            if w[n] <= 0.0:
                del w[n]
    for n in {keys[i] for i in promote.nonzero()[0].tolist()}:
        if now[n]:
            w[n] = min(1.0, w[n] + rate) if n in w else 0.0
    if not w:
        return np.zeros(k, bool), np.ones(k)
    weights = np.array([w.get(n, -1.0) for n in keys])
    mask = weights >= 0.0
    weights[~mask] = 1.0
    return mask, weights


def test_row_ramp_equals_the_reference_with_repeated_and_changing_names() -> None:
    rng = np.random.default_rng(8)
    tables = [("a", "b", "c", "a"), ("a", "b", "c", "a"), ("b", "d"), ("x",) * 3, tuple(f"r{i}" for i in range(9))]
    from isf_robot.core.handover import PromotionRamp, promote_rows
    from isf_robot.core.jit import compiled

    ways = [PromotionRamp(promote_rows), PromotionRamp(compiled(promote_rows))]  # (as written; compiled)
    state: dict = {"w": {}, "t": None}
    t, t_prev, ramping = 0.0, None, 0
    for step in range(3000):
        names = tables[(step // 40) % len(tables)]
        k = len(names) if step % 13 else len(names) + 1  # sometimes a row count that does not match the names
        if step % 40 == 0:
            names = tuple(list(names))  # (an equal tuple, another object now and then)
        promote = rng.random(k) < 0.3
        t += 0.001 if step % 97 else -0.0005  # time going back once in a while
        ref_mask, ref_weights = _ramp_reference(state, t, names, promote, 0.02)
        rate = (t - t_prev) / 0.02 if t_prev is not None else 0.0
        t_prev = t
        for way in ways:  # (promoted: the failing rows; every Xi_on above c)
            mask, weights = way(np.ones(k), 0.1, promote, rate, names)
            assert mask.tolist() == ref_mask.tolist(), step
            np.testing.assert_allclose(weights, ref_weights, rtol=0, atol=1e-12, err_msg=str(step))
            assert way.weights().keys() == state["w"].keys()
        ramping += int(np.any((weights > 0.0) & (weights < 1.0)))
    assert ramping > 500  # the ramps were exercised, not only 0 and 1


def test_reset_returns_every_filter_to_off_and_forgets_its_history() -> None:
    # the hysteresis itself must be reset: a filter that was on starts the next episode off, and its next
    # step with Xi_on between 0 and c stays off (it would stay on if the on mode survived reset)
    from isf_robot.core import LieData, SafetyFilter

    lie_bad = LieData(np.array([0.01]), np.array([-5.0]), np.array([[1.0]]), np.array([1.0]), ("a",))
    lie_mid = LieData(np.array([0.5]), np.array([-0.45]), np.array([[1.0]]), np.array([1.0]), ("a",))
    f = IntermittentSafetyFilter(1.0, 0.2, 0.05, 0.0)
    assert f.step_lie(0.0, lie_bad, np.zeros(1)).on
    assert f.step_lie(0.01, lie_mid, np.zeros(1)).on  # Xi_on = 0.05 < c: stays on
    f.reset(0.0)
    assert not f.on and f.trigger.n_on == 0 and f.qp_solves == 0
    s = f.step_lie(0.0, lie_mid, np.zeros(1))
    assert not s.on and s.event is None and s.qp is None
    cbf = SafetyFilter(1.0, 0.0)
    assert cbf.step_lie(0.0, lie_bad, np.zeros(1)).on
    cbf.reset()
    assert not cbf.on and cbf.qp_solves == 0


def test_the_off_predictor_takes_a_rollouts_own_prediction_where_it_answers():
    """A rollout with ``prediction(t, x, alpha, d_bar)`` answers the check itself; ``None`` sends it the long way."""

    class Rollout:
        def __init__(self) -> None:
            self.answer = None
            self.asked: list[str] = []

        def __call__(self, t, x):  # type: ignore[no-untyped-def]
            self.asked.append("points")
            return [(0.1, _one_row(-0.5), np.zeros(1))]

        def prediction(self, t, x, alpha, d_bar):  # type: ignore[no-untyped-def]
            self.asked.append("prediction")
            return self.answer

    roll = Rollout()
    pred = OffPredictor(roll, every=1)
    got, ran = pred.check(0.0, None, Linear(1.0), 0.0)
    assert ran and roll.asked == ["prediction", "points"]
    assert repr(got) == repr(predict(roll(0.0, None), Linear(1.0), 0.0)) and not got.ok and got.failing == {"a"}
    roll.asked.clear()
    roll.answer = predict([(0.1, _one_row(0.5), np.zeros(1))], Linear(1.0), 0.0)
    got, ran = pred.check(0.01, None, Linear(1.0), 0.0)
    assert ran and got is roll.answer and roll.asked == ["prediction"]
