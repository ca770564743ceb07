"""Fast gravity for long runs: the exact polyhedron field tabulated once on a body-frame shell grid.

The table holds the non-Kepler part ``a - (-GM r / |r|^3)`` of the exact constant-density
polyhedron field (:mod:`satellite.gravity.polyhedron`) at the nodes of a spherical grid in the body
frame: radii ``r_k = r_lo + k dr`` (``k = 0 .. n_r - 1``), latitudes at the centres of
``n_lat`` equal cells, longitudes at the centres of ``2 n_lat`` equal cells. Between nodes each
Cartesian component is interpolated by a tensor-product cubic B-spline in radius, latitude and
longitude (64 coefficients per point, C2, fourth-order accurate) that passes through the node
values: the coefficients come from the values by the usual prefilter (:func:`prefilter`: along
every great circle through both poles, which is periodic, along longitude, periodic, and along
radius with extrapolated ghost nodes beyond the ends). C2 matters: a C1 interpolant (e.g.
Catmull-Rom) made DOP853 at rtol 1e-10 take 6x more steps than the degree-8 series, its second
derivative jumping at every cell face; with the B-spline it takes about 1.2x. The Kepler part is added
back exactly. Outside ``[r_lo + dr, r_hi - dr]`` (the table's radii) the shell part is the same
spline out to the end nodes and continued radially beyond them (:func:`shell_continued`, value- and
slope-matched), then the fine boxes and Kepler as inside. The interpolant is continuous except
exactly at the poles, where its value depends on the longitude of approach by at most about twice
the interpolation error. Within a few tens of metres of the surface the shell's cells are too
coarse: fine Cartesian B-spline boxes correct it there (:mod:`satellite.gravity.fine`, also C2),
built from the exact near-surface tile sums of :mod:`satellite.gravity.near` (which the table
applies itself, at 0.2-0.7 ms a call, only when it has no boxes).

The grid is generated once (the polyhedron costs a few ms per node: about 23 min for the default
grid on 2 cores) by ``isf-satellite gravity --table`` and written as ``.npz`` with its provenance;
the default Itokawa table is committed (``satellite/data/``, loaded by
:func:`satellite.gravity.fields.load_field`). The measured accuracy of the default grid is in REPRODUCTION.md.
"""

from __future__ import annotations

import io
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from isf_robot.support.files import write_bytes_atomic
from satellite.compiled import compiled, inlined
from satellite.errors import GravityModelError
from satellite.gravity.fine import NO_BOXES, FineBoxes, boxes_correction
from satellite.gravity.near import NearTiles, build_near_tiles, cell_flags
from satellite.gravity.polyhedron import PolyhedronField, exact_parallel
from satellite.gravity.splines import RG as _RG
from satellite.gravity.splines import bspline3, dbspline3, pad_nodes, prefilter

__all__ = ["GravityTable", "TableGrid", "build_table", "shell_spline", "shell_continued", "table_acceleration",
           "table_accelerations"]

TABLE_FORMAT = "isf-satellite-gravity-table/2"
"""/2: cubic B-spline through the node values (/1 was Catmull-Rom and is refused: rebuild it)."""

