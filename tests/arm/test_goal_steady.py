"""``GoalSequence.steady``: when it says the goal index cannot change over a window, no sequence of updates changes it."""

from __future__ import annotations

import copy
import math

import numpy as np

from isf_robot.arm.goals import GoalSequence


def _random_sequence(rng: np.random.Generator) -> GoalSequence:
    n = int(rng.integers(1, 4))
    dwell = rng.choice([0.0, 0.003, 0.01, 0.05, 0.3], size=n)  # (multiples of the 1 ms grid: boundary ties)
    timeout = float(rng.choice([0.02, 0.1, 0.5, math.inf]))
    return GoalSequence(n, dwell, tolerance=0.1, loop=bool(rng.integers(2)), timeout=timeout)


def test_a_steady_window_never_sees_the_index_change() -> None:
    rng = np.random.default_rng(20261123)
    steady = changed = 0
    for _ in range(2000):
        g = _random_sequence(rng)
        t = 0.0
        for _ in range(int(rng.integers(0, 40))):  # a history: arrivals, dwells, timeouts
            t += 0.001 * int(rng.integers(1, 20))
            g.update(t, float(rng.choice([0.05, 0.5])))
        dt = 0.001 * int(rng.integers(1, 40))
        n = int(rng.integers(1, 12))
        times = [t + j * dt for j in range(1, n + 1)]  # (as the rollout's points: t + s, s = j dt)
        ok = g.steady(times[0], times[-1])
        for _ in range(4):  # any errors along the window
            h = copy.deepcopy(g)
            index = h.index
            for tj in times:
                h.update(tj, float(rng.choice([0.05, 0.5, 0.09999, 0.1])))
            if h.index != index:
                changed += 1
                assert not ok, (vars(g), times)
        steady += ok
    assert steady > 500 and changed > 500  # both kinds of window are exercised


def test_steady_known_answers() -> None:
    g = GoalSequence(2, [0.05, 0.05], tolerance=0.1, timeout=1.0)
    assert g.steady(0.0, 0.04)  # nothing started: no timeout within 1 s, no dwell of 0.05 within 0.04
    assert not g.steady(0.0, 0.05)  # an arrival at 0.0 could advance at 0.05
    g.update(0.0, 0.5)  # started at 0
    assert not g.steady(0.96, 1.0)  # the timeout at 1.0
    g.update(0.5, 0.05)  # arrived at 0.5
    assert g.steady(0.51, 0.549) and not g.steady(0.51, 0.55)
