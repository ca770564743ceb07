"""Surface contact inside the dynamics: a conservative radius envelope watched as an event.

The paper's simulation ignores the surface; the band's inner edge (1.6 R = 259 m) lies inside
Itokawa's 311.7 m long-axis reach. Here contact is part of the run:

* :class:`RadiusEnvelope`: a continuous function ``r_env(u)`` of the body-frame direction ``u``
  that is at least the radius of every surface point in that direction. Built on a latitude x
  longitude grid (cells of ``180 / n_lat`` degrees): each cell gets the largest vertex radius of
  the faces whose vertex directions' latitude/longitude box touches it, then the largest value of
  its 3 x 3 neighbourhood, and the values are interpolated bilinearly between cell centres (the
  four centres around a direction are all neighbours of its cell, so the interpolant is at least
  the cell's own value). Rows above 80 deg of latitude take their row maximum, so the function is
  continuous at the poles. Its slope on the unit sphere is bounded by :attr:`RadiusEnvelope.slope`.
* :class:`ContactWatch`: the event ``g = |r| - r_env(u_body(t))`` (entering the envelope is
  necessary for contact), with a rate bound for :mod:`satellite.orbit.events`' scan, and the exact
  check of each pass inside the envelope against the shape (samples every ``step_s`` of the
  pass, bisection on the exact inside test for the first contact). A contact shorter than
  ``step_s`` is missed only if it is shallower than about ``|v| step_s / 2`` (5 cm at 0.1 m/s).

The rate bound: ``|dg/dt| <= |r_dot| + S |du/dt|`` with ``S`` the envelope's slope and
``|du/dt| <= |v| / r + omega`` (orbital motion and the body's spin), with ``r >= min r_env``
wherever ``g >= 0``, the only place the bound is needed (see :mod:`satellite.orbit.events`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from satellite.compiled import compiled, inlined
from satellite.gravity.fields import exact_samples
from satellite.orbit.model import to_body
from satellite.shape.surfaces import EllipsoidSurface, SurfaceModel

__all__ = ["CONTACT_MODES", "envelope_radius", "envelope_radii", "contact_g", "contact_rate", "RadiusEnvelope",
           "ContactWatch", "ellipsoid_mesh", "make_contact", "contact_samples"]

CONTACT_MODES = ("off", "count", "stop")
"""``off``: surface ignored (the paper); ``count``: contacts counted, the orbit goes on through
the body; ``stop``: the run ends at the first contact."""

_POLAR_DEG = 80.0


def _lat_lon(p: NDArray[np.float64], r: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Latitude and longitude [rad] of points ``p`` (N, 3) with norms ``r`` (N,), by libm's asin/atan2.

    Element by element on purpose: numpy's ``arcsin``/``arctan2`` loops are machine dependent (SVML on
    AVX-512 CPUs, libm elsewhere) and round differently in the last bit, which moved the contact
    samples (``u * uniform(r_env(u), ...)``) off the committed exact-field cache
    (:mod:`satellite.shape.cache`) on one machine and not another. libm's results are the same on both.
    """
    n = len(r)
    z = np.clip(p[:, 2] / r, -1.0, 1.0).tolist()
    lat = np.fromiter(map(math.asin, z), dtype=np.float64, count=n)
    lon = np.fromiter(map(math.atan2, p[:, 1].tolist(), p[:, 0].tolist()), dtype=np.float64, count=n)
    return lat, lon


