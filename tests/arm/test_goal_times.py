"""Time to complete the goals: arrival times with a fake clock, in every run's result, and the sweep's
``goals_time_s`` (the k-th arrival, censored at the episode's duration)."""

from __future__ import annotations

import pytest

from isf_robot.arm import ArmSimulation, GoalSequence, load_scene
from isf_robot.arm.sweep import goals_time


def test_arrival_times_follow_the_fake_clock_and_survive_a_rollout_snapshot(planar):
    g = GoalSequence(2, [0.5, 0.0], tolerance=0.1, loop=True)
    for t, err in [(0.0, 1.0), (1.0, 0.05), (1.2, 0.05), (1.5, 0.5), (2.25, 0.01), (2.3, 0.01), (3.0, 0.0)]:
        g.update(t, err)
    assert g.arrivals == (1.0, 2.25, 3.0) and g.reached == 3  # dwelling does not count again
    g.update(3.1, 0.5)  # a timeout never adds an arrival
    g2 = GoalSequence(1, [0.0], tolerance=0.1, timeout=1.0)
    g2.update(0.0, 1.0)
    g2.update(1.0, 1.0)
    assert g2.arrivals == () and g2.missed == 1

    sim = ArmSimulation(planar, "nominal", seed=0, d_bar=0.05)
    nom = sim.nominal
    state = nom.snapshot()
    nom.goals.update(5.0, 0.0)  # a rollout's predicted arrival...
    assert nom.goal_times == (5.0,)
    nom.restore(state)  # ...is forgotten when the controller is put back
    assert nom.goal_times == ()


def test_every_result_reports_its_arrival_times():
    scene = load_scene("planar")
    res = ArmSimulation(scene, "nominal", seed=0, d_bar=0.05).run(3.0)
    d = res.as_dict()
    times = d["goal_times_s"]
    assert len(times) == d["goals_reached"] >= 1
    assert times == sorted(times) and 0.0 < times[0] and times[-1] <= d["duration_s"]
    steps = [t / res.control_period for t in times]  # arrivals happen at control ticks
    assert all(abs(s - round(s)) < 1e-6 for s in steps)


def _run(times, duration=10.0):
    return {"goal_times_s": list(times), "duration_s": duration}


def test_goals_time_known_answers():
    # every episode completes the 3 goals: k = 3, the mean time of the third arrival
    k, rows = goals_time([[_run([1, 2, 3]), _run([1, 2, 5, 9])], [_run([2, 4, 6])]], 3)
    assert k == 3 and rows == [{"goals_time_s": 4.0, "goals_time_censored": 0},
                               {"goals_time_s": 6.0, "goals_time_censored": 0}]
    # one episode reached only 2: k = 2 for every point of the scene
    k, rows = goals_time([[_run([1, 2, 3]), _run([1, 7])], [_run([2, 4, 6])]], 3)
    assert k == 2 and [r["goals_time_s"] for r in rows] == [4.5, 4.0]
    # an episode with no arrival: k = 1 and that episode counts as its whole duration (censored)
    k, rows = goals_time([[_run([]), _run([3])], [_run([2, 4])]], 3)
    assert k == 1 and rows[0] == {"goals_time_s": pytest.approx(6.5), "goals_time_censored": 1}
    assert rows[1] == {"goals_time_s": 2.0, "goals_time_censored": 0}
