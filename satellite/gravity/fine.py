"""Fine Cartesian B-spline boxes that correct the gravity table near the surface (C2, one lookup per call).

The shell table (:mod:`satellite.gravity.table`, 4 deg x 10 m cells) cannot follow the exact
field within a few tens of metres of the surface, where it varies on the scale of the distance
to the nearest faces. :mod:`satellite.gravity.near` fixed that by summing the nearby faces
exactly at every call (0.2-0.7 ms, and only C0 where a tile switches on). Here the same
correction is tabulated once on a fine Cartesian lattice (step ``h``, 4 m by default) in a few
boxes around the parts of the surface that reach into the table's radii:

    a(x) = T(x) + F(x),     F = cubic B-spline (C2) through node values delta_n,

* outside the body, ``delta_n = tau(d_n) [a_src(x_n) - T(x_n)]`` with ``a_src`` an accurate
  source (the table with its exact near-surface tiles, or the exact polyhedron field below the
  table's radii), ``d_n`` the node's distance to the surface and ``tau`` a smoothstep from 1 at
  ``d_full`` (25 m) to 0 at ``d_zero`` (35 m), beyond which the shell table alone is accurate;
* inside the body, within ``depth`` (``2 sqrt(3) h`` plus a step: every node a stencil of an
  outside point reaches), the **exterior field continued through the surface**:
  ``a_src(x_n) + 4 pi G rho (x_n - c_n) - T(x_n)``, ``c_n`` the closest surface point. Across a
  surface of density ``rho`` the gradient of the field jumps by ``4 pi G rho n n^T`` (Gauss's
  law); the added term removes that jump to first order, so the nodes inside continue the
  outside field smoothly and the spline stays accurate right up to the surface (measured:
  0.3 % instead of 1.3 % within 1 m of the surface with 2 m nodes, 0.6 % instead of 2.6 % with
  4 m nodes; REPRODUCTION.md has the final figures);
* elsewhere (deeper inside, or far from the surface) ``delta_n = 0``.

A second level (:func:`add_fine_level`, 2 m nodes within 6 m of the surface, in the band) corrects
what the table and the 4 m boxes leave near edges and vertices of the shape, where the exact
field's gradient is log-singular; every box keeps its own step and the corrections of all boxes add.

Each box carries ``ZERO_LAYERS`` rows of zero nodes on every side, so the B-spline's
coefficients die out (as ``0.27^k``) before the box's edge: leaving a box changes the field by
less than 1e-9 of the correction (below the integrator's tolerance), and inside the boxes the
field is C2 like the shell table's. Inside the body, beyond ``depth``, the field is the shell
table's (finite and smooth; it is not the exact interior field there, which no orbit needs).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from satellite.compiled import inlined
from satellite.errors import GravityModelError
from satellite.gravity.polyhedron import exact_parallel
from satellite.gravity.splines import bspline3

__all__ = ["FineBoxes", "boxes_correction", "NO_BOXES", "build_fine_boxes", "add_fine_level", "STEP_M", "D_FULL_M",
           "D_ZERO_M"]

STEP_M = 4.0
"""Default node spacing [m] of the boxes."""

D_FULL_M = 25.0
"""Default distance [m] from the surface within which the boxes carry the full correction."""

D_ZERO_M = 35.0
"""Default distance [m] from the surface beyond which the shell table alone answers."""

FINE2_STEP_M, FINE2_FULL_M, FINE2_ZERO_M = 2.0, 3.0, 6.0
"""Second level (:func:`add_fine_level`): node spacing, full correction within, none beyond [m]."""

ZERO_LAYERS = 16
"""Rows of zero nodes on each side of a box (coefficient leakage 0.27^16 = 7e-10 of the correction)."""


NO_BOXES = (np.zeros((0, 4)), np.zeros((0, 4), dtype=np.int64), np.zeros(0))
"""The packed arrays of no boxes (:meth:`FineBoxes.packed`)."""


@inlined
def boxes_correction(x: float, y: float, z: float, box_o: NDArray[np.float64], box_n: NDArray[np.int64],
                     coef: NDArray[np.float64]) -> tuple[float, float, float, bool]:
    """The boxes' correction [m/s^2] at a point [m]: the sum over the boxes holding it, and whether any does.

    Box ``b`` has its corner and ``1/step`` in ``box_o[b]``, its node counts and the offset of its
    coefficients in ``coef`` (flat, C order of (nx, ny, nz, 3)) in ``box_n[b]`` (:meth:`FineBoxes.packed`).
    """
    fx = fy = fz = 0.0
    hit = False
    for b in range(box_o.shape[0]):
        nx, ny, nz, off = box_n[b, 0], box_n[b, 1], box_n[b, 2], box_n[b, 3]
        inv = box_o[b, 3]
        bu = (x - box_o[b, 0]) * inv
        bv = (y - box_o[b, 1]) * inv
        bw = (z - box_o[b, 2]) * inv
        if not (1.0 <= bu < nx - 2 and 1.0 <= bv < ny - 2 and 1.0 <= bw < nz - 2):
            continue
        hit = True
        bi, bj, bk = int(bu), int(bv), int(bw)
        qa = bspline3(bu - bi)
        qb = bspline3(bv - bj)
        qc = bspline3(bw - bk)
        gx = gy = gz = 0.0
        for cc in range(4):  # per z layer, the 4 x 4 x-y sum, then weighted (as the shell's)
            sx = sy = sz = 0.0
            for aa in range(4):
                for bb in range(4):
                    wab = qa[aa] * qb[bb]
                    n = off + 3 * (((bi - 1 + aa) * ny + (bj - 1 + bb)) * nz + (bk - 1 + cc))
                    sx += wab * coef[n]
                    sy += wab * coef[n + 1]
                    sz += wab * coef[n + 2]
            gx += qc[cc] * sx
            gy += qc[cc] * sy
            gz += qc[cc] * sz
        fx += gx
        fy += gy
        fz += gz
    return fx, fy, fz, hit


class FineBoxes:
    """Fine correction boxes on a common lattice (see the module docstring).

    Args:
        step: Node spacing [m].
        boxes: Per box, the lattice index of its first node (3 integers: the node sits at
            ``step * index``) and its node values [m/s^2], shape (nx, ny, nz, 3).

    """

    def __init__(self, step: float, boxes: list[tuple[Any, ...]]) -> None:
        from scipy.ndimage import spline_filter1d  # (deferred: scipy.ndimage loads when boxes are first read)

        if not (math.isfinite(step) and step > 0):
            raise GravityModelError(f"fine box step must be a positive number of metres, got {step}")
        self.step = float(step)
        self.origins: list[NDArray[np.int64]] = []
        self.values: list[NDArray[np.float64]] = []
        self.steps: list[float] = []
        self._coef4: list[NDArray[np.float64]] = []
        heads = []
        for origin, values, *own in boxes:
            h = float(own[0]) if own else self.step
            if not (math.isfinite(h) and h > 0):
                raise GravityModelError(f"fine box step must be a positive number of metres, got {h}")
            o = np.asarray(origin, dtype=np.int64).reshape(3)
            v = np.asarray(values, dtype=np.float64)
            if v.ndim != 4 or v.shape[3] != 3 or min(v.shape[:3]) < 4 or not np.isfinite(v).all():
                raise GravityModelError(f"fine box values must be finite, shape (nx >= 4, ny, nz, 3), got {v.shape}")
            self.origins.append(o)
            self.values.append(v)
            self.steps.append(h)
            heads.append((o, v.shape[:3], h))
        sizes = [v.size for v in self.values]
        offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self._coef = np.empty(int(offsets[-1]))  # every box's coefficients, flat (one array for the kernels)
        self._box_o = np.zeros((len(heads), 4))
        self._box_n = np.zeros((len(heads), 4), dtype=np.int64)
        for b, ((o, shape, h), v) in enumerate(zip(heads, self.values)):
            c = v
            for axis in range(3):
                c = spline_filter1d(c, 3, axis=axis, mode="mirror")
            view = self._coef[offsets[b]: offsets[b + 1]]
            view[:] = c.reshape(-1)
            self._coef4.append(view.reshape(c.shape))
            self._box_o[b] = (float(o[0]) * h, float(o[1]) * h, float(o[2]) * h, 1.0 / h)
            self._box_n[b] = (*shape, offsets[b])

    def packed(self) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
        """``(box_o, box_n, coef)``: the boxes' corners and 1/step, node counts and offsets, flat coefficients."""
        return self._box_o, self._box_n, self._coef

    def merged(self, other: FineBoxes) -> FineBoxes:
        """The boxes of ``self`` and ``other`` (each keeps its step): their corrections add."""
        return FineBoxes(self.step, [(o, v, h) for b in (self, other) for o, v, h in zip(b.origins, b.values, b.steps)])

    def __len__(self) -> int:
        return len(self.values)

    def at(self, x: float, y: float, z: float) -> list[float] | None:
        """Correction [m/s^2] at one point [m] as three floats, or None outside every box (:func:`boxes_correction`)."""
        fx, fy, fz, hit = boxes_correction(x, y, z, self._box_o, self._box_n, self._coef)
        return [fx, fy, fz] if hit else None

    def at_batch(self, points: ArrayLike) -> NDArray[np.float64]:
        """Correction [m/s^2] at points [m], shape (N, 3) -> (N, 3) (zero outside the boxes)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.zeros_like(p)
        for (x0, y0, z0, inv), (nx, ny, nz, _), coef in zip(self._box_o.tolist(), self._box_n.tolist(), self._coef4):
            u = (p - np.array([x0, y0, z0])) * inv
            ok = ((u >= 1.0) & (u < np.array([nx, ny, nz]) - 2.0)).all(axis=1)
            if not ok.any():
                continue
            q = u[ok]
            idx = q.astype(np.intp)
            w = [np.stack(bspline3(q[:, a] - idx[:, a]), axis=1) for a in range(3)]
            acc = np.zeros((len(q), 3))
            for a in range(4):
                for b in range(4):
                    wab = w[0][:, a] * w[1][:, b]
                    for c in range(4):
                        acc += (wab * w[2][:, c])[:, None] * coef[idx[:, 0] - 1 + a, idx[:, 1] - 1 + b,
                                                                  idx[:, 2] - 1 + c]
            out[ok] += acc
        return out

    # -- files -------------------------------------------------------------------------------
    def to_arrays(self) -> dict[str, Any]:
        """Arrays for the table's ``.npz``: per box its lattice origin and shape, the non-zero nodes (sparse)."""
        heads, index, values = [], [], []
        for o, v in zip(self.origins, self.values):
            flat = v.reshape(-1, 3)
            nz = np.flatnonzero((flat != 0).any(axis=1))
            heads.append([*o.tolist(), *v.shape[:3], len(nz)])
            index.append(nz.astype(np.int32))
            values.append(flat[nz].astype(np.float32))
        return {"fine_step": np.array([self.step]), "fine_box_step": np.array(self.steps),
                "fine_boxes": np.array(heads, dtype=np.int64),
                "fine_index": np.concatenate(index), "fine_values": np.concatenate(values)}

    @classmethod
    def from_arrays(cls, data: Any) -> FineBoxes:
        """Inverse of :meth:`to_arrays` (node values come back as stored, float32)."""
        step = float(np.asarray(data["fine_step"]).reshape(-1)[0])
        heads = np.asarray(data["fine_boxes"], dtype=np.int64).reshape(-1, 7)
        steps = np.asarray(data["fine_box_step"], dtype=np.float64) if "fine_box_step" in data else \
            np.full(len(heads), step)  # tables before the second level: one step
        index, values = np.asarray(data["fine_index"]), np.asarray(data["fine_values"], dtype=np.float64)
        boxes, s = [], 0
        for (ox, oy, oz, nx, ny, nz, n), h in zip(heads.tolist(), steps.tolist()):
            dense = np.zeros((nx * ny * nz, 3))
            dense[index[s: s + n]] = values[s: s + n]
            boxes.append(((ox, oy, oz), dense.reshape(nx, ny, nz, 3), h))
            s += n
        return cls(step, boxes)


