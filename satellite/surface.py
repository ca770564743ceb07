"""Optional surface check of a trajectory against the body's shape (contact, clearance).

The paper, and the simulation, ignore contact with the surface: the band's inner edge 1.6R
(259 m) lies inside the 311.7 m long-axis reach of Itokawa. This module checks a trajectory
against the body's shape after the fact; it never changes the dynamics.

Shape models, both in the body frame of the gravity model (origin at the centre of mass, the
mesh's axes, metres; see :mod:`satellite.gravity`):

* :class:`MeshSurface`: a closed triangle mesh (the Gaskell shape model), recentred at its
  constant-density centre of mass exactly as :meth:`satellite.gravity.GravityField.from_mesh`
  does. Inside/outside is exact: points farther than the largest vertex radius are outside
  without touching the mesh; for the others the ray from the centre of mass through the point
  is intersected with the faces (candidate faces from a cube-map direction grid, so each ray
  tests a handful of faces), which decides every point below the first or beyond the last
  crossing; points in between (concavities) get the generalized winding number (sum of the
  faces' solid angles, Van Oosterom and Strackee 1983).
* :class:`EllipsoidSurface`: the fallback without a shape file, the triaxial ellipsoid of the
  published dimensions 535 x 294 x 209 m (Fujiwara et al. 2006), axes along body x, y, z.

Clearance is the **radial clearance**: the distance from the point to the nearest surface
crossing along the line through the centre of mass and the point, positive outside and negative
inside. For a surface that is star-shaped about the centre of mass it is ``|r| - r_s(r_hat)``,
with ``r_s`` the surface radius in that direction; it is an upper bound on the Euclidean
distance to the surface (equal to it where the surface is normal to the radius).

Trajectory sampling (:class:`SurfaceCheck`): positions on a fixed time grid (every
``step_s``, default 10 s, taken from the integrator's dense output) plus every located event
state (apses, impulses, arc ends), each turned into the body frame with the body angle at its
time, ``r_body = Rz(-theta(t)) r``, ``theta = theta0 + omega t`` (as in
:class:`satellite.model.OrbitModel`). Near the body the body-frame speed is below about
0.15 m/s (orbital speed at 1.6R plus the surface's spin speed at 312 m), so consecutive samples
are at most about 1.5 m apart: a pass whose path inside the body is longer than that is not
missed (and the smallest clearance is sampled to within centimetres on a gently curved surface).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from isf_robot.core import ConfigError
from satellite.mesh import TriangleMesh, read_obj

__all__ = [
    "ITOKAWA_DIMENSIONS_M",
    "SurfaceModel",
    "EllipsoidSurface",
    "MeshSurface",
    "SurfaceCheck",
    "default_shape_path",
    "load_surface",
    "to_body_frame",
    "winding_numbers",
]

ITOKAWA_DIMENSIONS_M = (535.0, 294.0, 209.0)
"""Itokawa's overall dimensions along body x, y, z [m] (Fujiwara et al. 2006)."""


def default_shape_path() -> Path:
    """Return ``<repo>/../shared/data/itokawa/itokawa_low.obj`` (which may not exist)."""
    return Path(__file__).resolve().parents[1].parent / "shared" / "data" / "itokawa" / "itokawa_low.obj"


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


