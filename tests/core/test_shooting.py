"""Maneuvers by shooting (core/shooting.py) in the intermittent filter, on a 1-D integrator with a fake clock.

The barrier is ``h = x`` of ``x_dot = u`` (a wall at 0); the nominal swings into the wall and away.
The shooting rollout is explicit Euler of the nominal on this model, with the candidate command
over its first step. Each choice is checked against every level's re-trigger time computed here,
brute force; safety and the robust condition are checked at every step.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import ConfigError, IntermittentSafetyFilter, LieData, Linear
from isf_robot.core.intermittent import Prediction
from isf_robot.core.shooting import LEVELS, ManeuverShooter, release_time

DT = 0.01
A = 2.0  # alpha(h) = A h
B = 0.2  # promotion rate
H_SHOOT = 0.6  # shooting horizon [s]
POINTS = 10


def _lie(x: float) -> LieData:
    return LieData(np.array([x]), np.zeros(1), np.array([[1.0]]), np.ones(1), ("wall",))


def u_nom(t: float, x: float) -> float:
    return -1.5 * math.cos(t) - 0.1 * x


def shoot_rollout(t, state, first=None):
    """Euler of x_dot = u_nom over H_SHOOT in POINTS points; ``first`` over the first step."""
    x, out, ds = float(state[0]), [], H_SHOOT / POINTS
    calls.append(t)
    for j in range(1, POINTS + 1):
        u = float(first[0]) if (j == 1 and first is not None) else u_nom(t + (j - 1) * ds, x)
        x += ds * u
        out.append((j * ds, _lie(x), np.array([u_nom(t + j * ds, x)])))
    return out


calls: list[float] = []


def retrigger_time(t: float, x: float, u_first: float) -> float:
    """The first point (of the shooting rollout's grid) with Xi_on = u_nom + A h <= 0; inf: none."""
    ds = H_SHOOT / POINTS
    for j in range(1, POINTS + 1):
        x += ds * (u_first if j == 1 else u_nom(t + (j - 1) * ds, x))
        if u_nom(t + j * ds, x) + A * x <= 0.0:
            return j * ds
    return math.inf


def _run(shoot: float, every: int = 3, t_end: float = 8.0):
    calls.clear()
    f = IntermittentSafetyFilter(Linear(A), c=1.0, b=B, predict_every=every, shoot=shoot,
                                 shoot_rollout=shoot_rollout if shoot else None)
    x, t, steps = 1.5, 0.0, []
    while t < t_end:
        n_before = 0 if f.shooter is None else f.shooter.choices
        s = f.step_lie(t, _lie(x), np.array([u_nom(t, x)]), x=np.array([x]))
        chose = f.shooter is not None and f.shooter.choices > n_before
        steps.append((t, x, s, chose, None if f.shooter is None else (f.shooter.factor, f.shooter.last_tau)))
        x += DT * float(s.u[0])
        t = round(t + DT, 10)
    return f, steps


def test_each_choice_is_the_level_with_the_latest_retrigger():
    f, steps = _run(H_SHOOT)
    chosen = [(t, x, s, info) for t, x, s, chose, info in steps if chose]
    assert len(chosen) >= 5
    raised = 0
    for t, x, s, (factor, taus) in chosen:
        assert s.on
        # every level's command is the filter's QP with that level: Lf h + Lg h u >= level, so u = max(u_nom, level)
        expect = []
        for lv in LEVELS:
            u = max(u_nom(t, x), lv * B)
            expect.append(retrigger_time(t, x, u))
        assert list(taus) == pytest.approx(expect)
        best = max(expect)
        assert factor == next(lv for lv, tau in zip(LEVELS, expect) if tau == best)  # ties: the smallest
        assert float(s.u[0]) == pytest.approx(max(u_nom(t, x), factor * B))
        raised += factor != LEVELS[0]
    assert raised >= 1  # the case makes a larger push pay at least once
    assert f.shooter.raised == raised


def test_shooting_keeps_safety_and_the_robust_condition():
    _, steps = _run(H_SHOOT)
    assert min(x for _, x, *_ in steps) >= 0.0
    assert min(float(s.u[0]) + A * x for _, x, s, *_ in steps) >= -1e-9
    # while on, the command meets the promotion (Lf h + Lg h u >= b at least)
    for _, _, s, _, _ in steps:
        if s.on:
            assert float(s.u[0]) >= B - 1e-9


def test_choices_at_each_on_switch_then_every_k_steps():
    every = 4
    f, steps = _run(H_SHOOT, every=every)
    on_runs: list[list[bool]] = []
    for _, _, s, chose, _ in steps:
        if s.on and (not on_runs or s.event is not None and s.event.kind == "on"):
            on_runs.append([])
        if s.on:
            on_runs[-1].append(chose)
        else:
            assert not chose  # no choice while off
    assert len(on_runs) >= 2
    for run in on_runs:
        assert run[0]  # a choice at the on switch
        assert [i for i, c in enumerate(run) if c] == list(range(0, len(run), every))
    assert len(calls) == f.shooter.choices * len(LEVELS)


def test_without_shooting_the_filter_is_unchanged_and_level_b():
    f, steps = _run(0.0)
    assert f.shooter is None
    for t, x, s, _, _ in steps:
        if s.on:
            assert float(s.u[0]) == pytest.approx(max(u_nom(t, x), B))


def test_release_time_known_answers():
    assert release_time(Prediction(True, 1.0, None, frozenset(), 10)) == math.inf
    assert release_time(Prediction(False, -1.0, 0.3, frozenset({"wall"}), 10)) == 0.3


def test_bad_shooting_options_are_config_errors():
    with pytest.raises(ConfigError, match="shoot_rollout"):
        IntermittentSafetyFilter(Linear(A), c=1.0, b=B, shoot=0.5)
    with pytest.raises(ConfigError, match="shoot"):
        IntermittentSafetyFilter(Linear(A), c=1.0, b=B, shoot=-1.0, shoot_rollout=shoot_rollout)
    with pytest.raises(ConfigError, match="levels"):
        ManeuverShooter(shoot_rollout, levels=(2.0, 1.0))
    with pytest.raises(ConfigError, match="every"):
        ManeuverShooter(shoot_rollout, every=0)
    with pytest.raises(ConfigError, match="rollout"):
        ManeuverShooter(None)  # type: ignore[arg-type]


def test_a_new_choice_moves_the_level_in_use_at_the_bounded_rate():
    """The level in use crosses the levels' range in ``ramp`` seconds, never in one step."""
    prefer_top = [False]

    def fake_rollout(t, x, first=None):  # (level 10 re-triggers latest once prefer_top, else all the same)
        tau = 0.5 if prefer_top[0] and float(first[0]) >= 10 * B - 1e-12 else 0.1
        return [(tau, _lie(-1.0), np.zeros(1))]  # (h = -1: Xi_on < 0 at s = tau)

    sh = ManeuverShooter(fake_rollout, every=1, ramp=0.1)
    solve = lambda level: np.array([level])  # noqa: E731
    assert sh.level(0.0, None, B, solve, Linear(A), 0.0) == pytest.approx(B)  # all equal: the smallest
    prefer_top[0] = True
    used, t = [], 0.0
    for _ in range(15):
        t = round(t + DT, 10)
        used.append(sh.level(t, None, B, solve, Linear(A), 0.0) / B)
    steps = np.diff([1.0, *used])
    assert np.all(steps <= (LEVELS[-1] - LEVELS[0]) / 0.1 * DT + 1e-9)  # 0.9 per 10 ms
    assert used[-1] == pytest.approx(LEVELS[-1]) and used[0] < LEVELS[-1]
    assert sh.raised == 15
    sh.idle()  # off: the next on period starts from the first level
    prefer_top[0] = False
    assert sh.level(1.0, None, B, solve, Linear(A), 0.0) == pytest.approx(B)
    with pytest.raises(ConfigError, match="ramp"):
        ManeuverShooter(fake_rollout, ramp=-1.0)
