import numpy as np
import pytest

from isf_robot.core import ConfigError, IntermittentSafetyFilter, LieData, Linear, OnOffTrigger


class FakeClock:
    def __init__(self, dt=0.1):
        self.t = 0.0
        self.dt = dt

    def tick(self):
        self.t += self.dt
        return self.t


def drive(trigger, xis, clock=None):
    clock = clock or FakeClock()
    modes, events = [], []
    for xi in xis:
        ev = trigger.update(clock.tick(), xi)
        modes.append(trigger.on)
        if ev:
            events.append(ev)
    return modes, events


def test_on_at_zero_off_only_at_c():
    trig = OnOffTrigger(c=1.0)
    script = [2.0, 0.5, 0.0, -0.3, 0.2, 0.9, 0.99, 1.0, 0.7, 0.3, -0.1]
    modes, events = drive(trig, script)
    assert modes == [False, False, True, True, True, True, True, False, False, False, True]
    assert [e.kind for e in events] == ["on", "off", "on"]
    # off happens at the first sample with Xi >= c, not earlier
    assert events[1].xi_min == pytest.approx(1.0)
    assert events[1].t == pytest.approx(0.8)
    assert events[1].duration_s == pytest.approx(0.8 - 0.3)  # on period length
    assert events[2].duration_s == pytest.approx(1.1 - 0.8)  # off period length


def test_no_chattering_between_zero_and_c():
    rng = np.random.default_rng(0)
    trig = OnOffTrigger(c=0.5)
    clock = FakeClock()
    drive(trig, [-1.0], clock)
    assert trig.on
    # Xi oscillating strictly inside (0, c): no switch at all
    modes, events = drive(trig, list(rng.uniform(1e-6, 0.5 - 1e-6, 500)), clock)
    assert all(modes) and events == []
    # the same band while off: stays off
    drive(trig, [0.6], clock)
    assert not trig.on
    modes, events = drive(trig, list(rng.uniform(1e-6, 0.5 - 1e-6, 500)), clock)
    assert not any(modes) and events == []


def test_literal_paper_sign_would_switch_off_immediately_but_ours_does_not():
    # The paper's Xi_off = Xi_on - c <= 0 holds right at the on-time. Our trigger must stay on.
    trig = OnOffTrigger(c=0.5)
    clock = FakeClock()
    drive(trig, [-0.2], clock)
    assert trig.on
    drive(trig, [-0.2 + 0.01 * k for k in range(60)], clock)  # rises to 0.39 < c
    assert trig.on


def test_time_must_not_go_backwards_and_nan_rejected():
    trig = OnOffTrigger(c=1.0)
    trig.update(1.0, 2.0)
    with pytest.raises(ConfigError):
        trig.update(0.5, 2.0)
    with pytest.raises(ConfigError):
        trig.update(2.0, float("nan"))


def test_off_hold_asks_the_off_condition_to_have_held_that_long():
    # clock 0.125 s (exact in binary); hold 0.375 s: on at 0.125 (Xi <= 0: the condition fails there); the
    # condition (Xi >= c = 1) holds from 0.25, fails again at 0.5 (the hold starts over), holds from 0.625: off at
    # 0.875, 0.375 s after the last failure
    script = [-1.0, 2.0, 2.0, 0.5, 2.0, 2.0, 2.0, 2.0]
    trig = OnOffTrigger(c=1.0, off_hold=0.375)
    modes, events = drive(trig, script, FakeClock(0.125))
    assert modes == [True, True, True, True, True, True, False, False]
    assert [(e.kind, e.t) for e in events] == [("on", 0.125), ("off", 0.875)]
    # without the hold: off at the first sample at or above c, as before
    modes, _ = drive(OnOffTrigger(c=1.0), script, FakeClock(0.125))
    assert modes == [True, False, False, False, False, False, False, False]
    # a hold never delays the on trigger, and a filter that was never on has nothing to hold
    trig = OnOffTrigger(c=1.0, off_hold=10.0)
    assert drive(trig, [2.0, 2.0, 0.0])[0] == [False, False, True]
    # reset forgets the last failure; starting on counts as failing at t0
    trig.reset(5.0, start_on=True)
    assert trig.update(5.2, 2.0) is None and trig.on  # held 0.2 < 10
    trig.reset(0.0)
    assert not trig.on
    for bad in (-0.1, True, "0.1", None):
        with pytest.raises(ConfigError, match="off_hold"):
            OnOffTrigger(c=1.0, off_hold=bad)


