"""Near the surface, the gravity table's cubic cannot follow the field: the faces there are summed exactly.

Within a few tens of metres of the surface the exact field varies on the scale of the distance
to the nearest faces (its gradient jumps across the surface and is log-singular at edges), far
below the table's cell size (4 deg, 18 m at 1.6 R), so the plain interpolant errs by several
per cent of the non-Kepler part there (the Itokawa band is crossed by both ends of the long axis,
which reach 1.93 R). The field is a sum over faces (:class:`satellite.gravity.polyhedron.FacePatch`), so

    a(x) = T(x) + sum_k s_k(x) [ a_k(x) - T_k(x) ],

with ``T`` the table of the whole field, the faces that reach above ``r_cut`` grouped into
compact **tiles** ``k`` of a few hundred faces, ``a_k`` a tile's exact field, ``T_k`` the same
B-spline interpolation of the tile's field (its coefficients kept at the nodes near the tile), and ``s_k`` a
weight that is 1 within ``d_in`` of the tile's nearest vertex and 0 beyond ``d_out``
(smoothstep between: the field stays continuous). Where ``s_k = 1`` the tile's part is exact and
what is left for the cubic is smooth on the cell scale (the other faces are at least ``d_in``
away, or below ``r_cut``). Beyond ``d_out`` of every tile (most of the band) one table lookup
answers. Measured accuracy and cost: REPRODUCTION.md and ``benchmarks/satellite_gravity.py``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from satellite.errors import GravityModelError
from satellite.gravity.polyhedron import FacePatch, PolyhedronField
from satellite.gravity.splines import pad_nodes as pad
from satellite.gravity.splines import prefilter

__all__ = ["NearTiles", "build_near_tiles", "tile_faces"]

D_IN_M = 30.0
"""Default distance [m] from a tile within which the tile is summed exactly."""

D_OUT_M = 40.0
"""Default distance [m] from a tile beyond which the table alone answers for it."""


def tile_faces(centroids: NDArray[np.float64], max_faces: int) -> NDArray[np.intp]:
    """Tile index of every face: recursive halving at the median of the widest axis of the centroids."""
    tile = np.zeros(len(centroids), dtype=np.intp)
    todo, n = [np.arange(len(centroids))], 0
    while todo:
        idx = todo.pop()
        if len(idx) <= max_faces:
            tile[idx] = n
            n += 1
            continue
        c = centroids[idx]
        axis = int(np.argmax(np.ptp(c, axis=0)))
        order = idx[np.argsort(c[:, axis], kind="stable")]
        todo += [order[len(order) // 2:], order[: len(order) // 2]]
    return tile


class NearTiles:
    """The exact near-surface correction of a :class:`~satellite.gravity.table.GravityTable`.

    Args:
        patch: The faces above ``r_cut`` (all tiles).
        tile: Tile index of each face of ``patch``, shape (F,).
        ext: Per tile, the B-spline coefficients of its field at the table's nodes near it, padded
            like the table (NaN at nodes no stencil near the tile uses), shape
            (K, n_r, n_lat + 4, n_lon + 4, 3).
        d_in: Exact within this distance [m] of a tile's nearest vertex.
        d_out: Table alone beyond this distance [m]; ``d_in < d_out <= d_max``.
        d_max: Largest ``d_out`` the tabulated nodes cover [m].

    """

    def __init__(self, patch: FacePatch, tile: NDArray[np.intp], ext: NDArray[np.float32],
                 d_in: float = D_IN_M, d_out: float = D_OUT_M, d_max: float = D_OUT_M) -> None:
        if not 0.0 <= d_in < d_out <= d_max:
            raise GravityModelError(f"near-surface distances must satisfy 0 <= d_in < d_out <= {d_max:g} m, "
                                    f"got {d_in:g}, {d_out:g}")
        self.patch, self.tile, self.ext = patch, np.asarray(tile, dtype=np.intp), ext
        self.d_in, self.d_out, self.d_max = float(d_in), float(d_out), float(d_max)
        k = len(ext)
        self.faces_of = [np.flatnonzero(self.tile == t) for t in range(k)]
        self.patches = [FacePatch(patch.triangles[f], patch.g_rho) for f in self.faces_of]
        self.vertices = [np.unique(patch.triangles[f].reshape(-1, 3), axis=0) for f in self.faces_of]
        self.centres = np.array([v.mean(axis=0) for v in self.vertices])
        self.radii = np.array([np.linalg.norm(v - c, axis=1).max() for v, c in zip(self.vertices, self.centres)])
        self._trees: list[Any] | None = None

    def weights(self, x: NDArray[np.float64]) -> list[tuple[int, float]]:
        """``(tile, s_k)`` for the tiles with ``s_k > 0`` at one point ``x`` [m]."""
        d = np.linalg.norm(self.centres - x, axis=1) - self.radii
        out = []
        for t in np.flatnonzero(d < self.d_out).tolist():
            v = self.vertices[t] - x
            dk = math.sqrt(float(np.einsum("vi,vi->v", v, v).min()))
            if dk < self.d_out:
                u = min(1.0, (self.d_out - dk) / (self.d_out - self.d_in))
                out.append((t, u * u * (3.0 - 2.0 * u)))
        return out

    def near(self, p: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Which points (N, 3) may get a correction (within ``d_out`` of a tile's bounding sphere)."""
        d = np.linalg.norm(p[:, None, :] - self.centres[None], axis=2) - self.radii[None]
        return (d < self.d_out).any(axis=1)  # type: ignore[no-any-return]

    def correction(self, x: NDArray[np.float64], k: int, i: int, j: int, wr: NDArray[np.float64],
                   wl: NDArray[np.float64], wn: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """``sum_k s_k (a_k - T_k)`` at ``x`` [m] for the table's stencil (cells ``k, i, j``, weights), or None."""
        ws = self.weights(x)
        if not ws:
            return None
        exact = sum(s * self.patches[t].point_acceleration(x) for t, s in ws)
        block = sum(s * self.ext[t, k - 1: k + 3, i + 1: i + 5, j + 1: j + 5].astype(np.float64) for t, s in ws)
        tab = np.einsum("a,b,c,abcd->d", wr, wl, wn, block)
        if not np.isfinite(tab).all():
            raise GravityModelError("near-surface tile value missing at a stencil node (table built with a "
                                    "smaller d_max)")
        return exact - tab  # type: ignore[no-any-return]

    def correction_batch(self, x: NDArray[np.float64], k: NDArray[np.intp], i: NDArray[np.intp],
                         j: NDArray[np.intp], wr: NDArray[np.float64], wl: NDArray[np.float64],
                         wn: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`correction` at many points (N, 3) with their stencils (N,) and weights (N, 4); zeros where none.

        Tile by tile: the points within ``d_out`` of its vertices (a k-d tree), its faces summed
        for all of them at once (:meth:`FacePatch.acceleration`), its B-spline gathered.
        """
        from scipy.spatial import cKDTree

        out = np.zeros((len(x), 3))
        if self._trees is None:
            self._trees = [cKDTree(v) for v in self.vertices]
        for t, tree in enumerate(self._trees):
            dk = tree.query(x, distance_upper_bound=self.d_out)[0]
            m = np.flatnonzero(dk < self.d_out)
            if not len(m):
                continue
            u = np.minimum(1.0, (self.d_out - dk[m]) / (self.d_out - self.d_in))
            s = u * u * (3.0 - 2.0 * u)
            tab = np.zeros((len(m), 3))
            km, im, jm = k[m], i[m], j[m]
            for a in range(4):
                for b in range(4):
                    wab = wr[m, a] * wl[m, b]
                    for c in range(4):
                        tab += (wab * wn[m, c])[:, None] * self.ext[t, km - 1 + a, im + 1 + b, jm + 1 + c]
            if not np.isfinite(tab).all():
                raise GravityModelError("near-surface tile value missing at a stencil node (table built with a "
                                        "smaller d_max)")
            out[m] += s[:, None] * (self.patches[t].acceleration(x[m]) - tab)
        return out

    # -- files -------------------------------------------------------------------------------
    def to_arrays(self) -> dict[str, Any]:
        """Arrays for the table's ``.npz``: the triangles, tiles and the tiles' coefficients near them (sparse)."""
        flat = self.ext[:, :, 2:-2, 2:-2].reshape(len(self.ext), -1, 3)
        keep = np.isfinite(flat[..., 0])
        t_idx, n_idx = np.nonzero(keep)
        return {"near_triangles": self.patch.triangles, "near_tile": self.tile.astype(np.int32),
                "near_node_tile": t_idx.astype(np.int32), "near_node": n_idx.astype(np.int32),
                "near_coef": flat[keep].astype(np.float32),
                "near_d": np.array([self.d_in, self.d_out, self.d_max, self.patch.g_rho])}

    @classmethod
    def from_arrays(cls, data: Any, grid: Any) -> NearTiles:
        """Inverse of :meth:`to_arrays` for a table's ``grid``."""
        d_in, d_out, d_max, g_rho = (float(v) for v in data["near_d"])
        tile = np.asarray(data["near_tile"], dtype=np.intp)
        k = int(tile.max()) + 1
        dense = np.full((k, grid.n_r * grid.n_lat * grid.n_lon, 3), np.nan, dtype=np.float32)
        dense[np.asarray(data["near_node_tile"]), np.asarray(data["near_node"])] = data["near_coef"]
        dense = dense.reshape(k, grid.n_r, grid.n_lat, grid.n_lon, 3)
        ext = np.stack([pad(dense[t], grid.n_lat) for t in range(k)])
        return cls(FacePatch(data["near_triangles"], g_rho), tile, ext, d_in, d_out, d_max)


def build_near_tiles(field: PolyhedronField, grid: Any, *, r_cut: float, max_faces: int = 300,
                     d_in: float = D_IN_M, d_out: float = D_OUT_M) -> NearTiles | None:
    """Tiles of the faces of ``field`` with a vertex above ``r_cut`` [m] (None when there are none).

    Each tile's field is computed at every node of ``grid`` (a table's
    :class:`~satellite.gravity.table.TableGrid`), turned into B-spline coefficients, and kept at
    the nodes that a stencil of a point within ``d_out`` of the tile can use (within ``d_out``
    plus the stencil's reach of a vertex).
    """
    rv = np.linalg.norm(field.vertices, axis=1)
    mask = rv[field.faces].max(axis=1) > r_cut
    if not mask.any():
        return None
    patch = FacePatch.from_field(field, mask)
    tile = tile_faces(patch.triangles.mean(axis=1), max_faces)
    nodes = grid.nodes().reshape(-1, 3)
    reach = 2.0 * math.sqrt(grid.dr**2 + 2.0 * (grid.dang * grid.r_hi) ** 2) + float(patch._len.max())
    k = int(tile.max()) + 1
    from scipy.spatial import cKDTree  # here: loading a table (every run) needs no k-d tree

    dense = np.full((k, len(nodes), 3), np.nan, dtype=np.float32)
    for t in range(k):
        tri = patch.triangles[tile == t]
        near = np.isfinite(cKDTree(tri.reshape(-1, 3)).query(nodes, distance_upper_bound=d_out + reach)[0])
        values = FacePatch(tri, patch.g_rho).acceleration(nodes).reshape(grid.n_r, grid.n_lat, grid.n_lon, 3)
        dense[t, near] = prefilter(values).reshape(-1, 3)[near]
    dense = dense.reshape(k, grid.n_r, grid.n_lat, grid.n_lon, 3)
    ext = np.stack([pad(dense[t], grid.n_lat) for t in range(k)])
    return NearTiles(patch, tile, ext, d_in, d_out, d_out)


def cell_flags(near: NearTiles, grid: Any) -> NDArray[np.bool_]:
    """Per table cell ``(k, i + 1, j + 1)``: can a point of it lie within ``d_out`` of a tile (conservative).

    ``k`` is the radial cell, ``i, j`` the table's floor indices in latitude and longitude (from -1).
    """
    r = grid.r_lo + grid.dr * (np.arange(grid.n_r) + 0.5)
    lat_edges = np.clip(-0.5 * math.pi + grid.dang * (np.arange(grid.n_lat + 2) - 0.5), -0.5 * math.pi, 0.5 * math.pi)
    lat = 0.5 * (lat_edges[:-1] + lat_edges[1:])
    lon = -math.pi + grid.dang * np.arange(grid.n_lon + 1)
    R, LA, LO = np.meshgrid(r, lat, lon, indexing="ij")
    centres = np.stack([R * np.cos(LA) * np.cos(LO), R * np.cos(LA) * np.sin(LO), R * np.sin(LA)], axis=-1)
    half = 0.5 * math.sqrt(grid.dr**2 + 2.0 * (grid.dang * (grid.r_hi + grid.dr)) ** 2)
    verts = np.concatenate(near.vertices)
    from scipy.spatial import cKDTree

    d = cKDTree(verts).query(centres.reshape(-1, 3))[0].reshape(R.shape)
    return d <= near.d_out + half + float(near.patch._len.max())  # type: ignore[no-any-return]
