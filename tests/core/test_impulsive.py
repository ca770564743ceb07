"""A toy impulsive system with closed-form flows.

State x = (p, v): flow p' = v, v' = -a (a constant pull toward the boundary p = 0);
jump v+ = v + dv. Barrier h = p. Greedy trigger Xi = LF h + k h = v + k p.
Safeguarding controller: set v to V > 0, so Xi(x+) = V + k p >= V >= c.
"""

import math

import numpy as np
import pytest

from isf_robot.core import (
    ConfigError,
    EventTriggeredImpulsiveController,
    FunctionBarrier,
    Linear,
    ManeuverScheduler,
    PostJumpConditionError,
    ZenoError,
    ZenoGuard,
)

A, K, V, C = 1.0, 2.0, 1.5, 1.0


def make(controller=None, c=C, zeno=None):
    barrier = FunctionBarrier(lambda x, t: x[0], lambda x, t: np.array([1.0, 0.0]), name="p")
    return EventTriggeredImpulsiveController(
        flow_model=lambda t, x: np.array([x[1], -A]),
        jump_map=lambda x, dv: x + np.array([0.0, dv[0]]),
        barrier=barrier,
        controller=controller or (lambda t, x: np.array([V - x[1]])),
        alpha=Linear(K),
        c=c,
        zeno=zeno,
    )


def flow(x, s):
    return np.array([x[0] + x[1] * s - 0.5 * A * s * s, x[1] - A * s])


def time_to_trigger(x):
    # Xi(s) = v - A s + K (p + v s - A s^2 / 2) = 0  ->  -K A/2 s^2 + (K v - A) s + (v + K p) = 0
    p, v = x
    qa, qb, qc = -K * A / 2, K * v - A, v + K * p
    disc = qb * qb - 4 * qa * qc
    return (-qb - math.sqrt(disc)) / (2 * qa)


def run_greedy(x0, n_jumps):
    ctrl = make()
    t, x = 0.0, np.array(x0, float)
    times = []
    for _ in range(n_jumps):
        s = time_to_trigger(x)
        t += s
        x = flow(x, s)
        assert ctrl.xi(t, x) == pytest.approx(0.0, abs=1e-9)
        ev = ctrl.apply_jump(t, x)
        x = ev.x_after
        times.append(t)
    return ctrl, np.array(times)


def test_greedy_trigger_times_match_closed_form_and_stay_safe():
    ctrl, times = run_greedy([2.0, 0.0], 6)
    # after the first jump every flow starts at v = V from the trigger point; check each interval
    for ev in ctrl.jumps:
        assert ev.h_after >= 0.0
        assert ev.xi_after >= C
        assert ev.x_after[0] == ev.x_before[0]  # position unchanged by an impulse
    # interval i+1 is the closed-form trigger time from the post-jump state of jump i
    for prev, nxt in zip(ctrl.jumps[:-1], ctrl.jumps[1:]):
        assert nxt.interval_s == pytest.approx(time_to_trigger(prev.x_after), rel=1e-12)
    np.testing.assert_allclose(np.diff(times), ctrl.inter_event_times)
    # safety along the flow: p(s) >= 0 between jumps (sample finely)
    for prev, nxt in zip(ctrl.jumps[:-1], ctrl.jumps[1:]):
        s = np.linspace(0, nxt.interval_s, 200)
        assert np.all(prev.x_after[0] + V * s - 0.5 * A * s**2 >= 0)


def test_post_jump_condition_failure_raises():
    weak = make(controller=lambda t, x: np.array([0.2 - x[1]]))  # Xi(x+) = 0.2 + K p < c near p = 0
    with pytest.raises(PostJumpConditionError) as info:
        weak.apply_jump(1.0, np.array([0.1, -0.5]))
    assert info.value.xi_after == pytest.approx(0.2 + K * 0.1)
    assert info.value.c == C
    unsafe = make(controller=lambda t, x: np.array([5.0]))
    barrier_breaker = EventTriggeredImpulsiveController(
        unsafe.flow_model, lambda x, dv: np.array([-1.0, 10.0]), unsafe.barrier, unsafe.controller, Linear(K), C)
    with pytest.raises(PostJumpConditionError, match="h\\(G"):
        barrier_breaker.apply_jump(0.0, np.array([0.5, 0.0]))


def test_zeno_guard_stops_repeated_jumps_at_one_instant():
    ctrl = make(zeno=ZenoGuard(window=4, min_span=1e-6))
    with pytest.raises(ZenoError):
        for _ in range(10):
            ctrl.apply_jump(1.0, np.array([0.5, 0.0]))


def test_maneuver_scheduler_alternates_and_gates():
    ctrl = make()
    sched = ManeuverScheduler(ctrl, tau_p=lambda h: 2.0 + h, dtau_p_dh=lambda h: 1.0)
    assert sched.phase == "first"
    with pytest.raises(ConfigError):
        sched.apply_jump(0.0, np.array([1.0, 0.0]), "tau")
    ev = sched.apply_jump(1.0, np.array([0.5, -0.3]), "greedy")
    assert sched.phase == "second"
    assert sched.gate_time == pytest.approx(1.0 + 2.0 + ev.h_after)
    with pytest.raises(ConfigError):
        sched.apply_jump(1.5, np.array([0.5, 0.0]), "tau")  # before the gate
    # Xi_tau = (1 + tau' LF h) / 2 with LF h = v
    assert sched.xi_tau(2.0, np.array([0.4, -3.0])) == pytest.approx((1 + 1.0 * -3.0) / 2)
    sched.apply_jump(sched.gate_time + 0.1, np.array([0.6, -1.0]), "tau")
    assert sched.phase == "first" and sched.gate_time is None
    sched.apply_jump(9.0, np.array([0.1, -0.2]), "greedy")
    sched.apply_jump(9.5, np.array([0.1, -0.2]), "safe")  # safety may fire the second impulse early
    assert [j.kind for j in ctrl.jumps] == ["greedy", "tau", "greedy", "safe"]
