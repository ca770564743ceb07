"""The body's shape as a closed triangle mesh: exact inside/outside, and the shape file.

:class:`MeshSurface` recentres the mesh at its constant-density centre of mass exactly as
:meth:`satellite.gravity.spherical.GravityField.from_mesh` does. Inside/outside is exact: points farther
than the largest vertex radius are outside without touching the mesh; for the others the ray
from the centre of mass through the point is intersected with the faces (candidate faces from a
cube-map direction grid, so each ray tests a handful of faces), which decides every point below
the first or beyond the last crossing; points in between (concavities) get the generalized
winding number (sum of the faces' solid angles, Van Oosterom and Strackee 1983). Clearance is
the radial clearance (see :mod:`satellite.shape.surfaces`).

:func:`load_surface` picks the shape of the surface check (the shipped Gaskell mesh, or a user's
OBJ file); :func:`body_mesh_info` gives observers the body's triangles.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from isf_robot.core import ConfigError
from isf_robot.paths import shared_data_dir
from satellite.errors import MeshError
from satellite.shape.cache import SHAPE_NAME, read_obj, shipped_mesh
from satellite.shape.mesh import TriangleMesh
from satellite.shape.surfaces import SurfaceModel, winding_numbers

__all__ = ["MeshSurface", "default_shape_path", "load_surface", "body_mesh_info"]


def default_shape_path() -> Path:
    """Return ``<shared data>/itokawa/itokawa_low.obj``, the raw default shape (which may not exist).

    Only regenerating the shipped files reads it (:mod:`satellite.shape.cache`, ``isf-satellite gravity
    --table``); runs use the shipped mesh (:func:`satellite.shape.cache.shipped_mesh`). The shared data
    folder is ``$ISF_ROBOT_DATA`` or ``../shared/data`` beside the checkout (see
    :func:`isf_robot.paths.shared_data_dir`).
    """
    return shared_data_dir() / "itokawa" / "itokawa_low.obj"


_SMALL_FACE_RAD = math.radians(17.0)
"""Faces whose directions from the origin fit in a cap of this angular radius are binned on the
cube map; larger ones are tested against every ray. Below 17 deg a face with a vertex behind a
cube face's hemisphere cannot reach that cube face's region (within 54.7 deg of its axis)."""


class MeshSurface(SurfaceModel):
    """Closed triangle mesh recentred at its constant-density centre of mass.

    Args:
        mesh: Closed, outward mesh [m] in the body axes (from :func:`satellite.shape.cache.read_obj`).
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
        """Read an OBJ shape file (see :func:`satellite.shape.cache.read_obj`) and recentre it."""
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
    """Shape model for the surface check and the contact watch.

    Args:
        shape: OBJ file; ``None`` for the default shape, the shipped Gaskell mesh
            (:func:`satellite.shape.cache.shipped_mesh`).
        units: Length unit of the OBJ file (``"km"`` for the Gaskell model).

    Returns:
        A :class:`MeshSurface` centred at the mesh's centre of mass.

    Raises:
        FileNotFoundError: An explicit ``shape`` file does not exist.
        MeshError: The file is not a closed, oriented triangle mesh (or the shipped mesh is missing).

    """
    if shape is None:
        return MeshSurface(shipped_mesh(), name=f"mesh {SHAPE_NAME} (Gaskell, centre of mass)")
    path = Path(shape)
    if not path.is_file():
        raise FileNotFoundError(f"shape file not found: {path} (an OBJ triangle mesh; without --shape the shipped "
                                "Itokawa shape is used)")
    return MeshSurface.from_obj(path, units=units)


def body_mesh_info(surface: SurfaceModel | None = None) -> dict[str, Any] | None:
    """The body's triangles for observers (the ``body_mesh`` entry of a run's start info).

    Args:
        surface: The run's surface-check shape; when it is a :class:`MeshSurface` its (already
            recentred) triangles are used, else the shipped default shape's.

    Returns:
        ``{"vertices": (N, 3) float64 [m] relative to the centre of mass (the gravity model's
        origin, body axes), "faces": (M, 3) int64 (outward), "name": str}``, or ``None`` when the
        shipped mesh is unreadable (a broken install): observers then draw the published-dimension
        ellipsoid.

    """
    if isinstance(surface, MeshSurface):
        return {"vertices": surface.vertices, "faces": surface.faces.astype(np.int64), "name": surface.name}
    try:
        mesh = shipped_mesh()
    except MeshError:
        return None
    return {
        "vertices": np.asarray(mesh.vertices - mesh.centre_of_mass, dtype=np.float64),
        "faces": np.asarray(mesh.faces, dtype=np.int64),
        "name": SHAPE_NAME,
    }