@inlined
def shell_continued(x: float, y: float, z: float, ext: NDArray[np.float64], r_lo: float, r_hi: float, inv_dr: float,
                    inv_dang: float, n_r: int) -> tuple[float, float, float]:
    """The table's shell part (non-Kepler, [m/s^2]) at a body-frame point [m] outside its radii, continued.

    Between the table's end nodes ``r_lo`` and ``r_hi`` (its radii leave out one cell at each end)
    it is the shell B-spline itself, through the node values as inside. Beyond them, with ``r_b``
    the nearer end node and ``S``, ``S' = dS/dr`` the spline and its radial derivative at ``r_b``
    in the point's direction, each component is continued radially as

        ``f(r) = (r_b / r)^4 [S + (r - r_b) (S' + 4 S / r_b)]``,

    which equals ``S`` with slope ``S'`` at ``r_b`` (C1 there; the second derivative jumps) and
    decays like the field's leading non-Kepler (quadrupole) term, ``r^-4``, with a linear correction.
    The caller adds the fine boxes (Cartesian, built across ``r_in`` down to ~1.39 R) and the Kepler
    part, as inside the radii (:func:`table_acceleration`); ``ext`` is the table's padded coefficients
    (``GravityTable._ext``).

    Why it is sound: a run's accepted trajectory stays in the band, ``[1.6 R, 2.4 R]``, inside the
    table's radii ``[1.5625 R, 2.4375 R]``; only DOP853's stage and trial points of steps near the
    band's edges reach outside (``r/R`` 1.47-2.56 at ``--alpha-gain`` x100), within ~0.12 R, where
    this answers to a fraction of a per cent of the non-Kepler part (measured against the exact
    field outside the body: REPRODUCTION.md, "The truth field and its accuracy"), and the step's
    accepted point is back in the band. An accepted point outside the radii lies past a band exit,
    which the run reports (``none`` and ``periodic`` stop at the first exit, ``greedy`` and
    ``maneuver`` count ``band_exits``); beyond it the field is this continuation, not the exact
    field. The contact watch's sample points below the radii use the exact field
    (:func:`satellite.gravity.fields.exact_samples`).
    """
    r = math.sqrt(x * x + y * y + z * z)
    rb = min(max(r, r_lo), r_hi)
    u = (rb - r_lo) * inv_dr
    k = min(int(u), n_r - 2)
    v = (math.asin(z / r) + 0.5 * math.pi) * inv_dang - 0.5
    i = math.floor(v)
    w = (math.atan2(y, x) + math.pi) * inv_dang - 0.5
    j = math.floor(w)
    wa = bspline3(u - k)
    da = dbspline3(u - k)
    wb = bspline3(v - i)
    wc = bspline3(w - j)
    sx = sy = sz = dx = dy = dz = 0.0
    for aa in range(4):
        for bb in range(4):
            for cc in range(4):
                e = ext[k + _RG - 1 + aa, i + 1 + bb, j + 1 + cc]
                wv = wa[aa] * wb[bb] * wc[cc]
                wd = da[aa] * wb[bb] * wc[cc] * inv_dr
                sx += wv * e[0]
                sy += wv * e[1]
                sz += wv * e[2]
                dx += wd * e[0]
                dy += wd * e[1]
                dz += wd * e[2]
    if r == rb:
        return sx, sy, sz
    q = rb / r
    q2 = q * q
    q4 = q2 * q2  # (r_b / r)^4: the quadrupole's decay
    lin = r - rb
    return (q4 * (sx + lin * (dx + 4.0 * sx / rb)), q4 * (sy + lin * (dy + 4.0 * sy / rb)),
            q4 * (sz + lin * (dz + 4.0 * sz / rb)))


@inlined
def shell_spline(x: float, y: float, z: float, r: float, ext: NDArray[np.float64], r_lo: float, inv_dr: float,
                 inv_dang: float, n_r: int) -> tuple[float, float, float]:
    """The table's shell B-spline (non-Kepler, [m/s^2]) at a body-frame point [m] of radius ``r`` within its radii."""
    u = (r - r_lo) * inv_dr
    k = min(int(u), n_r - 3)
    v = (math.asin(z / r) + 0.5 * math.pi) * inv_dang - 0.5
    i = math.floor(v)
    w = (math.atan2(y, x) + math.pi) * inv_dang - 0.5
    j = math.floor(w)
    wa = bspline3(u - k)
    wb = bspline3(v - i)
    wc = bspline3(w - j)
    ax = ay = az = 0.0
    for cc in range(4):  # per longitude layer, the 4 x 4 radius-latitude sum, then weighted
        sx = sy = sz = 0.0
        for aa in range(4):
            for bb in range(4):
                wab = wa[aa] * wb[bb]
                e = ext[k + _RG - 1 + aa, i + 1 + bb, j + 1 + cc]
                sx += wab * e[0]
                sy += wab * e[1]
                sz += wab * e[2]
        ax += wc[cc] * sx
        ay += wc[cc] * sy
        az += wc[cc] * sz
    return ax, ay, az