def ellipsoid_mesh(semi_axes: NDArray[np.float64], n: int = 96) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Vertices on the ellipsoid (a latitude x longitude net, ``n`` x ``2n``) and its triangles."""
    lat = np.linspace(-0.5 * math.pi, 0.5 * math.pi, n + 1)
    lon = np.linspace(-math.pi, math.pi, 2 * n, endpoint=False)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    u = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1).reshape(-1, 3)
    verts = u / np.sqrt(((u / semi_axes) ** 2).sum(axis=1))[:, None]
    idx = np.arange((n + 1) * 2 * n).reshape(n + 1, 2 * n)
    a, b = idx[:-1], np.roll(idx[:-1], -1, axis=1)
    c, d = idx[1:], np.roll(idx[1:], -1, axis=1)
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return verts, faces


@inlined
def envelope_radius(values: NDArray[np.float64], d: float, n_lat: int, n_lon: int, x: float, y: float,
                    z: float) -> float:
    """``r_env`` [m] in the direction of the body-frame point ``(x, y, z)``: bilinear between cell centres.

    ``values`` is the envelope's (n_lat, n_lon) grid of cells of ``d`` radians (:class:`RadiusEnvelope`).
    """
    r = math.sqrt(x * x + y * y + z * z)
    q = z / r if r > 0 else z
    lat = math.asin(min(max(q, -1.0), 1.0))
    lon = math.atan2(y, x)
    xx = min(max((lat + 0.5 * math.pi) / d - 0.5, 0.0), n_lat - 1.0)
    yq = (lon + math.pi) / d - 0.5
    yq = yq - n_lon * math.floor(yq / n_lon)
    i = min(int(math.floor(xx)), n_lat - 2) if n_lat > 1 else 0
    fl = math.floor(yq)
    j = int(fl) % n_lon
    fx = xx - i
    fy = yq - fl
    j1 = (j + 1) % n_lon
    i1 = min(i + 1, n_lat - 1)
    return ((1 - fx) * ((1 - fy) * values[i, j] + fy * values[i, j1])  # type: ignore[no-any-return]
            + fx * ((1 - fy) * values[i1, j] + fy * values[i1, j1]))


@compiled
def envelope_radii(values: NDArray[np.float64], d: float, n_lat: int, n_lon: int,
                   points: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`envelope_radius` of each row of ``points`` (N, 3) -> (N,)."""
    out = np.empty(points.shape[0])
    for k in range(points.shape[0]):
        out[k] = envelope_radius(values, d, n_lat, n_lon, points[k, 0], points[k, 1], points[k, 2])
    return out


@inlined
def contact_g(t: float, px: float, py: float, pz: float, phase: float, omega: float, values: NDArray[np.float64],
              d: float, n_lat: int, n_lon: int, max_radius: float) -> float:
    """The contact event ``g = |r| - r_env(u_body(t))`` [m] (``|r| - max r_env`` beyond the envelope's reach)."""
    r = math.sqrt(px * px + py * py + pz * pz)
    if r > max_radius:
        return r - max_radius
    _, _, qx, qy = to_body(phase + omega * t, px, py)
    return r - envelope_radius(values, d, n_lat, n_lon, qx, qy, pz)


@inlined
def contact_rate(ya: Any, yb: Any, dt: Any, a: float, slope: float, min_radius: float, max_radius: float,
                 omega: float) -> Any:
    """Bound on ``|dg/dt|`` [m/s] of :func:`contact_g` over intervals (floats, or arrays of end states (6, k))."""
    ra = np.sqrt(ya[0] * ya[0] + ya[1] * ya[1] + ya[2] * ya[2])
    rb = np.sqrt(yb[0] * yb[0] + yb[1] * yb[1] + yb[2] * yb[2])
    v = 0.5 * (np.sqrt(ya[3] * ya[3] + ya[4] * ya[4] + ya[5] * ya[5])
               + np.sqrt(yb[3] * yb[3] + yb[4] * yb[4] + yb[5] * yb[5])) + 0.5 * a * dt
    r_low = np.minimum(ra, rb) - 0.5 * v * dt
    turn = slope * (v / np.maximum(r_low, min_radius) + abs(omega))
    return v + turn * (r_low <= max_radius)  # beyond the envelope g = r - max: no turn term


