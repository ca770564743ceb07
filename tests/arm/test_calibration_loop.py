"""d_bar calibrated with the filter in the loop (arm/calibration_loop.py) on the planar scene."""

from __future__ import annotations

import pytest

from isf_robot.arm import ArmSimulation
from isf_robot.arm.calibration_loop import calibrate_in_loop
from isf_robot.arm.params import resolve_params
from isf_robot.core import ConfigError

KW = dict(seeds=(0, 1), duration=1.5, use_cache=False)


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
