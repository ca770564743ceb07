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


def test_add_step_records_steps_and_their_solver_figures():
    """add_step keeps add's per-step figures plus the jumps and solver counts, against a direct count."""
    from isf_robot.core import FilterStep, QPResult, SwitchEvent

    rng = np.random.default_rng(3)
    acc, plain = MetricsAccumulator(), MetricsAccumulator()
    us, events, kinds = [], [], []
    for k in range(120):
        u, un = rng.normal(size=4), rng.normal(size=4)
        if k % 5 == 0:
            u = un  # the nominal command passed through: no intervention
        kind = ("none", "closed_form", "optimal")[k % 3]
        qp = None if kind == "none" else QPResult(u, kind, np.zeros(1, bool), 1e-6 * (k + 1), 1, 0.0)
        ev = SwitchEvent(k * 0.01, "on" if k % 2 else "off", 0.0, 1) if k % 17 == 5 else None
        step = FilterStep(k * 0.01, u, un, bool(k % 4 == 1), np.zeros(1), np.zeros(1), ev, qp,
                          ("r",) if k % 11 == 0 else (), k % 13 == 0, resolved=k % 7 == 0, off_bound_s=float(200 - k))
        acc.add_step(step, 0.01)
        plain.add(k * 0.01, 0.01, step.on, u, un, qp is not None)
        us.append(u)
        events.append(ev is not None)
        kinds.append(kind)
    assert acc.arrays().keys() == plain.arrays().keys()
    for name, col in acc.arrays().items():
        assert np.array_equal(col, plain.arrays()[name]), name
    jumps = [float(np.linalg.norm(us[k] - us[k - 1])) for k in range(1, len(us))]
    st = acc.stats()
    assert st.jump_max == pytest.approx(max(jumps), rel=1e-14)
    assert st.switch_jump_max == pytest.approx(max(j for j, e in zip(jumps, events[1:]) if e), rel=1e-14)
    assert st.qp_closed_form == kinds.count("closed_form")
    assert st.fallbacks == len(range(0, 120, 13)) and st.relaxations == len(range(0, 120, 11))
    assert st.resolves == len(range(0, 120, 7)) and st.off_bound_min_s == 81.0
    times = [1e-6 * (k + 1) for k in range(120) if kinds[k] == "optimal"]
    assert st.solver_time_median_us == pytest.approx(float(np.median(times)) * 1e6)


def test_steps_packed_into_arrays_read_back_the_same(monkeypatch):
    """Steps are packed into arrays every _CHUNK steps (memory): arrays(), len() and the metrics do not change."""
    from isf_robot.core import metrics

    rng = np.random.default_rng(5)
    data = [(k * 0.01, 0.01, bool(rng.random() < 0.3), rng.normal(size=3), rng.normal(size=3), bool(k % 4))
            for k in range(50)]
    whole = MetricsAccumulator()
    for row in data:
        whole.add(*row)
    monkeypatch.setattr(metrics, "_CHUNK", 7)
    packed = MetricsAccumulator()
    for row in data:
        packed.add(*row)
    assert len(packed._packed) == 7 and len(packed) == len(whole) == 50
    for name, col in whole.arrays().items():
        assert np.array_equal(packed.arrays()[name], col) and packed.arrays()[name].dtype == col.dtype, name
    assert packed.result() == whole.result()


def test_duty_cycle_is_time_on_over_time_not_steps_on_over_steps():
    # steps of unequal length: on for one 3 s step, off for three 1 s steps: on 3 s of 6 s (a count of steps
    # would say 1 of 4); the intervention integrates over time as well
    t = np.array([0.0, 3.0, 4.0, 5.0])
    dt = np.array([3.0, 1.0, 1.0, 1.0])
    on = np.array([True, False, False, False])
    m = compute_metrics(t, dt, on, np.where(on, 2.0, 0.0), on)
    assert m.duration_s == 6.0
    assert m.duty_cycle == pytest.approx(0.5)
    assert m.intervention == pytest.approx(2.0 * 3.0)
    acc = MetricsAccumulator()  # the in-loop accumulator integrates the same way
    for ti, di, oi in zip(t, dt, on):
        acc.add(float(ti), float(di), bool(oi), np.full(2, 1.0) if oi else np.zeros(2), np.zeros(2), bool(oi))
    assert acc.result().duty_cycle == pytest.approx(0.5)
