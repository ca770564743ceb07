"""Useful Zeno protection (issue 14, item 4): the practical minimum interval and the MIET estimate."""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core import ConfigError
from satellite.orbit.model import InitialOrbit
from satellite.orbit.simulate import simulate

HOLD = 3600.0  # longer than several of the free run's intervals (shortest ~1000 s)


@pytest.fixture(scope="module")
def runs() -> dict[float, object]:
    return {m: simulate("greedy", 60.0, initial=InitialOrbit(seed=2), miet_samples=200, min_interval_s=m)
            for m in (0.0, 60.0, HOLD)}


def test_interval_that_does_not_bind_leaves_the_run_unchanged(runs) -> None:  # type: ignore[no-untyped-def]
    free, default = runs[0.0], runs[60.0]
    assert free.min_inter_event_h * 3600.0 > 60.0  # the default does not bind here
    assert default.min_interval_binds == 0 and default.min_interval_overrides == 0
    assert [e.t for e in default.events] == [e.t for e in free.events]
    np.testing.assert_array_equal(default.events[-1].x_after, free.events[-1].x_after)


def test_long_interval_holds_impulses_and_keeps_the_satellite_in_the_band(runs) -> None:  # type: ignore[no-untyped-def]
    free, held = runs[0.0], runs[HOLD]
    assert free.min_inter_event_h * 3600.0 < HOLD  # it would bind: the test can fail
    assert held.min_interval_binds > 0 and held.min_interval_s == HOLD
    assert held.min_h >= 0.0 and held.band_exits == 0
    c = held.settings["c"]
    short = [e for e in held.events[1:] if e.interval_s < HOLD - 1e-6]
    assert len(short) <= held.min_interval_overrides  # only an edge override fires sooner
    for e in short:
        assert 0.0 <= e.h_before <= 1e-5 * 4200.0  # at the band's edge, still inside
    for e in held.events:
        assert e.xi_before <= 1e-6 and e.xi_after >= c - 1e-9  # fired with Xi <= 0, post-jump met
    assert held.min_interval_binds > held.min_interval_overrides  # some holds ran their full length
    assert any(e.interval_s == pytest.approx(HOLD) for e in held.events)


def test_miet_estimate_is_not_vacuous_and_below_the_measured_minimum(runs) -> None:  # type: ignore[no-untyped-def]
    for res in runs.values():
        est_s = res.miet_estimate_h * 3600.0
        assert est_s > 20.0 * res.miet_bound_h * 3600.0  # Proposition 1's product: 0.026 s here
        assert 0.1 < est_s <= res.min_inter_event_h * 3600.0


def test_bad_interval_is_refused() -> None:
    with pytest.raises(ConfigError, match="min_interval_s"):
        simulate("greedy", 1.0, min_interval_s=-1.0)
