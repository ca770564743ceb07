"""The periodic station-keeping baseline: impulses on a clock, the run ends at the first band exit."""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core import ConfigError
from satellite.orbit.simulate import simulate


def test_impulses_come_every_period_and_keep_the_post_jump_condition() -> None:
    res = simulate("periodic", 2.0, period_h=0.1)
    assert res.kinds == {"periodic": 19}  # at 0.1 .. 1.9 h; none at the end time itself
    t = np.array([e.t for e in res.events]) / 3600.0
    np.testing.assert_allclose(t, 0.1 * np.arange(1, 20), atol=1e-9)
    assert all(e.h_after >= 0 and e.xi_after >= res.settings["c"] - 1e-9 for e in res.events)
    assert res.left_band_h is None and res.min_h > 0


def test_a_long_period_leaves_the_band_and_the_run_stops_there() -> None:
    free = simulate("none", 10.0)
    res = simulate("periodic", 10.0, period_h=5.0)
    assert res.triggers == 0 and res.left_band_h == pytest.approx(free.left_band_h, rel=1e-9)
    assert res.simulated_h == pytest.approx(res.left_band_h)


def test_the_periodic_trigger_needs_a_period() -> None:
    with pytest.raises(ConfigError, match="needs a period"):
        simulate("periodic", 1.0)


def test_an_impulse_at_the_start_then_every_period() -> None:
    res = simulate("periodic", 1.0, period_h=0.25, period_at_start=True)
    t = np.array([e.t for e in res.events]) / 3600.0
    np.testing.assert_allclose(t, [0.0, 0.25, 0.5, 0.75], atol=1e-9)
    assert res.settings["period_at_start"] is True and res.events[0].xi_after >= res.settings["c"] - 1e-9
    with pytest.raises(ConfigError, match="periodic trigger only"):
        simulate("greedy", 1.0, period_at_start=True)
