"""Optional surface check of a trajectory against the body's shape (contact, clearance).

The paper, and the simulation, ignore contact with the surface: the band's inner edge 1.6R
(259 m) lies inside the 311.7 m long-axis reach of Itokawa. This module checks a trajectory
against the body's shape after the fact; it never changes the dynamics.

Shape models: :mod:`satellite.shape.surfaces` (interface, ellipsoid) and :mod:`satellite.shape.mesh_surface`
(the triangle mesh, :func:`~satellite.shape.mesh_surface.load_surface`).

Trajectory sampling (:class:`SurfaceCheck`): positions on a fixed time grid (every
``step_s``, default 10 s, taken from the integrator's dense output) plus every located event
state (apses, impulses, arc ends), each turned into the body frame with the body angle at its
time, ``r_body = Rz(-theta(t)) r``, ``theta = theta0 + omega t`` (as in
:class:`satellite.orbit.model.OrbitModel`). Near the body the body-frame speed is below about
0.15 m/s (orbital speed at 1.6R plus the surface's spin speed at 312 m), so consecutive samples
are at most about 1.5 m apart: a pass whose path inside the body is longer than that is not
missed (and the smallest clearance is sampled to within centimetres on a gently curved surface).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from isf_robot.core import ConfigError
from satellite.shape.surfaces import SurfaceModel

__all__ = ["SurfaceCheck", "to_body_frame"]


def to_body_frame(times: ArrayLike, positions: ArrayLike, body_phase: float, omega: float) -> NDArray[np.float64]:
    """Turn inertial positions into the spinning body frame.

    Args:
        times: Times [s], shape (N,).
        positions: Inertial positions [m], shape (N, 3).
        body_phase: Body angle ``theta0`` at ``t = 0`` [rad].
        omega: Spin rate [rad/s] (0 for a frozen body).

    Returns:
        Body-frame positions ``Rz(-theta(t)) r`` [m], shape (N, 3).

    """
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    th = body_phase + omega * t
    c, s = np.cos(th), np.sin(th)
    return np.stack([c * p[:, 0] + s * p[:, 1], c * p[:, 1] - s * p[:, 0], p[:, 2]], axis=1)


@dataclass
class _Closest:
    clearance: float = math.inf
    t: float = math.nan
    point: tuple[float, float, float] = (math.nan, math.nan, math.nan)


class SurfaceCheck:
    """Accumulates the surface check along a run (fed by :func:`satellite.orbit.simulate.simulate`).

    Call :meth:`add` with each arc's samples in time order (arcs in time order); read
    :meth:`report` at the end. Samples farther from the centre than ``surface.max_radius`` are
    outside and skip the shape, except that, to keep ``min_clearance_m`` exact over all samples,
    any sample with ``|r| < max_radius + (smallest clearance so far)`` is queried too (the
    clearance of a sample is at least ``|r| - max_radius``).

    Args:
        surface: Shape model in the body frame.
        body_phase: Body angle at ``t = 0`` [rad].
        omega: Spin rate [rad/s].
        step_s: Sampling interval of the trajectory [s], > 0 (the simulation evaluates its dense
            output at the multiples of ``step_s`` and adds its event states).

    Raises:
        ConfigError: If ``step_s`` is not positive.

    """

    def __init__(self, surface: SurfaceModel, body_phase: float, omega: float, step_s: float = 10.0) -> None:
        if not (math.isfinite(step_s) and step_s > 0.0):
            raise ConfigError(f"surface sampling step must be positive, got {step_s}")
        self.surface = surface
        self.body_phase = float(body_phase)
        self.omega = float(omega)
        self.step_s = float(step_s)
        self.samples = 0
        self.queried = 0
        self.hits = 0
        self.passes = 0
        self.first_hit_s: float | None = None
        self.hit_time_s = 0.0
        self._prev_inside = False
        self._prev_t: float | None = None
        self._closest = _Closest()

    def add(self, times: ArrayLike, positions: ArrayLike) -> None:
        """Check inertial samples of one stretch of the trajectory.

        Args:
            times: Sample times [s], shape (N,), increasing; times not after the last time of
                earlier calls are dropped (so arcs may share their end points).
            positions: Inertial positions [m], shape (N, 3).

        """
        t = np.asarray(times, dtype=np.float64).reshape(-1)
        p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        if self._prev_t is not None:
            new = t > self._prev_t
            t, p = t[new], p[new]
        if t.size == 0:
            return
        r = np.linalg.norm(p, axis=1)
        self.samples += t.size
        inside = np.zeros(t.size, dtype=bool)
        m = self.surface.max_radius
        k = int(np.argmin(r))
        if r[k] - m < self._closest.clearance:
            self._query(t[k : k + 1], p[k : k + 1])
        near = np.flatnonzero(r <= m + max(self._closest.clearance, 0.0))
        if near.size:
            inside[near] = self._query(t[near], p[near])
        if inside.any():
            hit_t = t[inside]
            self.hits += int(inside.sum())
            if self.first_hit_s is None:
                self.first_hit_s = float(hit_t[0])
            prev = np.concatenate([[self._prev_inside], inside[:-1]])
            self.passes += int((inside & ~prev).sum())
            dt = np.diff(np.concatenate([[self._prev_t if self._prev_t is not None else t[0]], t]))
            self.hit_time_s += float(dt[inside & prev].sum())
        self._prev_inside = bool(inside[-1])
        self._prev_t = float(t[-1])

    def _query(self, t: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.bool_]:
        body = to_body_frame(t, p, self.body_phase, self.omega)
        inside, clear = self.surface.query(body)
        self.queried += t.size
        finite = np.isfinite(clear)
        if finite.any():
            i = int(np.flatnonzero(finite)[np.argmin(clear[finite])])
            if clear[i] < self._closest.clearance:
                self._closest = _Closest(float(clear[i]), float(t[i]), tuple(float(x) for x in body[i]))  # type: ignore[arg-type]
        return inside

    def report(self) -> dict[str, Any]:
        """JSON-ready summary.

        Returns:
            ``surface_model`` (which shape), ``surface_hits`` (samples inside),
            ``surface_passes`` (separate stretches of inside samples), ``surface_inside_h``
            (time between consecutive inside samples, summed) [h], ``first_surface_hit_h``
            [h] or ``None``, ``min_clearance_m`` (smallest radial clearance over the samples
            [m], negative if a sample was inside), ``min_clearance_h`` [h] and
            ``min_clearance_body_m`` (body-frame point [m]) where it occurred,
            ``surface_samples``, ``surface_queried`` (samples that reached the shape),
            ``surface_step_s``, and ``surface_clearance`` (what the clearance means).

        """
        c = self._closest
        finite = math.isfinite(c.clearance)
        return {
            "surface_model": self.surface.name,
            "surface_hits": self.hits,
            "surface_passes": self.passes,
            "surface_inside_h": self.hit_time_s / 3600.0,
            "first_surface_hit_h": None if self.first_hit_s is None else self.first_hit_s / 3600.0,
            "min_clearance_m": c.clearance if finite else None,
            "min_clearance_h": c.t / 3600.0 if finite else None,
            "min_clearance_body_m": list(c.point) if finite else None,
            "surface_samples": self.samples,
            "surface_queried": self.queried,
            "surface_step_s": self.step_s,
            "surface_clearance": "radial: distance to the nearest surface crossing along the line "
            "through the centre of mass (upper bound on the Euclidean distance; negative inside)",
        }