@compiled
def table_acceleration(x: float, y: float, z: float, geom: NDArray[np.float64], ext: NDArray[np.float64],
                       box_o: NDArray[np.float64], box_n: NDArray[np.int64],
                       coef: NDArray[np.float64]) -> tuple[float, float, float]:
    """The tabulated field [m/s^2] at a body-frame point [m]: shell part, fine boxes, Kepler.

    The shell part is :func:`shell_spline` within the table's radii, :func:`shell_continued` outside them;
    the fine boxes' correction is :func:`satellite.gravity.fine.boxes_correction`. ``geom`` holds
    ``GM, r_lo, r_hi, 1/dr, 1/dang, n_r, r_in, r_out`` (:attr:`GravityTable.geom`); ``box_o``, ``box_n``,
    ``coef`` are the boxes' packed arrays (:class:`satellite.gravity.fine.FineBoxes`). The one evaluation of
    both the Python path (:meth:`GravityTable.acceleration`) and the compiled arcs.
    """
    r2 = x * x + y * y + z * z
    r = math.sqrt(r2)
    n_r = int(geom[5])
    if geom[6] <= r <= geom[7]:
        ax, ay, az = shell_spline(x, y, z, r, ext, geom[1], geom[3], geom[4], n_r)
    else:
        ax, ay, az = shell_continued(x, y, z, ext, geom[1], geom[2], geom[3], geom[4], n_r)
    fx, fy, fz, _ = boxes_correction(x, y, z, box_o, box_n, coef)
    kep = -geom[0] / (r2 * r)
    return ax + fx + kep * x, ay + fy + kep * y, az + fz + kep * z


