"""d_bar calibrated with the filter in the loop (arm/calibration_loop.py) on the planar scene."""

from __future__ import annotations

import dataclasses

import pytest

from isf_robot.arm import ArmSimulation, calibration_loop
from isf_robot.arm.calibration_loop import calibrate_in_loop, loop_params
from isf_robot.arm.params import resolve_params
from isf_robot.core import ConfigError

KW = dict(seeds=(0, 1), duration=1.5, use_cache=False)

# each test takes seconds; a wrong normal or sign makes the loop's simulations crawl: fail then, not minutes later
pytestmark = pytest.mark.time_limit(120)


def test_a_too_small_d_bar_is_raised_until_the_filter_s_tracking_error_is_covered(planar):
    p = resolve_params(planar, d_bar=1e-4, blend=0.0)
    cal = calibrate_in_loop(planar, "cbf", p, factor=1.25, max_rounds=4, **KW)
    assert len(cal.rounds) >= 2 and cal.rounds[0][0] == 1e-4 and cal.rounds[0][1] > 1e-4
    for (_, worst), (d_next, _) in zip(cal.rounds, cal.rounds[1:]):
        assert d_next == pytest.approx(1.25 * worst)  # raised to factor x the measured error
    assert cal.covered and cal.d_bar == cal.rounds[-1][0] >= cal.rounds[-1][1]
    # the fixed point holds: each calibration seed rerun with the d_bar found is covered
    q = resolve_params(planar, d_bar=cal.d_bar, blend=0.0)
    for s in KW["seeds"]:
        res = ArmSimulation(planar, "cbf", seed=s, params=q).run(KW["duration"])
        assert res.tracking_error_q99 <= cal.d_bar and res.as_dict()["d_bar_covered"]


def test_a_covering_d_bar_is_kept(planar):
    p = resolve_params(planar, d_bar=0.05)
    cal = calibrate_in_loop(planar, "cbf", p, **KW)
    assert cal.covered and cal.d_bar == 0.05 and len(cal.rounds) == 1 and cal.rounds[0][1] <= 0.05
    assert cal.as_dict()["strategy"] == "cbf"


def test_loop_params_take_the_loop_s_d_bar_and_say_so(planar):
    p = resolve_params(planar, d_bar=1e-4, blend=0.0)
    q = loop_params(planar, "cbf", p, seeds=(0,), duration=1.0, max_rounds=2)
    cal = calibrate_in_loop(planar, "cbf", p, seeds=(0,), duration=1.0, max_rounds=2)  # (the cached result)
    assert q.d_bar == cal.d_bar > p.d_bar and q.d_bar_source == "argument+loop"
    assert dataclasses.replace(q, d_bar=p.d_bar, d_bar_source=p.d_bar_source) == p  # nothing else changed


def test_bad_in_loop_arguments_are_refused(planar):
    p = resolve_params(planar, d_bar=0.05)
    with pytest.raises(ConfigError, match="filtering strategy"):
        calibrate_in_loop(planar, "nominal", p, **KW)
    with pytest.raises(ConfigError, match="valid|unknown|strateg"):
        calibrate_in_loop(planar, "nope", p, **KW)
    with pytest.raises(ConfigError, match="factor"):
        calibrate_in_loop(planar, "cbf", p, factor=0.5, **KW)
    with pytest.raises(ConfigError, match="seed"):
        calibrate_in_loop(planar, "cbf", p, seeds=(), duration=1.0)


class _FakeSim:
    """Stands in for ArmSimulation: the tracking error is a known function of the d_bar in use."""

    law = staticmethod(lambda d: d)
    calls: list[float] = []

    def __init__(self, scene, strategy, seed, params):
        self.d = params.d_bar

    def run(self, duration):
        _FakeSim.calls.append(self.d)

        class R:
            tracking_error_q99 = _FakeSim.law(self.d)

        return R()


@pytest.mark.parametrize("law, settles", [(lambda d: 0.05 + 0.2 * d, True), (lambda d: 0.1 + 2.0 * d, False)])
def test_known_answers_settling_and_a_diverging_error(planar, monkeypatch, law, settles):
    monkeypatch.setattr(calibration_loop, "ArmSimulation", _FakeSim)
    _FakeSim.calls = []
    monkeypatch.setattr(_FakeSim, "law", staticmethod(law))
    p = resolve_params(planar, d_bar=0.01)
    cal = calibrate_in_loop(planar, "isf", p, seeds=(0,), duration=1.0, factor=1.25, max_rounds=6, use_cache=False)
    if settles:  # 0.052 -> d = 0.065 -> error 0.063 <= 0.065: covered in the second round
        assert cal.covered and not cal.diverged
        assert [d for d, _ in cal.rounds] == pytest.approx([0.01, 1.25 * 0.052])
        assert cal.d_bar == pytest.approx(1.25 * 0.052)
    else:  # 0.12 -> d = 0.15 -> error 0.4 > 0.12 grew: stop, keep the starting d_bar, not covered
        assert cal.diverged and not cal.covered and len(cal.rounds) == 2
        assert cal.d_bar == 0.01
        assert [e for _, e in cal.rounds] == pytest.approx([0.12, 0.4])
    assert _FakeSim.calls == [d for d, _ in cal.rounds]  # the stand-in ran every round
