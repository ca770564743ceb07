"""Choosing a sweep's intermittent point (isf_robot.arm.tune): known answers on hand-written sweep rows."""

from __future__ import annotations

import pytest
import tomllib

from isf_robot.arm.tune import choose_point, filter_section, missed_targets


def _row(label, strategy="isf", **kw):  # type: ignore[no-untyped-def]
    base = {"strategy": strategy, "label": label, "values": {}, "episodes": 3, "pareto": True, "violations": 0,
            "min_off_all_s": 0.5, "goals_reached": 3.0, "duty_cycle": 0.4, "on_switches": 3.0, "intervention": 1.0}
    base.update(kw)
    return base


def test_the_lowest_duty_among_the_points_that_meet_every_target() -> None:
    cbf = _row("cbf", "cbf", duty_cycle=0.6, min_off_all_s=0.02)  # cbf's own chatter is not a criterion
    pts = [cbf,
           _row("a", duty_cycle=0.20, min_off_all_s=0.05, values={"c": 0.01}),   # lowest duty, but chatters
           _row("b", duty_cycle=0.35, values={"c": 0.05}),
           _row("c", duty_cycle=0.30, goals_reached=2.8, values={"c": 0.1}),     # 0.2 goals short of cbf
           _row("d", duty_cycle=0.25, violations=4, values={"c": 0.2}),         # unsafe
           _row("e", duty_cycle=0.10, pareto=False, values={"c": 0.3}),         # off the front (never chosen)
           _row("f", duty_cycle=0.35, on_switches=2.0, values={"c": 0.4})]      # ties b on duty, fewer switches
    best, missed = choose_point({"scene": "s", "points": pts})
    assert best["label"] == "f" and missed == []
    assert missed_targets(pts[1], cbf) == ["an off period of 0.050 s (< 0.25 s: chatter)"]
    assert missed_targets(pts[3], cbf) == ["2.80 goals against cbf's 3.00"]
    assert missed_targets(pts[4], cbf) == ["4 violation step(s)"]


def test_when_nothing_meets_every_target_the_section_says_what_is_missed() -> None:
    pts = [_row("cbf", "cbf"), _row("a", min_off_all_s=0.1, violations=1, values={"horizon": 0.2}),
           _row("b", min_off_all_s=0.1, duty_cycle=0.5, values={"horizon": 0.4, "predict_every": 3.0})]
    pts[2]["d_bar"] = 0.04
    best, missed = choose_point({"scene": "s", "points": pts})
    assert best["label"] == "b" and missed == ["an off period of 0.100 s (< 0.25 s: chatter)"]
    text = filter_section({"scene": "s", "points": pts}, [0, 1, 2], "t.json, t.txt")
    assert "# MISSES: an off period of 0.100 s" in text
    assert tomllib.loads(text)["filter"] == {"horizon": 0.4, "predict_every": 3, "d_bar": 0.04}
    with pytest.raises(ValueError, match="no intermittent point"):
        choose_point({"scene": "s", "points": [_row("cbf", "cbf")]})