class RadiusEnvelope:
    """Continuous upper envelope of the surface radius over body-frame directions (see module docstring).

    Args:
        vertices: Surface vertices [m] about the centre of mass, shape (V, 3).
        faces: Triangles, shape (F, 3).
        n_lat: Latitude cells (longitude cells are ``2 n_lat``).
        margin: Factor applied to the radii (``>= 1``; pads a sampled surface).
        name: Description for reports.

    Attributes:
        slope: Bound on ``|grad r_env|`` on the unit sphere [m/rad].
        min_radius: Smallest value [m].
        max_radius: Largest value [m].

    """

    def __init__(self, vertices: NDArray[np.float64], faces: NDArray[np.intp], n_lat: int = 90,
                 margin: float = 1.0, name: str = "surface") -> None:
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.intp)
        self.name = name
        self.n_lat, self.n_lon = int(n_lat), 2 * int(n_lat)
        self.d = math.pi / self.n_lat  # cell size [rad], both ways
        rad = np.linalg.norm(v, axis=1)
        lat, lon = _lat_lon(v, rad)
        lat, lon = lat[f], lon[f]
        rel = (lon - lon[:, :1] + math.pi) % (2.0 * math.pi) - math.pi  # longitudes about vertex 0
        lon0 = lon[:, 0] + rel.min(axis=1)
        span = rel.max(axis=1) - rel.min(axis=1)
        i0 = np.clip(np.floor((lat.min(axis=1) + 0.5 * math.pi) / self.d), 0, self.n_lat - 1).astype(np.intp)
        i1 = np.clip(np.floor((lat.max(axis=1) + 0.5 * math.pi) / self.d), 0, self.n_lat - 1).astype(np.intp)
        j0 = np.floor((lon0 + math.pi) / self.d).astype(np.intp)
        nj = np.floor((lon0 + span + math.pi) / self.d).astype(np.intp) - j0 + 1
        frad = rad[f].max(axis=1) * margin
        raw = np.zeros((self.n_lat, self.n_lon))
        # a face around a pole (its longitudes cover more than half a turn) fills whole rows
        polar_face = span > math.pi / 2
        for k in np.flatnonzero(polar_face):
            rows = slice(0, i1[k] + 1) if lat[k].mean() < 0 else slice(i0[k], self.n_lat)
            raw[rows] = np.maximum(raw[rows], frad[k])
        ok = ~polar_face
        ni = i1 - i0 + 1
        for di in range(int(ni[ok].max(initial=0))):
            for dj in range(int(nj[ok].max(initial=0))):
                m = ok & (di < ni) & (dj < nj)
                np.maximum.at(raw, (i0[m] + di, (j0[m] + dj) % self.n_lon), frad[m])
        env = raw.copy()
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                shifted = np.roll(raw, dj, axis=1)
                if di:
                    shifted = np.roll(shifted, di, axis=0)
                    shifted[0 if di > 0 else -1] = 0.0
                env = np.maximum(env, shifted)
        centres = -0.5 * math.pi + (np.arange(self.n_lat) + 0.5) * self.d
        polar = np.abs(centres) > math.radians(_POLAR_DEG)
        env[polar] = env[polar].max(axis=1, keepdims=True)
        self.values = env
        self.min_radius = float(env.min())
        self.max_radius = float(env.max())
        dlat = np.abs(np.diff(env, axis=0)) / self.d  # per patch between rows i, i+1
        dlon = np.abs(np.roll(env, -1, axis=1) - env) / self.d
        slon = np.maximum(dlon[:-1], dlon[1:]) / np.minimum(np.cos(centres[:-1]), np.cos(centres[1:]))[:, None]
        slat = np.maximum(dlat, np.roll(dlat, -1, axis=1))
        self.slope = float(np.sqrt(slat**2 + slon**2).max()) if self.n_lat > 1 else 0.0

    @classmethod
    def from_surface(cls, surface: SurfaceModel, n_lat: int = 90) -> RadiusEnvelope:
        """The envelope of a shape: a mesh's triangles, or a fine net on the ellipsoid (+0.5 %)."""
        if isinstance(surface, EllipsoidSurface):
            v, f = ellipsoid_mesh(surface.semi_axes, 2 * n_lat)
            return cls(v, f, n_lat, margin=1.005, name=surface.name)
        verts = getattr(surface, "vertices", None)
        faces = getattr(surface, "faces", None)
        if verts is None or faces is None:
            raise TypeError(f"no envelope for {type(surface).__name__}: needs vertices and faces")
        return cls(verts, faces, n_lat, name=surface.name)

    def radius(self, dirs: NDArray[np.float64]) -> NDArray[np.float64]:
        """``r_env`` [m] of directions, shape (N, 3) (need not be unit) -> (N,) (:func:`envelope_radius`)."""
        p = np.ascontiguousarray(dirs, dtype=np.float64).reshape(-1, 3)
        return envelope_radii(self.values, self.d, self.n_lat, self.n_lon, p)  # type: ignore[no-any-return]


