import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from isf_robot.demo_core import run_episode


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_barrier_stays_nonnegative_for_both_filters_and_nominal_violates(seed):
    nominal = run_episode("nominal", seed, duration=12.0)
    assert nominal["min_barrier"] < -0.05  # the scene is meaningful: unfiltered, it collides
    for strategy in ("cbf", "isf"):
        r = run_episode(strategy, seed, duration=12.0, record=True)
        assert r["min_barrier"] >= -1e-9, (strategy, seed, r["min_barrier"])
        assert r["collisions"] == 0
        # check the continuous trajectory between samples too (segments are straight lines)
        traj, scene = r["trajectory"], r["scene"]
        s = np.linspace(0, 1, 11)[:, None, None]
        pts = traj[:-1][None] + s * (traj[1:] - traj[:-1])[None]
        for c, rad in zip(scene.centers, scene.radii):
            d = pts - c
            assert np.min(np.einsum("...i,...i->...", d, d) - rad**2) >= -1e-9


def test_intermittent_filter_is_off_most_of_the_time_and_solves_fewer_qps():
    cbf = run_episode("cbf", 3)
    isf = run_episode("isf", 3)
    assert isf["qp_solves"] < cbf["qp_solves"]
    assert cbf["qp_solves"] == cbf["control_steps"]
    assert 0.0 < isf["duty_cycle"] < 0.6