def winding_numbers(
    points: ArrayLike, vertices: NDArray[np.float64], faces: NDArray[np.intp], chunk: int = 8
) -> NDArray[np.float64]:
    """Generalized winding numbers of points with respect to a closed, outward triangle mesh.

    Sum over faces of the signed solid angle (Van Oosterom and Strackee 1983) divided by 4 pi:
    1 inside, 0 outside (to rounding) for a closed, outward-oriented surface.

    Args:
        points: Query points [m], shape (N, 3).
        vertices: Mesh vertices [m], shape (V, 3).
        faces: Outward triangles, shape (F, 3).
        chunk: Points processed together (memory ~ chunk * F * 3 floats).

    Returns:
        Winding numbers, shape (N,).

    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.empty(p.shape[0])
    va, vb, vc = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    for i0 in range(0, p.shape[0], chunk):
        q = p[i0 : i0 + chunk, None, :]
        a, b, c = va[None] - q, vb[None] - q, vc[None] - q
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("pfi,pfi->pf", a, b) * lc
            + np.einsum("pfi,pfi->pf", a, c) * lb
            + np.einsum("pfi,pfi->pf", b, c) * la
        )
        out[i0 : i0 + chunk] = np.arctan2(det, den).sum(axis=1) / (2.0 * math.pi)
    return out


class SurfaceModel:
    """A closed body shape in the body frame (origin at the centre of mass, metres).

    Attributes:
        name: Short description for reports (which model and where it came from).
        max_radius: Largest distance of the surface from the origin [m]; every point farther
            out is outside.

    """

    name: str = "surface"
    max_radius: float = math.inf

    def query(self, points: ArrayLike) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        """Classify points and give their radial clearance.

        Args:
            points: Body-frame points [m], shape (N, 3).

        Returns:
            ``(inside, clearance)``: booleans, shape (N,), and the radial clearance [m],
            shape (N,), positive outside and negative inside (see the module docstring).

        """
        raise NotImplementedError

    def inside(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Return whether each body-frame point [m], shape (N, 3), is inside; shape (N,)."""
        return self.query(points)[0]

    def clearance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Radial clearance [m] of body-frame points [m], shape (N, 3); shape (N,)."""
        return self.query(points)[1]


class EllipsoidSurface(SurfaceModel):
    """Triaxial ellipsoid ``(x/a)^2 + (y/b)^2 + (z/c)^2 = 1`` centred at the origin.

    Args:
        semi_axes: ``(a, b, c)`` [m], all > 0.
        name: Description for reports.

    """

    def __init__(self, semi_axes: Iterable[float], name: str | None = None) -> None:
        ax = np.asarray(list(semi_axes), dtype=np.float64)
        if ax.shape != (3,) or not np.all(np.isfinite(ax)) or not np.all(ax > 0):
            raise ConfigError(f"ellipsoid semi-axes must be three positive lengths, got {ax.tolist()}")
        self.semi_axes = ax
        self.max_radius = float(ax.max())
        self.name = name or "ellipsoid {:g} x {:g} x {:g} m".format(*(2.0 * ax))

    @classmethod
    def itokawa(cls) -> EllipsoidSurface:
        """The ellipsoid of Itokawa's published dimensions 535 x 294 x 209 m (Fujiwara et al. 2006)."""
        return cls(
            np.asarray(ITOKAWA_DIMENSIONS_M) / 2.0,
            name="ellipsoid 535 x 294 x 209 m (Fujiwara et al. 2006; no shape file)",
        )

    def surface_radius(self, directions: ArrayLike) -> NDArray[np.float64]:
        """Distance [m] from the centre to the surface along each direction, shape (N,).

        Args:
            directions: Non-zero vectors, shape (N, 3) (need not be unit).

        """
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        u = d / np.linalg.norm(d, axis=1)[:, None]
        return 1.0 / np.sqrt(((u / self.semi_axes) ** 2).sum(axis=1))

    def query(self, points: ArrayLike) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        """See :meth:`SurfaceModel.query` (exact: radial clearance ``|r| - r_s(r_hat)``)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        r = np.linalg.norm(p, axis=1)
        inside = ((p / self.semi_axes) ** 2).sum(axis=1) <= 1.0
        clear = np.empty(p.shape[0])
        zero = r == 0.0
        clear[zero] = -float(self.semi_axes.min())
        clear[~zero] = r[~zero] - self.surface_radius(p[~zero])
        return inside, clear


_SMALL_FACE_RAD = math.radians(17.0)
"""Faces whose directions from the origin fit in a cap of this angular radius are binned on the
cube map; larger ones are tested against every ray. Below 17 deg a face with a vertex behind a
cube face's hemisphere cannot reach that cube face's region (within 54.7 deg of its axis)."""


class MeshSurface(SurfaceModel):
    """Closed triangle mesh recentred at its constant-density centre of mass.

    Args:
        mesh: Closed, outward mesh [m] in the body axes (from :func:`satellite.mesh.read_obj`).
        origin: Point of the mesh frame [m], shape (3,), that becomes the origin; default
            ``mesh.centre_of_mass`` (the gravity model's origin).
        name: Description for reports.
        grid: Cells per cube-map face edge for the candidate-face lookup (6 grid^2 cells).

    Attributes:
        vertices: Recentred vertices [m], shape (V, 3).
        faces: Outward triangles, shape (F, 3).

    Raises:
        ConfigError: If ``grid`` < 1.

    """

    def __init__(
        self, mesh: TriangleMesh, origin: ArrayLike | None = None, name: str | None = None, grid: int = 64
    ) -> None:
        if grid < 1:
            raise ConfigError(f"grid must be >= 1, got {grid}")
        o = mesh.centre_of_mass if origin is None else np.asarray(origin, dtype=np.float64).reshape(3)
        self.origin_in_mesh = np.array(o, dtype=np.float64)
        self.vertices = np.asarray(mesh.vertices - o, dtype=np.float64)
        self.faces = np.asarray(mesh.faces, dtype=np.intp)
        self.name = name or f"mesh ({self.faces.shape[0]} faces)"
        self.max_radius = float(np.linalg.norm(self.vertices, axis=1).max())
        self.grid = int(grid)
        a = self.vertices[self.faces[:, 0]]
        self._a = a
        self._e1 = self.vertices[self.faces[:, 1]] - a
        self._e2 = self.vertices[self.faces[:, 2]] - a
        self._build_grid()
        self.origin_inside = bool(winding_numbers(np.zeros((1, 3)), self.vertices, self.faces)[0] > 0.5)

    @classmethod
    def from_obj(cls, path: str | Path, units: str = "km", **kwargs: Any) -> MeshSurface:
        """Read an OBJ shape file (see :func:`satellite.mesh.read_obj`) and recentre it."""
        kwargs.setdefault("name", f"mesh {Path(path)}")
        return cls(read_obj(path, units=units), **kwargs)

    # -- cube-map lookup --------------------------------------------------------------------
    @staticmethod
    def _axes(k: int) -> tuple[int, float, int, int]:
        ax = k // 2
        return ax, (1.0 if k % 2 == 0 else -1.0), (ax + 1) % 3, (ax + 2) % 3

    def _cells_of(self, dirs: NDArray[np.float64]) -> NDArray[np.intp]:
        """Cube-map cell index of each direction, shape (N,)."""
        n = self.grid
        ad = np.abs(dirs)
        ax = np.argmax(ad, axis=1)
        rows = np.arange(dirs.shape[0])
        major = dirs[rows, ax]
        k = 2 * ax + (major < 0)
        denom = np.where(ad[rows, ax] > 0, ad[rows, ax], 1.0)
        u = dirs[rows, (ax + 1) % 3] / denom
        v = dirs[rows, (ax + 2) % 3] / denom
        i = np.clip(np.floor((u + 1.0) * 0.5 * n), 0, n - 1).astype(np.intp)
        j = np.clip(np.floor((v + 1.0) * 0.5 * n), 0, n - 1).astype(np.intp)
        return (k * n + i) * n + j

    def _build_grid(self) -> None:
        n = self.grid
        tri = self.vertices[self.faces]  # (F, 3 vertices, 3)
        unit = tri / np.linalg.norm(tri, axis=2, keepdims=True).clip(1e-300)
        centre = unit.sum(axis=1)
        centre /= np.linalg.norm(centre, axis=1, keepdims=True).clip(1e-300)
        cosang = np.einsum("fvi,fi->fv", unit, centre).min(axis=1)
        small = cosang > math.cos(_SMALL_FACE_RAD)
        self._global = np.flatnonzero(~small)
        cells: list[NDArray[np.intp]] = []
        owners: list[NDArray[np.intp]] = []
        eps = 1e-9
        for k in range(6):
            ax, sign, a1, a2 = self._axes(k)
            front = small & np.all(sign * tri[:, :, ax] > 0, axis=1)
            idx = np.flatnonzero(front)
            t = tri[idx]
            den = sign * t[:, :, ax]
            u, v = t[:, :, a1] / den, t[:, :, a2] / den
            umin, umax = u.min(axis=1) - eps, u.max(axis=1) + eps
            vmin, vmax = v.min(axis=1) - eps, v.max(axis=1) + eps
            keep = (umin <= 1) & (umax >= -1) & (vmin <= 1) & (vmax >= -1)
            idx, umin, umax, vmin, vmax = idx[keep], umin[keep], umax[keep], vmin[keep], vmax[keep]

            def cell(x: NDArray[np.float64]) -> NDArray[np.intp]:
                return np.clip(np.floor((x + 1.0) * 0.5 * n), 0, n - 1).astype(np.intp)

            i0, i1, j0, j1 = cell(umin), cell(umax), cell(vmin), cell(vmax)
            ni, nj = i1 - i0 + 1, j1 - j0 + 1
            cnt = ni * nj
            face_rep = np.repeat(np.arange(idx.size), cnt)
            start = np.repeat(np.cumsum(cnt) - cnt, cnt)
            local = np.arange(face_rep.size) - start
            ii = i0[face_rep] + local // nj[face_rep]
            jj = j0[face_rep] + local % nj[face_rep]
            cells.append((k * n + ii) * n + jj)
            owners.append(idx[face_rep])
        cell_all = np.concatenate(cells)
        owner_all = np.concatenate(owners)
        order = np.argsort(cell_all, kind="stable")
        self._cand = owner_all[order]
        self._ptr = np.zeros(6 * n * n + 1, dtype=np.intp)
        np.add.at(self._ptr, cell_all + 1, 1)
        self._ptr = np.cumsum(self._ptr)

    def _crossings(self, dirs: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        """Ray crossings: for each unit direction, the distances of its ray's hits.

        Returns:
            ``(point_index, t)``: for every hit, the direction's index and the distance [m]
            from the origin; hits on shared edges may appear twice (harmless for the uses here).

        """
        cells = self._cells_of(dirs)
        lo, hi = self._ptr[cells], self._ptr[cells + 1]
        cnt = hi - lo
        pid = np.repeat(np.arange(dirs.shape[0]), cnt)
        start = np.repeat(np.cumsum(cnt) - cnt, cnt)
        fid = self._cand[np.repeat(lo, cnt) + np.arange(pid.size) - start]
        if self._global.size:
            g = self._global
            pid = np.concatenate([pid, np.repeat(np.arange(dirs.shape[0]), g.size)])
            fid = np.concatenate([fid, np.tile(g, dirs.shape[0])])
        d = dirs[pid]
        a, e1, e2 = self._a[fid], self._e1[fid], self._e2[fid]
        pvec = np.cross(d, e2)
        det = np.einsum("ni,ni->n", e1, pvec)
        ok = np.abs(det) > 1e-300
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tvec = -a
        u = np.einsum("ni,ni->n", tvec, pvec) * inv
        qvec = np.cross(tvec, e1)
        v = np.einsum("ni,ni->n", d, qvec) * inv
        t = np.einsum("ni,ni->n", e2, qvec) * inv
        tol = 1e-9
        hit = ok & (u >= -tol) & (v >= -tol) & (u + v <= 1.0 + tol) & (t > 0.0)
        return pid[hit], t[hit]

    def query(self, points: ArrayLike) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        """See :meth:`SurfaceModel.query`.

        Inside/outside is exact (ray crossings, winding number in concavities); the clearance is
        the radial clearance, ``nan`` for a point whose ray found no crossing (not expected for
        a closed mesh around the origin).
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        npts = p.shape[0]
        r = np.linalg.norm(p, axis=1)
        inside = np.zeros(npts, dtype=bool)
        far = r > self.max_radius
        dirs = np.where(r[:, None] > 0, p / np.where(r > 0, r, 1.0)[:, None], np.array([1.0, 0.0, 0.0]))
        pid, t = self._crossings(dirs)
        nhit = np.bincount(pid, minlength=npts)
        t_in = np.full(npts, np.inf)
        t_out = np.full(npts, -np.inf)
        gap = np.full(npts, np.inf)
        np.minimum.at(t_in, pid, t)
        np.maximum.at(t_out, pid, t)
        np.minimum.at(gap, pid, np.abs(t - r[pid]))
        undecided = nhit == 0
        if self.origin_inside:
            inside[(r <= t_in) & ~undecided] = True
            between = (r > t_in) & (r < t_out) & ~undecided
        else:
            between = ~undecided & ~far
        between |= undecided & ~far
        if between.any():
            inside[between] = winding_numbers(p[between], self.vertices, self.faces) > 0.5
        inside[far] = False
        clear = np.where(undecided, np.nan, np.where(inside, -gap, gap))
        return inside, clear


def load_surface(shape: str | Path | None = None, units: str = "km") -> SurfaceModel:
    """Shape model for the surface check.

    Args:
        shape: OBJ file; ``None`` for the default ``../shared/data/itokawa/itokawa_low.obj``
            next to the repository, or the published-dimension ellipsoid when that is absent.
        units: Length unit of the OBJ file (``"km"`` for the Gaskell model).

    Returns:
        A :class:`MeshSurface` (centred at the mesh's centre of mass) or the
        :meth:`EllipsoidSurface.itokawa` fallback.

    Raises:
        FileNotFoundError: An explicit ``shape`` file does not exist.
        MeshError: The file is not a closed, oriented triangle mesh.

    """
    if shape is None:
        path = default_shape_path()
        if not path.is_file():
            return EllipsoidSurface.itokawa()
        return MeshSurface.from_obj(path, units=units, name=f"mesh {path.name} (Gaskell, centre of mass)")
    path = Path(shape)
    if not path.is_file():
        raise FileNotFoundError(f"shape file not found: {path}")
    return MeshSurface.from_obj(path, units=units)


@dataclass
class _Closest:
    clearance: float = math.inf
    t: float = math.nan
    point: tuple[float, float, float] = (math.nan, math.nan, math.nan)


class SurfaceCheck:
    """Accumulates the surface check along a run (fed by :func:`satellite.simulate.simulate`).

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
