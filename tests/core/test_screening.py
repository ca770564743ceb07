"""Row screening in the core filters and switch events of the standard filter."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import ConfigError, IntermittentSafetyFilter, LieData, Power, SafetyFilter


def _random_lie(rng: np.random.Generator, k: int, m: int) -> LieData:
    h = rng.uniform(0.0, 0.5, k)
    lg = rng.normal(size=(k, m))
    return LieData(h, rng.normal(scale=0.2, size=k), lg, np.linalg.norm(lg, axis=1),
                   tuple(f"b{i}" for i in range(k)))


@pytest.mark.parametrize("make", [
    lambda screen: SafetyFilter(Power(3.0, 0.7), 0.05, screen=screen),
    lambda screen: IntermittentSafetyFilter(Power(3.0, 0.7), 0.1, 0.05, 0.05, screen=screen),
])
def test_screening_never_changes_the_command(make) -> None:  # type: ignore[no-untyped-def]
    # tiny thresholds screen out rows the solution then needs: the re-solve must fix it
    rng = np.random.default_rng(7)
    resolves = 0
    for screen in (1e-5, 0.2, 1.0):
        full, screened = make(None), make(screen)
        for i in range(300):
            lie = _random_lie(rng, int(rng.integers(2, 9)), 3)
            u_nom = rng.normal(size=3)
            a = full.step_lie(0.01 * i, lie, u_nom)
            b = screened.step_lie(0.01 * i, lie, u_nom)
            assert a.on == b.on and (a.event is None) == (b.event is None)
            np.testing.assert_allclose(b.u, a.u, atol=1e-7)
            assert (a.qp is None) == (b.qp is None)
            resolves += b.resolved
    assert resolves > 0, "the thresholds must make some screened row necessary"


def test_screen_below_active_tol_is_rejected() -> None:
    with pytest.raises(ConfigError, match="screen"):
        SafetyFilter(1.0, screen=0.0)


def test_standard_filter_reports_switch_events_like_the_trigger() -> None:
    # one barrier h = x - 1 (x_dot = u): the filter is "on" while the constraint is active
    f = SafetyFilter(1.0, 0.0)
    events = []
    for i, (h, u_nom) in enumerate([(1.0, 0.0), (0.5, -1.0), (0.4, -1.0), (0.4, 1.0), (0.2, -1.0)]):
        lie = LieData(np.array([h]), np.zeros(1), np.ones((1, 1)), np.ones(1), ("x",))
        s = f.step_lie(float(i), lie, np.array([u_nom]))
        events.append(None if s.event is None else (s.event.kind, s.event.index, s.event.duration_s))
        assert s.on == (u_nom < -h)
    assert events == [None, ("on", 1, None), None, ("off", 1, 2.0), ("on", 2, 1.0)]


def test_non_finite_input_raises_even_without_validation() -> None:
    from isf_robot.core import NonFiniteError

    f = IntermittentSafetyFilter(1.0, 0.1, 0.1, validate=False)
    lie = LieData(np.array([0.5, math.nan]), np.zeros(2), np.eye(2), np.ones(2))
    with pytest.raises(NonFiniteError):
        f.step_lie(0.0, lie, np.zeros(2))