def _smoothstep(t: NDArray[np.float64]) -> NDArray[np.float64]:
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)  # type: ignore[no-any-return]


def build_fine_boxes(table: Any, source: Callable[[NDArray[np.float64]], NDArray[np.float64]], vertices: ArrayLike,
                     faces: ArrayLike, inside: Callable[[NDArray[np.float64]], NDArray[np.bool_]], g_rho: float, *,
                     step: float = STEP_M, d_full: float = D_FULL_M, d_zero: float = D_ZERO_M,
                     base: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
                     r_min: float | None = None,
                     region: Callable[[NDArray[np.float64]], NDArray[np.bool_]] | None = None,
                     log: Callable[[str], None] | None = None) -> FineBoxes | None:
    """Fine boxes correcting ``table`` (a :class:`~satellite.gravity.table.GravityTable`) near the surface.

    Args:
        table: The shell table; its B-spline part (extended below its radii) is what the boxes correct.
        source: The accurate acceleration [m/s^2] at points (N, 3) [m] (e.g. the table with its
            exact near-surface tiles within its radii, the exact field below them).
        vertices: Surface mesh vertices [m] in the body frame, shape (V, 3).
        faces: Its triangles, shape (F, 3).
        inside: Whether points (N, 3) lie inside the body (exact).
        g_rho: ``G rho`` [1/s^2] of the body.
        step: Node spacing [m].
        d_full: Full correction within this distance [m] of the surface.
        d_zero: No correction beyond this distance [m]; ``d_full < d_zero``.
        base: The acceleration [m/s^2] the boxes correct, Kepler included, at points (N, 3)
            (default: the table's B-spline plus Kepler; a second level passes that plus the first boxes).
        r_min: No nodes below this radius [m] (default: every node a stencil of a point within
            the table's radii uses, down to the spline's reach below them).
        region: Keep only the nodes where this is True (default: all).
        log: Called with progress lines.

    Returns:
        The boxes, or None when no part of the surface comes within ``d_zero`` of ``r_min``.

    """
    from scipy import ndimage
    from scipy.spatial import cKDTree

    from satellite.shape.closest import ClosestPoints  # (deferred with scipy.spatial: building boxes only)

    if not 0.0 <= d_full < d_zero:
        raise GravityModelError(f"fine boxes need 0 <= d_full < d_zero, got {d_full:g}, {d_zero:g} m")
    say = log or (lambda s: None)
    v = np.asarray(vertices, dtype=np.float64)
    reach = 2.0 * math.sqrt(3.0) * step  # farthest node a point's stencil uses
    depth = reach + step
    r_in = table.fast_radii[0]
    if r_min is None:
        r_min = max(r_in - reach - step, table.grid.r_lo - 2.0 * table.grid.dr)  # the spline's reach below r_lo
    rv = np.linalg.norm(v, axis=1)
    keep = rv >= r_min - d_zero - reach
    if not keep.any():
        return None
    lo = np.floor((v[keep].min(axis=0) - d_zero - reach) / step).astype(np.int64)
    hi = np.ceil((v[keep].max(axis=0) + d_zero + reach) / step).astype(np.int64)
    grid = np.stack(np.meshgrid(*[np.arange(lo[a], hi[a] + 1) for a in range(3)], indexing="ij"), axis=-1)
    nodes_idx = grid.reshape(-1, 3)
    nodes = nodes_idx * step
    r = np.linalg.norm(nodes, axis=1)
    sel = r >= r_min
    if region is not None:
        sel &= region(nodes)
    f = np.asarray(faces, dtype=np.intp)
    edge = float(np.linalg.norm(v[f] - v[np.roll(f, 1, axis=1)], axis=2).max())  # a vertex within d + edge
    near_any = np.isfinite(cKDTree(v).query(nodes[sel], distance_upper_bound=max(d_zero, depth) + edge)[0])
    sel[np.flatnonzero(sel)[~near_any]] = False
    nodes_idx, nodes = nodes_idx[sel], nodes[sel]
    cp, d = ClosestPoints(v, faces).query(nodes)
    say(f"fine boxes: {len(nodes)} candidate nodes")
    ins = inside(nodes)
    need = np.where(ins, d <= depth, d < d_zero)
    nodes_idx, nodes, cp, d, ins = nodes_idx[need], nodes[need], cp[need], d[need], ins[need]
    say(f"fine boxes: {len(nodes)} nodes ({int(ins.sum())} inside the body, "
        f"{int((np.linalg.norm(nodes, axis=1) < r_in).sum())} below the table's radii), step {step:g} m")
    if not len(nodes):
        return None
    acc = source(nodes)
    if base is None:
        delta = acc - (table.spline_batch(nodes) - table.gm * nodes / (np.linalg.norm(nodes, axis=1) ** 3)[:, None])
    else:
        delta = acc - base(nodes)
    delta[ins] += 4.0 * math.pi * g_rho * (nodes[ins] - cp[ins])
    delta[~ins] *= _smoothstep((d_zero - d[~ins]) / (d_zero - d_full))[:, None]
    # boxes: connected groups of nodes (bricks of 8 steps), merged while their padded boxes overlap
    brick = nodes_idx // 8
    b0 = brick.min(axis=0)
    occ = np.zeros(tuple(brick.max(axis=0) - b0 + 1), dtype=bool)
    occ[tuple((brick - b0).T)] = True
    labels, n_lab = ndimage.label(occ, structure=np.ones((3, 3, 3)))
    lab = labels[tuple((brick - b0).T)] - 1
    pad = ZERO_LAYERS + 2
    spans = [[nodes_idx[lab == g].min(axis=0) - pad, nodes_idx[lab == g].max(axis=0) + pad] for g in range(n_lab)]
    merged = True
    while merged:
        merged = False
        for a in range(len(spans)):
            for b in range(a + 1, len(spans)):
                if (spans[a][0] <= spans[b][1]).all() and (spans[b][0] <= spans[a][1]).all():
                    spans[a] = [np.minimum(spans[a][0], spans[b][0]), np.maximum(spans[a][1], spans[b][1])]
                    del spans[b]
                    merged = True
                    break
            if merged:
                break
    boxes = []
    for s_lo, s_hi in spans:
        m = ((nodes_idx >= s_lo) & (nodes_idx <= s_hi)).all(axis=1)
        dense = np.zeros((*(s_hi - s_lo + 1).tolist(), 3))
        dense[tuple((nodes_idx[m] - s_lo).T)] = delta[m].astype(np.float32)  # as stored
        boxes.append((s_lo, dense, step))
    say(f"fine boxes: {len(boxes)} box(es), shapes {[b[1].shape[:3] for b in boxes]}")
    return FineBoxes(step, boxes)


