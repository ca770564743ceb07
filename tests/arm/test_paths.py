"""Obstacle paths: one implementation for tracks, single lookups and the scene's mocap bodies."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CirclePath, LinearBouncePath
from isf_robot.arm.paths import path_cycle, path_track

PATHS = [
    CirclePath(center=(0.1, -0.2, 0.3), radius=0.25, period=2.0, normal=(0.0, 0.6, 0.8), phase=0.3),
    CirclePath(center=(0.0, 0.0, 0.5), radius=0.1, period=-1.5, normal=(1.0, 0.0, 0.0)),
    LinearBouncePath(start=(0.48, 0.0, 0.15), end=(0.48, 0.0, 0.75), speed=0.3),
    LinearBouncePath(start=(0.0, 0.1, 0.2), end=(0.3, -0.2, 0.4), speed=0.7, phase=0.65),
]


@pytest.mark.parametrize("path", PATHS)
def test_track_and_single_lookups_agree_to_the_bit(path, rng) -> None:  # type: ignore[no-untyped-def]
    t = np.sort(rng.uniform(-3.0, 9.0, 400))
    pos, vel = path_track(path, t)
    assert pos.shape == vel.shape == (t.size, 3)
    for k in range(0, t.size, 7):
        assert np.array_equal(path.position(float(t[k])), pos[k])
        assert np.array_equal(path.velocity(float(t[k])), vel[k])


@pytest.mark.parametrize("path", PATHS)
def test_motion_repeats_after_one_cycle_and_velocity_is_the_derivative(path, rng) -> None:  # type: ignore[no-untyped-def]
    cycle = path_cycle(path)
    assert cycle > 0
    t = rng.uniform(0.0, 5.0, 50)
    p0, v0 = path_track(path, t)
    p1, _ = path_track(path, t + cycle)
    np.testing.assert_allclose(p1, p0, atol=1e-12)
    eps = 1e-6
    fd = (path_track(path, t + eps)[0] - path_track(path, t - eps)[0]) / (2 * eps)
    smooth = np.linalg.norm(fd - v0, axis=1) < 1e-6
    assert smooth.mean() > 0.9  # everywhere except across a bounce's turning point


def test_other_path_objects_are_evaluated_point_by_point() -> None:
    class Spiral:
        def position(self, t: float) -> np.ndarray:
            return np.array([np.cos(t), np.sin(t), 0.1 * t])

        def velocity(self, t: float) -> np.ndarray:
            return np.array([-np.sin(t), np.cos(t), 0.1])

    t = np.linspace(0.0, 2.0, 5)
    pos, vel = path_track(Spiral(), t)
    np.testing.assert_array_equal(pos[3], Spiral().position(t[3]))
    np.testing.assert_array_equal(vel[4], Spiral().velocity(t[4]))
    assert path_cycle(Spiral()) == 0.0


def test_scene_mocap_lookups_use_the_same_numbers(planar_moving) -> None:  # type: ignore[no-untyped-def]
    sc = planar_moving
    data = mujoco.MjData(sc.model)
    t = np.array([0.0, 0.37, 2.5])
    for k, tk in enumerate(t.tolist()):
        sc.set_moving_obstacles(data, tk)
        lin, ang = sc.mocap_velocities(tk)
        assert not ang.any()
        for mocap, mv in zip(sc.moving_mocap_ids, sc.config.moving):
            pos, vel = path_track(mv.path, t)
            assert np.array_equal(data.mocap_pos[mocap], pos[k])
            assert np.array_equal(lin[mocap], vel[k])
