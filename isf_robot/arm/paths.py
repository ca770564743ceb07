"""Obstacle path motion: the one place that says where a moving obstacle is, and how fast it goes.

Every path computes its position and velocity for an array of times at once
(:meth:`CirclePath.track`, :meth:`LinearBouncePath.track`); :func:`path_track` dispatches to it,
and the scalar ``position(t)`` / ``velocity(t)`` are the same formulas at one time, so a
precomputed track (the simulation loop), a single lookup (:meth:`~isf_robot.arm.Scene.set_moving_obstacles`,
:meth:`~isf_robot.arm.Scene.mocap_velocities`) and the episode's random start phase
(:attr:`CirclePath.cycle`) agree to the last bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

__all__ = ["CirclePath", "LinearBouncePath", "ObstaclePath", "MovingObstacle", "path_track",
           "path_cycle"]


def _plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal in-plane axes (e1, e2) of the plane with unit ``normal``, each shape (3,).

    e1 is the projection of the world x axis (y axis when the normal is along x) onto the
    plane, normalised; e2 = normal x e1.
    """
    ref = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = ref - normal * float(normal @ ref)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(normal, e1)


def _times(t: Any) -> np.ndarray:
    """Times as a float array of shape (N,) (a scalar gives N = 1)."""
    return np.asarray(t, dtype=float).reshape(-1)


@dataclass(frozen=True)
class CirclePath:
    """Uniform motion on a circle: ``p(t) = c + r (cos th e1 + sin th e2)``.

    ``th = 2 pi (phase + t / period)``; e1, e2 span the plane normal to ``normal`` (e1 is the
    world x axis projected onto that plane, e2 = normal x e1).

    Attributes:
        center: Circle centre [m], shape (3,).
        radius: Radius [m].
        period: Time for one revolution [s] (negative: clockwise about ``normal``).
        normal: Unit normal of the circle's plane, shape (3,).
        phase: Start angle as a fraction of a revolution.

    """

    center: tuple[float, float, float]
    radius: float
    period: float
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    phase: float = 0.0

    @cached_property
    def _frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        e1, e2 = _plane_basis(np.asarray(self.normal, dtype=float))
        return np.asarray(self.center, dtype=float), e1, e2

    @property
    def cycle(self) -> float:
        """Time after which the motion repeats [s] (``|period|``)."""
        return abs(float(self.period))

    def track(self, t: Any) -> tuple[np.ndarray, np.ndarray]:
        """Positions [m] and velocities [m/s] at the times ``t`` [s], each shape (N, 3)."""
        c, e1, e2 = self._frame
        th = 2.0 * math.pi * (self.phase + _times(t) / self.period)
        cos, sin = np.cos(th)[:, None], np.sin(th)[:, None]
        w = 2.0 * math.pi / self.period
        return c + self.radius * (cos * e1 + sin * e2), self.radius * w * (-sin * e1 + cos * e2)

    def position(self, t: float) -> np.ndarray:
        """Position at time ``t`` [s]; shape (3,) [m]."""
        return self.track(t)[0][0]

    def velocity(self, t: float) -> np.ndarray:
        """Velocity at time ``t`` [s]; shape (3,) [m/s]."""
        return self.track(t)[1][0]


@dataclass(frozen=True)
class LinearBouncePath:
    """Back-and-forth motion at constant speed on the segment from ``start`` to ``end``.

    With ``L = |end - start|`` and ``s = (speed t + 2 L phase) mod 2L``, the position is
    ``start + min(s, 2L - s) e`` (e the unit direction); the velocity is ``+speed e`` on the
    way out and ``-speed e`` on the way back (it jumps at the turning points; one-sided there).

    Attributes:
        start: One end of the segment [m], shape (3,).
        end: The other end [m], shape (3,).
        speed: Speed [m/s], > 0.
        phase: Start point as a fraction of the round trip (0: at ``start`` going out).

    """

    start: tuple[float, float, float]
    end: tuple[float, float, float]
    speed: float
    phase: float = 0.0

    @cached_property
    def _segment(self) -> tuple[np.ndarray, float, np.ndarray]:
        a = np.asarray(self.start, dtype=float)
        seg = np.asarray(self.end, dtype=float) - a
        length = float(np.linalg.norm(seg))
        return a, length, seg / length

    @property
    def cycle(self) -> float:
        """Time of one round trip [s] (``2 L / speed``)."""
        return 2.0 * self._segment[1] / float(self.speed)

    def track(self, t: Any) -> tuple[np.ndarray, np.ndarray]:
        """Positions [m] and velocities [m/s] at the times ``t`` [s], each shape (N, 3)."""
        a, length, e = self._segment
        arc = np.mod(self.speed * _times(t) + 2.0 * length * self.phase, 2.0 * length)
        pos = a + np.minimum(arc, 2.0 * length - arc)[:, None] * e
        vel = np.where(arc < length, self.speed, -self.speed)[:, None] * e
        return pos, vel

    def position(self, t: float) -> np.ndarray:
        """Position at time ``t`` [s]; shape (3,) [m]."""
        return self.track(t)[0][0]

    def velocity(self, t: float) -> np.ndarray:
        """Velocity at time ``t`` [s]; shape (3,) [m/s] (one-sided at the turning points)."""
        return self.track(t)[1][0]


ObstaclePath = CirclePath | LinearBouncePath


@dataclass(frozen=True)
class MovingObstacle:
    """A mocap body that moves on a known path (its orientation stays fixed).

    Attributes:
        body: Name of the mocap body.
        path: Its path; ``position(t)`` and ``velocity(t)`` are analytic.

    """

    body: str
    path: ObstaclePath


def path_track(path: Any, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities of an obstacle path at many times at once.

    The shipped paths compute the whole array in a few numpy operations (their ``track``);
    any other object with ``position(t)`` and ``velocity(t)`` is evaluated point by point.

    Args:
        path: The path.
        t: Times [s], shape (N,).

    Returns:
        ``(positions, velocities)``, each shape (N, 3), in [m] and [m/s].

    """
    track = getattr(path, "track", None)
    if track is not None:
        return track(t)
    t = _times(t)
    return (np.array([path.position(x) for x in t]).reshape(-1, 3),
            np.array([path.velocity(x) for x in t]).reshape(-1, 3))


def path_cycle(path: Any) -> float:
    """Time after which a path repeats [s] (``path.cycle``; 0 for a path that does not say)."""
    return float(getattr(path, "cycle", 0.0))