def add_fine_boxes(table: Any, field: Any, surface: Any, *, step: float = STEP_M, workers: int = 1,
                   log: Callable[[str], None] | None = None) -> Any:
    """Give ``table`` fine boxes (``table.fine``) built against ``field``; returns ``table``.

    Args:
        table: A :class:`~satellite.gravity.table.GravityTable` of ``field``'s body. With
            near-surface tiles the source within its radii is the tiled table (exact sums near
            the surface, 0.2-0.7 ms a node), without them the exact field (some ms a node).
        field: The exact :class:`~satellite.gravity.polyhedron.PolyhedronField` (below the table's radii,
            and for ``G rho``).
        surface: The body's :class:`~satellite.shape.mesh_surface.MeshSurface` (same frame: centre of mass).
        step: Node spacing [m].
        workers: Processes for the exact field's nodes.
        log: Called with progress lines.

    """
    def exact(p: NDArray[np.float64]) -> NDArray[np.float64]:
        return exact_parallel(field, p, workers)

    def source(p: NDArray[np.float64]) -> NDArray[np.float64]:
        r = np.linalg.norm(p, axis=1)
        ok = (r >= table.fast_radii[0]) & (r <= table.fast_radii[1])
        out = np.empty_like(p)
        out[~ok] = exact(p[~ok])
        out[ok] = table.acceleration_batch(p[ok]) if table.near is not None else exact(p[ok])
        return out

    saved_fine, table.fine = table.fine, None
    try:
        fine = build_fine_boxes(table, source, surface.vertices, surface.faces, lambda p: surface.query(p)[0],
                                field.g_rho, step=step, log=log)
    finally:
        table.fine = saved_fine
    table.fine = fine
    return table


