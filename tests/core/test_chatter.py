"""Chatter: off periods under CHATTER_OFF_S counted in time (not steps), and the advice that fixes them."""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core import FilterSpec
from isf_robot.core.chatter import chatter_advice, chatter_risk, horizon_for
from isf_robot.core.metrics import CHATTER_OFF_S, compute_metrics


def _run(segments: list[tuple[bool, float, float]]):  # type: ignore[no-untyped-def]
    """Steps of a fake clock: (mode, length [s], step [s]) per segment; the steps' lengths differ by segment."""
    t, dt, on = [], [], []
    now = 0.0
    for mode, length, step in segments:
        n = round(length / step)
        for _ in range(n):
            t.append(now)
            dt.append(step)
            on.append(mode)
            now += step
    return compute_metrics(np.array(t), np.array(dt), np.array(on), np.zeros(len(t)), 0)


def test_short_off_periods_are_counted_in_time() -> None:
    # off periods (complete ones only): 0.2 s in 100 steps of 2 ms, 0.3 s in 3 steps of 0.1 s,
    # 0.24 s in 2 steps of 0.12 s; the first stretch (before any on) and the last (cut by the end) do not count
    m = _run([(False, 0.1, 0.01), (True, 0.1, 0.01), (False, 0.2, 0.002), (True, 0.05, 0.01),
              (False, 0.3, 0.1), (True, 0.05, 0.01), (False, 0.24, 0.12), (True, 0.1, 0.01),
              (False, 0.01, 0.01)])
    assert m.on_switches == 4 and m.off_switches == 4
    assert m.short_offs == 2  # 0.2 s and 0.24 s; the 0.3 s one in three long steps is not chatter
    assert m.min_off_s == pytest.approx(0.2)
    advice = chatter_advice(m.as_dict(), FilterSpec(blend=0.0, horizon=0.0), 0.01)
    assert advice is not None and advice.startswith("chatter: 2 off periods under 0.25 s (shortest 0.200 s)")
    assert "turn on the predictive off trigger: horizon = 0.3 (--horizon 0.3)" in advice  # 0.25 + 5 x 0.01
    quiet = _run([(True, 0.1, 0.01), (False, 0.5, 0.01), (True, 0.1, 0.01)])
    assert quiet.short_offs == 0 and chatter_advice(quiet.as_dict(), FilterSpec(), 0.01) is None


def test_the_advice_follows_what_is_set() -> None:
    m = {"short_offs": 1, "min_off_s": 0.1}
    # a horizon shorter than the rule's: lengthen it to the rule's value
    short = chatter_advice(m, FilterSpec(blend=0.1, horizon=0.2), 0.002)
    assert short is not None and "lengthen the predictive horizon (now 0.2 s): horizon = 0.3 (--horizon 0.3)" in short
    # a horizon that already covers the rule: half as long again, or design the margin
    long = chatter_advice(m, FilterSpec(blend=0.1, horizon=0.4), 0.002)
    assert long is not None and "horizon = 0.6 (--horizon 0.6)" in long and "min_off = 0.25" in long


def test_risk_from_the_parameters_alone() -> None:
    assert horizon_for(5, 0.002) == pytest.approx(CHATTER_OFF_S + 0.01)
    assert chatter_risk(FilterSpec(blend=0.15, horizon=0.26), 0.002) is None
    assert chatter_risk(FilterSpec(blend=0.0, horizon=0.0, min_off=CHATTER_OFF_S), 0.002) is None
    risk = chatter_risk(FilterSpec(blend=0.15, horizon=0.2), 0.002)
    assert risk is not None and "horizon = 0.3" in risk
    assert "turn on the predictive off trigger" in (chatter_risk(FilterSpec(), 0.002) or "")