class ContactWatch:
    """The contact event of a run and the exact check of its passes inside the envelope.

    Args:
        surface: The exact shape (inside test).
        envelope: Its radius envelope.
        body_phase: Body angle at ``t = 0`` [rad].
        omega: Spin rate [rad/s].
        accel_bound: Bound on the truth acceleration [m/s^2] outside the envelope and inside 2.4 R.
        step_s: Sampling interval of the exact check within a pass [s].

    """

    def __init__(self, surface: SurfaceModel, envelope: RadiusEnvelope, body_phase: float, omega: float,
                 accel_bound: float, step_s: float = 1.0) -> None:
        self.surface = surface
        self.envelope = envelope
        self.body_phase = body_phase
        self.omega = omega
        self.accel_bound = accel_bound
        self.step_s = step_s

    def _body(self, t: Any, p: NDArray[np.float64]) -> NDArray[np.float64]:
        th = self.body_phase + self.omega * np.asarray(t, dtype=float)
        c, s = np.cos(th), np.sin(th)
        return np.stack([c * p[0] + s * p[1], c * p[1] - s * p[0], p[2] * np.ones_like(th)], axis=-1)

    def body_point(self, t: float, y: NDArray[np.float64]) -> NDArray[np.float64]:
        """Body-frame position [m] of state ``y`` at time ``t``, shape (1, 3)."""
        return self._body(t, np.asarray(y, dtype=float)[:3]).reshape(1, 3)

    def g(self, t: float, y: NDArray[np.float64]) -> float:
        """``|r| - r_env(u_body)`` [m] (:func:`contact_g`)."""
        e = self.envelope
        px, py, pz = y[:3].tolist()
        return contact_g(t, px, py, pz, self.body_phase, self.omega, e.values, e.d, e.n_lat, e.n_lon, e.max_radius)

    def batch(self, t: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`g` at states ``y``, shape (6, k) -> (k,)."""
        return np.array([self.g(float(tk), y[:, k]) for k, tk in enumerate(np.broadcast_to(t, y.shape[1:]))])

    def rate(self, ya: NDArray[np.float64], yb: NDArray[np.float64], dt: Any) -> Any:
        """Bound on ``|dg/dt|`` [m/s] over the interval(s) (:func:`contact_rate`; see the module docstring)."""
        e = self.envelope
        return contact_rate(ya, yb, dt, self.accel_bound, e.slope, e.min_radius, e.max_radius, self.omega)

    def passes(self, t0: float, t1: float, g0: float, crossings: NDArray[np.float64]) -> list[tuple[float, float]]:
        """Intervals of ``[t0, t1]`` inside the envelope, from ``g(t0)`` and the crossing times."""
        out, inside, start = [], g0 < 0.0, t0
        for tc in crossings:
            if inside:
                out.append((start, float(tc)))
            inside, start = not inside, float(tc)
        if inside:
            out.append((start, t1))
        return out

    def first_contact(self, sol: Any, a: float, b: float) -> tuple[float | None, float]:
        """First time in ``[a, b]`` inside the exact shape, and the smallest radial clearance [m].

        Args:
            sol: Dense output ``t -> y`` (vectorised).
            a: Start of the pass [s].
            b: End of the pass [s].

        Returns:
            ``(t_contact or None, min clearance)`` over the samples.

        """
        n = max(2, int(math.ceil((b - a) / self.step_s)) + 1)
        ts = np.linspace(a, b, n)
        pts = self._body(ts, sol(ts)[:3])
        inside, clear = self.surface.query(pts)
        if not inside.any():
            return None, float(clear.min())
        k = int(np.argmax(inside))
        if k == 0:
            return float(ts[0]), float(clear.min())
        lo, hi = float(ts[k - 1]), float(ts[k])
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if self.surface.inside(self._body(mid, np.asarray(sol(mid))[:3]).reshape(1, 3))[0]:
                hi = mid
            else:
                lo = mid
            if hi - lo < 1e-6:
                break
        return hi, float(clear.min())


def contact_samples(model: Any, surface: SurfaceModel, samples: int = 4000,
                    slow_samples: int = 100) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The points of :func:`make_contact`'s acceleration bound: ``(fast, slow)``, body frame [m], shapes (k, 3).

    ``slow`` are the points outside the field's fast radii (at most ``slow_samples``, the first drawn;
    none when the field has no such radii).
    """
    env = RadiusEnvelope.from_surface(surface)
    rng = np.random.default_rng(0)
    u = rng.normal(size=(samples, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    lo = env.radius(u)
    pts = u * rng.uniform(lo, np.maximum(lo, 2.4 * model.R))[:, None]
    fast = getattr(model.field, "fast_radii", None)
    if fast is None:
        return pts, pts[:0]
    r = np.linalg.norm(pts, axis=1)
    slow = np.flatnonzero((r < fast[0]) | (r > fast[1]))
    keep = np.ones(len(pts), dtype=bool)
    keep[slow] = False
    return pts[keep], pts[slow[:slow_samples]]


def make_contact(model: Any, surface: SurfaceModel, step_s: float = 1.0, samples: int = 4000,
                 slow_samples: int = 100) -> ContactWatch:
    """The contact watch of a run: the shape's envelope and an acceleration bound outside it.

    The bound is ``2 x`` the largest sampled ``|a|`` of the truth field at points between the
    envelope and 2.4 R (directions uniform, radii uniform; :func:`contact_samples`): sampled, with a
    safety factor. A field with a fast range of radii (``fast_radii``, the gravity table's) is sampled
    at most at ``slow_samples`` points outside it (the first drawn), where it falls back to the exact
    field (milliseconds per point; the committed table's answers there are cached,
    :func:`satellite.gravity.fields.exact_samples`).

    Args:
        model: The run's :class:`satellite.orbit.model.OrbitModel` (field, spin, body phase).
        surface: The exact shape.
        step_s: Sampling interval of the exact check within a pass [s].
        samples: Points for the acceleration bound.
        slow_samples: At most this many of them outside the field's fast radii.

    """
    env = RadiusEnvelope.from_surface(surface)
    acc = 0.0
    for k, pts in enumerate(contact_samples(model, surface, samples, slow_samples)):
        if not len(pts):
            continue
        field = exact_samples(model.field, pts) if k else model.field.acceleration_batch(pts)
        kep = -model.mu * pts / (np.linalg.norm(pts, axis=1) ** 3)[:, None]
        truth = kep + model.disturbance_scale * (field - kep)
        acc = max(acc, float(np.linalg.norm(truth, axis=1).max()))
    return ContactWatch(surface, env, model.body_phase, model.omega, 2.0 * acc, step_s)
