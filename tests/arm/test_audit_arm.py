"""Audit additions: collisions counted at every physics step; seeds validated."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from isf_robot.arm import episode_setup, run_episode
from isf_robot.cli import main
from isf_robot.core import ConfigError, Observer


class _Steps(Observer):
    def __init__(self) -> None:
        self.steps: list[Any] = []

    def on_step(self, record: Any) -> None:
        self.steps.append(record)


def test_collisions_are_counted_at_every_physics_step(planar) -> None:  # type: ignore[no-untyped-def]
    # 5 physics steps per control tick: a contact lasting several ticks must be counted on the
    # physics steps between the ticks too, not only at the ticks the observer sees.
    obs = _Steps()
    r = run_episode(planar, "nominal", 4.0, 0, control_period=0.005, observers=[obs])
    assert r.physics_steps == 5 * r.control_steps + 1
    pair = np.array(["|" in n for n in obs.steps[0].names])
    colliding_ticks = sum(int(np.min(s.h[pair]) < 0.0) for s in obs.steps)
    assert colliding_ticks >= 5, "the nominal run must collide for this test to mean anything"
    assert r.collisions <= r.physics_steps
    assert r.collisions >= 3 * colliding_ticks, (r.collisions, colliding_ticks)


@pytest.mark.parametrize("seed", [-1, 2.5, True])
def test_episode_setup_rejects_bad_seed(planar, seed) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError, match="seed must be a non-negative integer"):
        episode_setup(planar, seed)


@pytest.mark.parametrize("argv", [
    ["run", "--scene", "planar", "--duration", "0.1", "--seed", "-3"],
    ["compare", "--scene", "planar", "--episodes", "1", "--duration", "0.1", "--seed", "-1"],
])
def test_negative_seed_cli_exit_2_one_line(argv: list[str], capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "seed" in err and "non-negative" in err and "\n" not in err and "Traceback" not in err


class _XiLog(Observer):
    def __init__(self) -> None:
        self.rows: list[tuple[float, bool, float]] = []

    def on_step(self, record: Any) -> None:
        self.rows.append((record.t, record.on, record.xi_min))


def test_recorded_run_with_fast_off_logs_the_same_steps_as_a_full_filter_run(planar) -> None:  # type: ignore[no-untyped-def]
    # With an observer attached, the isf fast path (filter not called while off and every
    # Xi_on > 0) must log the same modes and min Xi_on as calling the filter every step.
    logs = []
    results = []
    for fast in (True, False):
        log = _XiLog()
        results.append(run_episode(planar, "isf", duration=2.0, seed=1, observers=[log], fast_off=fast))
        logs.append(np.array(log.rows))
    assert results[0].on_switches == results[1].on_switches >= 1
    assert results[0].qp_solves == results[1].qp_solves
    np.testing.assert_array_equal(logs[0][:, :2], logs[1][:, :2])
    np.testing.assert_allclose(logs[0][:, 2], logs[1][:, 2], rtol=1e-12, atol=1e-12)
