import numpy as np
import pytest

from isf_robot.core import (
    DiscObstacleBarrier,
    IntermittentSafetyFilter,
    Linear,
    MetricsAccumulator,
    SingleIntegrator,
    ZenoError,
    ZenoGuard,
    estimate_miet_constants,
    evaluate_barriers,
    lie_data,
    miet_bound,
    xi_on,
)


def test_miet_bound_formula():
    assert miet_bound(1.0, 2.0, 3.0, 1.0) == pytest.approx(1.0 / (2.0 * 4.0))
    assert miet_bound(1.0, 2.0, 0.0, 0.0) == float("inf")


def test_measured_min_off_period_respects_the_bound():
    # Constant nominal velocity v toward a disc; workspace |p - c| <= R_ws.
    # Xi_on(p) = 2 (p - c) . v + g (|p - c|^2 - r^2): |dXi/dp| = |2 v + 2 g (p - c)| <= 2|v| + 2 g R_ws,
    # B = |v| (the state moves at most at |u|; while off u = v), d_bar = 0.
    v = np.array([1.0, 0.15])
    center, radius, gain, c = np.array([3.0, 0.0]), 0.6, 2.0, 0.5
    barrier = DiscObstacleBarrier(center, radius)
    system = SingleIntegrator(2)
    f = IntermittentSafetyFilter(Linear(gain), c=c, b=0.5, system=system, barriers=[barrier])
    r_ws = 4.0
    L = 2 * np.linalg.norm(v) + 2 * gain * r_ws
    bound = miet_bound(c, L, np.linalg.norm(v))
    x = np.array([0.0, 0.0])
    dt = 1e-3
    acc = MetricsAccumulator()
    # after passing the disc, loop the robot back to the start so events repeat
    for k in range(40_000):
        t = k * dt
        if x[0] > 5.0:
            x = np.array([0.0, x[1] % 0.4 - 0.2])
        step = f.step(t, x, v)
        assert np.linalg.norm(x - center) <= r_ws
        acc.add_step(step, dt)
        x = x + dt * step.u
    m = acc.result()
    assert m.on_switches >= 5
    assert m.min_off_s is not None
    assert m.min_off_s >= bound
    # sampled constants give a bound no larger than the analytic one (they are tighter estimates)
    rng = np.random.default_rng(0)
    samples = center + rng.uniform(-2.8, 2.8, size=(400, 2))
    xi = lambda p: xi_on(lie_data(evaluate_barriers([barrier], p), np.zeros(2), np.eye(2)), v, Linear(gain), 0.0)[0]
    est = estimate_miet_constants(xi, lambda p: v, samples, c)
    assert est.lipschitz_xi <= L + 1e-6
    assert est.bound_s >= bound


def test_zeno_guard_fires_on_accumulating_events():
    g = ZenoGuard(window=5, min_span=1e-3)
    t = 0.0
    with pytest.raises(ZenoError) as info:
        for k in range(10):
            t += 1e-5 * 0.5**k  # converging event times
            g.record(t)
    assert info.value.t <= 1e-4
    g2 = ZenoGuard(min_interval=0.1)
    g2.record(0.0)
    with pytest.raises(ZenoError):
        g2.record(0.05)
    ok = ZenoGuard(window=5, min_span=1e-3)
    for k in range(50):
        ok.record(k * 0.01)


def test_rate_estimate_known_answer_and_never_below_the_product_bound():
    # Xi(x) = a . x + 1 on a linear flow F(x) = M x: dXi/dt = a . M x (+ a_d . d), known state by state
    from isf_robot.core import estimate_miet_rate

    a = np.array([1.0, -2.0, 0.5])
    M = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -0.3]])
    rng = np.random.default_rng(1)
    xs = rng.uniform(-1.0, 1.0, size=(300, 3))
    c, d = 0.2, 0.05
    est = estimate_miet_rate(lambda x: float(a @ x) + 1.0, lambda x: M @ x, xs, c, d, disturbed=(1, 2))
    want = max(abs(float(a @ M @ x)) for x in xs) + float(np.linalg.norm(a[1:])) * d
    assert est.rate_bound == pytest.approx(want, rel=1e-8)
    assert est.bound_s == pytest.approx(c / want, rel=1e-8) and est.samples == 300
    prop1 = estimate_miet_constants(lambda x: float(a @ x) + 1.0, lambda x: M @ x, xs, c, d)
    assert est.bound_s >= prop1.bound_s  # the same argument, suprema taken jointly
    # a state-independent gradient orthogonal to the flow: no rate, no finite bound
    flat = estimate_miet_rate(lambda x: float(x[2]), lambda x: np.array([1.0, 0.0, 0.0]), xs, c)
    assert flat.rate_bound == pytest.approx(0.0, abs=1e-6) or flat.bound_s > 1e5
    from isf_robot.core import ConfigError

    with pytest.raises(ConfigError, match="at least one sample"):
        estimate_miet_rate(lambda x: 0.0, lambda x: x, [], c)
    with pytest.raises(ConfigError, match="d_bar"):
        estimate_miet_rate(lambda x: 0.0, lambda x: x, xs, c, -1.0)
