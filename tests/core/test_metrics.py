import numpy as np
import pytest

from isf_robot.core import MetricsAccumulator, compute_metrics


def test_known_sequence():
    on = np.array([0, 0, 1, 1, 0, 0, 0, 1, 0, 0], bool)  # dt = 0.5
    t = np.arange(10) * 0.5
    rate = np.where(on, 4.0, 0.0)
    m = compute_metrics(t, 0.5, on, rate, on)
    assert m.duration_s == 5.0
    assert m.duty_cycle == pytest.approx(0.3)
    assert m.on_switches == 2
    assert m.off_switches == 2
    # complete off periods: steps 4-6 only (the first is cut by the start, the last by the end)
    assert m.min_off_s == pytest.approx(1.5)
    assert m.mean_off_s == pytest.approx(1.5)
    assert m.mean_on_s == pytest.approx((1.0 + 0.5) / 2)
    assert m.intervention == pytest.approx(4.0 * 0.5 * 3)
    assert m.qp_solves == 3


def test_no_complete_off_period_gives_none_and_start_on_counts_a_switch():
    m = compute_metrics(np.arange(4.0), 1.0, np.array([1, 1, 0, 0], bool), np.zeros(4), 0)
    assert m.on_switches == 1
    assert m.min_off_s is None and m.mean_off_s is None


def test_accumulator_matches_batch():
    rng = np.random.default_rng(0)
    acc = MetricsAccumulator()
    rows = []
    for k in range(200):
        on = bool(rng.random() < 0.3)
        u, un = rng.normal(size=3), rng.normal(size=3)
        acc.add(k * 0.01, 0.01, on, u, un, on)
        rows.append((on, float((u - un) @ (u - un))))
    a = acc.result()
    b = compute_metrics(np.arange(200) * 0.01, 0.01, np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                        np.array([r[0] for r in rows]))
    assert a == b