def test_the_filters_off_hold_keeps_it_on_and_its_constraints_enforced():
    # Xi_on = u_nom + h (one row, Lg h = 1); on at Xi <= 0, pushed at b while held, off after 0.375 s of Xi >= c
    f = IntermittentSafetyFilter(Linear(1.0), c=0.5, b=0.2, off_hold=0.375)
    clock = FakeClock(0.125)
    lie = LieData(np.array([0.1]), np.zeros(1), np.ones((1, 1)), np.ones(1), ("b",))
    assert f.step_lie(clock.tick(), lie, np.array([-0.2])).on
    steps = [f.step_lie(clock.tick(), lie, np.array([0.0 if k < 3 else 1.0])) for k in range(7)]
    # Xi 0.1 (< c) at 0.25-0.5, 1.1 from 0.625: the condition last failed at 0.5, off at 0.875
    assert [s.on for s in steps] == [True] * 5 + [False] * 2
    assert all(s.u[0] >= 0.2 - 1e-9 for s in steps[:5])  # promoted while held on (u >= b)
    assert steps[5].event is not None and steps[5].event.kind == "off" and steps[5].t == 0.875
    f.reset()
    assert not f.on and f.trigger.off_hold == 0.375 and f.spec.as_info()["off_hold"] == 0.375
    plain = IntermittentSafetyFilter(Linear(1.0), c=0.5, b=0.2, off_hold=None)  # (None: no hold, none recorded)
    assert plain.trigger.off_hold == 0.0 and "off_hold" not in plain.spec.as_info()


def test_intermittent_filter_modes_follow_trigger_with_scripted_xi():
    # one barrier with Lg h = 1, Lf h = 0, alpha = 1*h: Xi_on = u_nom + h
    f = IntermittentSafetyFilter(Linear(1.0), c=0.5, b=0.2)
    clock = FakeClock(0.01)
    seen = []
    for h, u_nom in [(1.0, 0.0), (0.1, -0.2), (0.1, -0.05), (0.3, 0.0), (0.6, 0.0), (0.4, 0.0)]:
        lie = LieData(np.array([h]), np.zeros(1), np.ones((1, 1)), np.ones(1), ("b",))
        step = f.step_lie(clock.tick(), lie, np.array([u_nom]))
        seen.append((step.on, step.event.kind if step.event else None, step.u[0]))
    # Xi = 1.0 off; -0.1 -> on (promote: u >= b = 0.2); 0.05 stays on; 0.3 on; 0.6 >= c off; 0.4 off
    assert [s[0] for s in seen] == [False, True, True, True, False, False]
    assert [s[1] for s in seen] == [None, "on", None, None, "off", None]
    assert seen[1][2] == pytest.approx(0.2, abs=1e-9)
    assert seen[4][2] == 0.0  # nominal passes through when off
    assert f.qp_solves == 3


def test_several_barriers_promote_only_those_below_c():
    f = IntermittentSafetyFilter(Linear(1.0), c=0.5, b=0.3)
    lg = np.eye(2)
    # barrier 0: Xi = -0.2 (promote), barrier 1: Xi = 5 (robust only)
    lie = LieData(np.array([0.1, 5.0]), np.zeros(2), lg, np.ones(2), ("a", "b"))
    step = f.step_lie(0.0, lie, np.array([-0.3, 0.0]))
    assert step.on and step.qp.status in ("optimal", "closed_form")
    assert step.u[0] == pytest.approx(0.3, abs=1e-8)  # promoted: dh0/dt >= b
    assert step.u[1] == pytest.approx(0.0, abs=1e-8)  # robust row inactive: untouched