@compiled
def table_accelerations(points: NDArray[np.float64], geom: NDArray[np.float64], ext: NDArray[np.float64],
                        box_o: NDArray[np.float64], box_n: NDArray[np.int64],
                        coef: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`table_acceleration` at each row of ``points`` (N, 3) -> (N, 3)."""
    out = np.empty((points.shape[0], 3))
    for n in range(points.shape[0]):
        ax, ay, az = table_acceleration(points[n, 0], points[n, 1], points[n, 2], geom, ext, box_o, box_n, coef)
        out[n, 0] = ax
        out[n, 1] = ay
        out[n, 2] = az
    return out


class TableGrid:
    """The grid of a table (see the module docstring).

    Args:
        r_lo: Smallest node radius [m].
        r_hi: Largest node radius [m].
        n_r: Radial nodes, >= 4.
        n_lat: Latitude cells (longitude cells ``2 n_lat``), >= 4.

    """

    def __init__(self, r_lo: float, r_hi: float, n_r: int, n_lat: int) -> None:
        if not (0 < r_lo < r_hi and n_r >= 4 and n_lat >= 4):
            raise GravityModelError(f"bad table grid: r in [{r_lo}, {r_hi}] m, {n_r} radii, {n_lat} latitudes")
        self.r_lo, self.r_hi = float(r_lo), float(r_hi)
        self.n_r, self.n_lat, self.n_lon = int(n_r), int(n_lat), 2 * int(n_lat)
        self.dr = (self.r_hi - self.r_lo) / (self.n_r - 1)
        self.dang = math.pi / self.n_lat

    def describe(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {"r_lo_m": self.r_lo, "r_hi_m": self.r_hi, "n_r": self.n_r, "n_lat": self.n_lat, "n_lon": self.n_lon}

    def nodes(self) -> NDArray[np.float64]:
        """Node positions [m], shape (n_r, n_lat, n_lon, 3)."""
        r = self.r_lo + self.dr * np.arange(self.n_r)
        lat = -0.5 * math.pi + self.dang * (np.arange(self.n_lat) + 0.5)
        lon = -math.pi + self.dang * (np.arange(self.n_lon) + 0.5)
        la, lo = np.meshgrid(lat, lon, indexing="ij")
        u = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)
        return r[:, None, None, None] * u[None]


class GravityTable:
    """Body-frame gravity from a table of the exact field's non-Kepler part (see module docstring).

    Args:
        grid: The table's grid.
        values: Non-Kepler acceleration [m/s^2] at the nodes, shape (n_r, n_lat, n_lon, 3).
        r_ref_m: Reference radius R [m] (as the degree-8 table's, for the band).
        gm: ``GM`` [m^3/s^2].
        exact: The exact field (anything with ``acceleration((N, 3))``) the table was built from, or
            ``None``; the contact watch's samples outside the radii use it
            (:func:`satellite.gravity.fields.exact_samples`); the table itself answers everywhere.
        provenance: Where the table came from (stored with it).
        near: Exact near-surface tiles (:mod:`satellite.gravity.near`), used when there are no
            ``fine`` boxes (and to build them).
        fine: Fine correction boxes near the surface (:mod:`satellite.gravity.fine`).

    """

    degree = None
    model_name = "polyhedron-table"

    def __init__(self, grid: TableGrid, values: NDArray[np.float64], r_ref_m: float, gm: float,
                 exact: Any = None, provenance: dict[str, Any] | None = None, near: Any = None,
                 fine: Any = None) -> None:
        if values.shape != (grid.n_r, grid.n_lat, grid.n_lon, 3) or not np.isfinite(values).all():
            raise GravityModelError(f"table values must be finite, shape {(grid.n_r, grid.n_lat, grid.n_lon, 3)}")
        self.grid, self.values = grid, values
        self.r_ref_m, self.gm = float(r_ref_m), float(gm)
        self.exact = exact
        self.provenance = dict(provenance or {})
        # radial ghost layers of coefficients on each side: the spline extends two cells below r_lo
        self._ext = np.ascontiguousarray(pad_nodes(prefilter(values, ghosts=_RG), grid.n_lat))
        self._r_in, self._r_out = grid.r_lo + grid.dr, grid.r_hi - grid.dr
        self._inv_dr, self._inv_dang = 1.0 / grid.dr, 1.0 / grid.dang
        self.geom = np.array([self.gm, grid.r_lo, grid.r_hi, self._inv_dr, self._inv_dang, grid.n_r, self._r_in,
                              self._r_out], dtype=np.float64)
        """``GM, r_lo, r_hi, 1/dr, 1/dang, n_r, r_in, r_out``: the scalars of :func:`table_acceleration`."""
        self.near, self.fine = near, fine
        self._near_cells: NDArray[np.bool_] | None = None  # the tiles answer only in a table without boxes

    def _cells(self) -> NDArray[np.bool_]:
        """Per cell: may a tile correct it (:func:`satellite.gravity.near.cell_flags`, computed on first use)."""
        if self._near_cells is None:
            self._near_cells = cell_flags(self.near, self.grid)
        return self._near_cells

    @property
    def fast_radii(self) -> tuple[float, float]:
        """Radii [m] between which the table answers directly (outside: :func:`shell_continued`)."""
        return self._r_in, self._r_out

    # -- evaluation ---------------------------------------------------------------------------
    def acceleration(self, r_body: ArrayLike) -> NDArray[np.float64]:
        """Acceleration [m/s^2] at one body-frame point [m] (shape (3,) or a 3-tuple); (k, 3) goes to the batch path.

        :func:`table_acceleration` (compiled where numba is used); a table with exact near-surface tiles instead
        of fine boxes adds the tiles' correction.
        """
        if type(r_body) is tuple:
            x, y, z = r_body
        else:
            p = np.asarray(r_body, dtype=np.float64)
            if p.ndim == 2:
                return self.acceleration_batch(p)
            x, y, z = p.tolist()
        if self.fine is None and self.near is not None:
            return self._with_tiles(x, y, z)
        box_o, box_n, coef = self.fine.packed() if self.fine is not None else NO_BOXES
        return np.array(table_acceleration(x, y, z, self.geom, self._ext, box_o, box_n, coef))

    def _with_tiles(self, x: float, y: float, z: float) -> NDArray[np.float64]:
        """:meth:`acceleration` of a table whose near-surface correction is its exact tiles (no fine boxes)."""
        box_o, box_n, coef = NO_BOXES
        ax, ay, az = table_acceleration(x, y, z, self.geom, self._ext, box_o, box_n, coef)
        r = math.sqrt(x * x + y * y + z * z)
        if not self._r_in <= r <= self._r_out:
            return np.array([ax, ay, az])
        g = self.grid
        u = (r - g.r_lo) * self._inv_dr
        k = min(int(u), g.n_r - 3)
        v = (math.asin(z / r) + 0.5 * math.pi) * self._inv_dang - 0.5
        i = math.floor(v)
        w = (math.atan2(y, x) + math.pi) * self._inv_dang - 0.5
        j = math.floor(w)
        if self._cells()[k, i + 1, j + 1]:
            fix = self.near.correction(np.array([x, y, z]), k, i, j, np.array(bspline3(u - k)),
                                       np.array(bspline3(v - i)), np.array(bspline3(w - j)))
            if fix is not None:
                ax, ay, az = ax + float(fix[0]), ay + float(fix[1]), az + float(fix[2])
        return np.array([ax, ay, az])

    def spline_batch(self, r_body: ArrayLike) -> NDArray[np.float64]:
        """The shell B-spline alone (non-Kepler part [m/s^2], no tiles, no boxes) at points [m], (N, 3) -> (N, 3).

        Defined from two radial steps below ``r_lo`` to ``r_hi`` (below the table's radii the
        spline is continued through extrapolated ghost nodes: for building fine boxes only).
        """
        q = np.asarray(r_body, dtype=np.float64).reshape(-1, 3)
        g = self.grid
        rq = np.linalg.norm(q, axis=1)
        if len(q) and not (rq.min() >= g.r_lo - 2 * g.dr and rq.max() <= g.r_hi):
            raise GravityModelError(f"spline_batch: radii must lie in [{g.r_lo - 2 * g.dr:.6g}, {g.r_hi:.6g}] m")
        u = (rq - g.r_lo) / g.dr
        k = np.minimum(np.floor(u).astype(np.intp), g.n_r - 3)
        v = (np.arcsin(np.clip(q[:, 2] / np.where(rq > 0, rq, 1.0), -1.0, 1.0)) + 0.5 * math.pi) / g.dang - 0.5
        i = np.floor(v).astype(np.intp)
        w = (np.arctan2(q[:, 1], q[:, 0]) + math.pi) / g.dang - 0.5
        j = np.floor(w).astype(np.intp)
        wr, wl, wn = (np.stack(bspline3(t), axis=1) for t in (u - k, v - i, w - j))
        acc = np.zeros((len(q), 3))
        for a in range(4):
            for b in range(4):
                wab = wr[:, a] * wl[:, b]
                for c in range(4):
                    acc += (wab * wn[:, c])[:, None] * self._ext[k + _RG - 1 + a, i + 1 + b, j + 1 + c]
        return acc

    def acceleration_batch(self, r_body: ArrayLike) -> NDArray[np.float64]:
        """Acceleration [m/s^2] at body-frame points [m], shape (N, 3) -> (N, 3) (:func:`table_accelerations`)."""
        p = np.ascontiguousarray(r_body, dtype=np.float64).reshape(-1, 3)
        if self.fine is not None or self.near is None:
            box_o, box_n, coef = self.fine.packed() if self.fine is not None else NO_BOXES
            return table_accelerations(p, self.geom, self._ext, box_o, box_n, coef)  # type: ignore[no-any-return]
        # a table with exact near-surface tiles (no fine boxes): the tiles' correction, vectorised
        g = self.grid
        r = np.linalg.norm(p, axis=1)
        out = np.empty_like(p)
        ok = (r >= self._r_in) & (r <= self._r_out)
        out[~ok] = table_accelerations(np.ascontiguousarray(p[~ok]), self.geom, self._ext, *NO_BOXES)
        q, rq = p[ok], r[ok]
        acc = self.spline_batch(q)
        u = (rq - g.r_lo) / g.dr
        k = np.minimum(u.astype(np.intp), g.n_r - 3)
        v = (np.arcsin(q[:, 2] / rq) + 0.5 * math.pi) / g.dang - 0.5
        i = np.floor(v).astype(np.intp)
        w = (np.arctan2(q[:, 1], q[:, 0]) + math.pi) / g.dang - 0.5
        j = np.floor(w).astype(np.intp)
        wr, wl, wn = (np.stack(bspline3(t), axis=1) for t in (u - k, v - i, w - j))
        m = np.flatnonzero(self._cells()[k, i + 1, j + 1])
        if len(m):
            acc[m] += self.near.correction_batch(q[m], k[m], i[m], j[m], wr[m], wl[m], wn[m])
        out[ok] = acc - self.gm * q / (rq**3)[:, None]
        return out

    # -- files -------------------------------------------------------------------------------
    def save(self, path: str | Path) -> None:
        """Write the table as ``.npz`` (atomically: a temporary file renamed into place, usual permissions)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {"format": TABLE_FORMAT, "grid": self.grid.describe(), "r_ref_m": self.r_ref_m, "gm": self.gm,
                "provenance": self.provenance}
        arrays = self.near.to_arrays() if self.near is not None else {}
        if self.fine is not None:
            arrays.update(self.fine.to_arrays())
        buf = io.BytesIO()
        np.savez_compressed(buf, values=self.values, meta=np.array(json.dumps(meta)), **arrays)
        write_bytes_atomic(path, buf.getvalue())

    @classmethod
    def load(cls, path: str | Path, exact: Any = None) -> GravityTable:
        """Read a table written by :meth:`save`."""
        try:
            with np.load(path) as data:
                values = np.asarray(data["values"], dtype=np.float64)
                meta = json.loads(str(data["meta"]))
                near_arrays = {key: data[key] for key in data.files if key.startswith("near_")}
                fine_arrays = {key: data[key] for key in data.files if key.startswith("fine_")}
        except (OSError, KeyError, ValueError) as exc:
            raise GravityModelError(f"{path}: not a gravity table ({exc})") from None
        if meta.get("format") != TABLE_FORMAT:
            raise GravityModelError(f"{path}: format {meta.get('format')!r}, expected {TABLE_FORMAT!r}")
        grid = TableGrid(*(meta["grid"][key] for key in ("r_lo_m", "r_hi_m", "n_r", "n_lat")))
        near = None
        if near_arrays:
            try:
                near = NearTiles.from_arrays(near_arrays, grid)
            except (KeyError, ValueError, IndexError) as exc:
                raise GravityModelError(f"{path}: bad near-surface tiles ({exc})") from None
        fine = None
        if fine_arrays:
            try:
                fine = FineBoxes.from_arrays(fine_arrays)
            except (KeyError, ValueError, IndexError) as exc:
                raise GravityModelError(f"{path}: bad fine boxes ({exc})") from None
        return cls(grid, values, meta["r_ref_m"], meta["gm"], exact, meta.get("provenance"), near, fine)


def build_table(field: PolyhedronField, grid: TableGrid, r_ref_m: float, *, workers: int = 1,
                progress: Callable[[int, int], None] | None = None,
                provenance: dict[str, Any] | None = None, near_cut: float | None = None) -> GravityTable:
    """Evaluate the exact field at every node of ``grid`` (in ``workers`` processes) and tabulate it.

    Args:
        field: The exact field.
        grid: The grid.
        r_ref_m: Reference radius R [m] of the table.
        workers: Processes (1: in this process).
        progress: Called with ``(nodes done, nodes)`` after each chunk.
        provenance: Stored with the table.
        near_cut: With a radius [m], the faces reaching above it are also tiled and summed exactly
            near the surface (:mod:`satellite.gravity.near`); ``None``: the table alone.

    """
    nodes = grid.nodes().reshape(-1, 3)
    acc = exact_parallel(field, nodes, workers, progress)
    r = np.linalg.norm(nodes, axis=1)
    values = (acc + field.gm * nodes / (r**3)[:, None]).reshape(grid.n_r, grid.n_lat, grid.n_lon, 3)
    near = None
    if near_cut is not None:
        near = build_near_tiles(field, grid, r_cut=near_cut)
    return GravityTable(grid, values, r_ref_m, field.gm, field, provenance, near)
