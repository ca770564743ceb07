"""The predicted-safe off margin ``c_pred`` of the intermittent filter (core/filters.py), on a 1-D
integrator driven by a fake clock, checked against a brute-force rollout of the nominal."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import ConfigError, IntermittentSafetyFilter, LieData, Linear

DT = 0.01
A = 2.0  # alpha(h) = A h
H = 0.2  # rollout horizon [s]


def _lie(x: float) -> LieData:
    """Barrier h = x (stay at x >= 0) of x_dot = u: Lf h = 0, Lg h = 1."""
    return LieData(np.array([x]), np.zeros(1), np.array([[1.0]]), np.ones(1), ("wall",))


def u_nom(t: float, x: float) -> float:
    """A nominal that drives into the wall and away again (a swing of about 3 around x = 0)."""
    return -1.5 * math.cos(t) - 0.1 * x


def rollout(t, state):
    """Explicit Euler of x_dot = u_nom(t, x) over the horizon in 10 points (the adapter's model)."""
    x, out, ds = float(state[0]), [], H / 10
    for j in range(1, 11):
        x += ds * u_nom(t + (j - 1) * ds, x)
        out.append((j * ds, _lie(x), np.array([u_nom(t + j * ds, x)])))
    return out


def brute_force_safe(t: float, x: float, fine: int = 200) -> bool:
    """Whether the nominal alone keeps Xi_on = u_nom + A h > 0 over the horizon (fine Euler grid)."""
    ds = H / fine
    for j in range(1, fine + 1):
        x += ds * u_nom(t + (j - 1) * ds, x)
        if u_nom(t + j * ds, x) + A * x <= 0.0:
            return False
    return True


def _run(c_pred: float | None, t_end: float = 8.0):
    f = IntermittentSafetyFilter(Linear(A), c=1.0, b=0.5, rollout=rollout, predict_every=1, c_pred=c_pred)
    x, t, steps = 1.5, 0.0, []
    while t < t_end:
        s = f.step_lie(t, _lie(x), np.array([u_nom(t, x)]), x=np.array([x]))
        steps.append((t, x, s))
        x += DT * float(s.u[0])  # the exact flow of x_dot = u over one control period
        t = round(t + DT, 10)
    return steps


def test_off_as_soon_as_the_rollout_predicts_safe_and_never_unsafe():
    steps = _run(c_pred=0.02)
    offs = [(t, x, s) for t, x, s in steps if s.event is not None and s.event.kind == "off"]
    ons = [t for t, _, s in steps if s.event is not None and s.event.kind == "on"]
    assert len(offs) >= 3 and len(ons) >= 3
    for t, x, s in offs:
        assert s.xi_min < 1.0  # earlier than the margin c = 1 would allow
        assert s.xi_min >= 0.02
        assert s.margin == pytest.approx(0.02)
        assert brute_force_safe(t, x)  # the nominal alone keeps Xi_on > 0 over the horizon
    # off at the first predicted-safe step: one step earlier the rollout (the same Euler as brute_force_safe
    # on 10 points) said no
    for t, _, _ in offs:
        i = next(i for i, (tt, _, _) in enumerate(steps) if tt == t)
        tp, xp, sp = steps[i - 1]
        if sp.xi_min >= 0.02:
            assert not brute_force_safe(tp, xp, fine=10)  # the adapter's model said no one step earlier
    # safety: h >= 0, and the robust condition (d_bar 0: u + A h >= 0) holds at every step, on or off
    assert min(x for _, x, _ in steps) >= 0.0
    assert min(float(s.u[0]) + A * x for _, x, s in steps) >= -1e-9
    # off periods last about the horizon at least (the prediction is this model's, up to Euler error)
    periods = [min(t_on for t_on in ons if t_on > t0) - t0 for t0, _, _ in offs if any(t_on > t0 for t_on in ons)]
    assert periods and min(periods) >= H - 2 * DT


def test_c_pred_turns_off_earlier_than_the_margin_c_alone():
    base = _run(c_pred=None)
    early = _run(c_pred=0.02)
    duty = [sum(s.on for _, _, s in r) / len(r) for r in (base, early)]
    push = [sum((float(s.u[0]) - float(s.u_nom[0])) ** 2 for _, _, s in r) * DT for r in (base, early)]
    assert duty[1] < 0.8 * duty[0]
    assert push[1] < 0.8 * push[0]
    base_offs = [s.xi_min for _, _, s in base if s.event is not None and s.event.kind == "off"]
    assert base_offs and min(base_offs) >= 1.0  # without c_pred: off only at Xi_on >= c


def test_c_pred_options_are_checked():
    with pytest.raises(ConfigError, match="c_pred.*rollout"):
        IntermittentSafetyFilter(1.0, 0.1, 0.1, c_pred=0.05)
    with pytest.raises(ConfigError, match="c_pred must be <= c"):
        IntermittentSafetyFilter(1.0, 0.1, 0.1, c_pred=0.5, rollout=rollout)
    with pytest.raises(ConfigError, match="c_pred"):
        IntermittentSafetyFilter(1.0, 0.1, 0.1, c_pred=-0.05, rollout=rollout)  # (0: none)