def add_fine_level(table: Any, field: Any, surface: Any, *, step: float = FINE2_STEP_M, d_full: float = FINE2_FULL_M,
                   d_zero: float = FINE2_ZERO_M, r_band: float, workers: int = 1,
                   log: Callable[[str], None] | None = None) -> Any:
    """Add a finer level of boxes to ``table.fine`` within ``d_zero`` of the surface, in the band; returns ``table``.

    The first level (4 m nodes) cannot follow the exact field within a metre or two of sharp
    features of the surface (its gradient is log-singular at edges). This level corrects what
    the table and its first boxes leave, ``a_exact - (T + F)``, on ``step``-metre nodes: fully
    within ``d_full`` of the surface, faded out by a smoothstep at ``d_zero``, the exterior
    field continued inside the body as for the first level, and only at nodes a point at
    ``r >= r_band`` (the band's inner edge) reaches. Node values come from the exact field.
    """
    if table.fine is None:
        raise GravityModelError("a second level of fine boxes needs a table with a first level (--fine-step)")
    first = table.fine

    def base(p: NDArray[np.float64]) -> NDArray[np.float64]:
        kep = table.gm * p / (np.linalg.norm(p, axis=1) ** 3)[:, None]
        return table.spline_batch(p) - kep + first.at_batch(p)  # type: ignore[no-any-return]

    level = build_fine_boxes(table, lambda p: exact_parallel(field, p, workers), surface.vertices, surface.faces,
                             lambda p: surface.query(p)[0], field.g_rho, step=step, d_full=d_full, d_zero=d_zero,
                             base=base, r_min=r_band - (2.0 * math.sqrt(3.0) + 1.0) * step, log=log)
    if level is not None:
        table.fine = first.merged(level)
    return table
