"""Exact gravity of a constant-density polyhedron (Werner and Scheeres 1997).

Werner, R. A. and Scheeres, D. J. (1997), "Exterior gravitation of a polyhedron derived and
compared with harmonic and mascon gravitation representations of asteroid 4769 Castalia",
Celestial Mechanics and Dynamical Astronomy 65:313-344. With ``x`` the field point, for a
closed, outward-oriented triangle mesh of density ``rho``:

    U(x)      =  G rho / 2 * sum_e  r_e . E_e . r_e  L_e  -  G rho / 2 * sum_f  r_f . F_f . r_f  w_f,
    grad U(x) = -G rho     * sum_e  E_e . r_e  L_e      +  G rho     * sum_f  F_f . r_f  w_f,
    lap U(x)  = -G rho     * sum_f  w_f,

* ``F_f = n_f n_f^T`` with ``n_f`` the face's outward unit normal; ``r_f`` runs from ``x`` to any
  point of the face;
* ``E_e = n_A n_e^A^T + n_B n_e^B^T`` for the edge shared by faces ``A`` and ``B``, with
  ``n_e^A`` the unit normal of the edge in the plane of ``A``, pointing out of ``A``
  (``(p_j - p_i) x n_A / |p_j - p_i|`` for the edge ``i -> j`` of ``A``); ``r_e`` runs from ``x``
  to any point of the edge;
* ``L_e = ln((a + b + e) / (a + b - e))``, with ``a, b`` the distances from ``x`` to the edge's
  ends and ``e`` its length;
* ``w_f`` is the solid angle of face ``f`` seen from ``x``, signed (Van Oosterom and Strackee
  1983): ``w_f = 2 atan2(r_i . (r_j x r_k), |r_i||r_j||r_k| + |r_i| r_j.r_k + |r_j| r_k.r_i +
  |r_k| r_i.r_j)`` with ``r_i`` from ``x`` to the face's vertices; ``sum_f w_f`` is ``4 pi``
  inside the body and 0 outside (Gauss's law: ``lap U = -4 pi G rho`` inside, 0 outside).

``U`` is positive (``GM / |x|`` far away) and the acceleration is ``grad U``, as in
:mod:`satellite.gravity.spherical`. The field is exact everywhere, inside the body too; it is continuous,
its gradient jumps across the surface.

Cost: one point needs every face and edge; :class:`PolyhedronField.evaluate` works on chunks of
points, with the sums expanded in the field point (products with point-independent terms, so
most of the work is matrix products). The terms are large and cancel far from the body (about
``(|x| / size)^2``): at 100 body sizes the result keeps about 12 digits.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from numpy.typing import ArrayLike, NDArray

from satellite.errors import GravityModelError
from satellite.shape.mesh import TriangleMesh

__all__ = ["PolyhedronField", "PolyhedronValues", "exact_parallel"]


class PolyhedronValues:
    """The field at ``N`` points.

    Attributes: ``potential`` (N,) [m^2/s^2], ``acceleration`` (N, 3) [m/s^2], ``solid_angle`` (N,)
    (``sum_f w_f``) and ``laplacian`` (N,) [1/s^2].
    """

    def __init__(self, potential: NDArray[np.float64], acceleration: NDArray[np.float64],
                 solid_angle: NDArray[np.float64], g_rho: float) -> None:
        self.potential = potential
        self.acceleration = acceleration
        self.solid_angle = solid_angle
        self.laplacian = -g_rho * solid_angle


class PolyhedronField:
    """Gravity of a constant-density closed triangle mesh, exactly (see the module docstring).

    Args:
        vertices: Vertices [m] in the field's frame, shape (V, 3).
        faces: Outward triangles, shape (F, 3); every edge shared by exactly two faces.
        gm: ``G M`` [m^3/s^2] of the body (the density follows from the mesh's volume).

    Attributes:
        g_rho: ``G rho`` [1/s^2].
        volume_m3: Volume of the mesh [m^3].

    Raises:
        GravityModelError: Not a closed, consistently oriented mesh, or a bad ``gm``.

    """

    def __init__(self, vertices: ArrayLike, faces: ArrayLike, gm: float) -> None:
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.intp)
        if not (np.isfinite(gm) and gm > 0):
            raise GravityModelError(f"gm must be a positive number of m^3/s^2, got {gm}")
        mesh = TriangleMesh.from_arrays(v, f)  # checks closed and oriented
        self.vertices, self.faces = v, f
        self.volume_m3 = float(mesh.volume)
        if self.volume_m3 <= 0:
            raise GravityModelError(f"mesh volume must be positive (outward faces), got {self.volume_m3}")
        self.gm = float(gm)
        self.g_rho = self.gm / self.volume_m3
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        n = np.cross(b - a, c - a)
        self.normals = n / np.linalg.norm(n, axis=1)[:, None]
        # directed edges i -> j of every face; each undirected edge appears once each way
        i = f.reshape(-1)
        j = np.roll(f, -1, axis=1).reshape(-1)
        face_of = np.repeat(np.arange(len(f)), 3)
        d = v[j] - v[i]
        en = np.cross(d, self.normals[face_of])
        en /= np.linalg.norm(en, axis=1)[:, None]
        key = np.minimum(i, j) * len(v) + np.maximum(i, j)
        order = np.argsort(key, kind="stable")
        first, second = order[0::2], order[1::2]
        if len(order) % 2 or not np.array_equal(key[first], key[second]):
            raise GravityModelError("every edge must be shared by exactly two faces")
        na, nb = self.normals[face_of[first]], self.normals[face_of[second]]
        self.edge_dyads = na[:, :, None] * en[first][:, None, :] + nb[:, :, None] * en[second][:, None, :]
        self.edge_ends = np.stack([i[first], j[first]], axis=1)
        self.edge_lengths = np.linalg.norm(d[first], axis=1)
        # the sums expand in x (r = p - x) into products with point-independent terms:
        # r_i.(r_j x r_k) = p_i.(p_j x p_k) - x.(p_i x p_j + p_j x p_k + p_k x p_i),
        # r_j.r_k = p_j.p_k - x.(p_j + p_k) + |x|^2, n.r = n.p_i - n.x,
        # r.E r = p.E p - x.(E + E^T) p + x.E x, E r = E p - E x.
        self._triple = np.einsum("fi,fi->f", a, np.cross(b, c))
        self._cross_sum = np.cross(a, b) + np.cross(b, c) + np.cross(c, a)
        self._dots = np.stack([np.einsum("fi,fi->f", b, c), np.einsum("fi,fi->f", c, a),
                               np.einsum("fi,fi->f", a, b)])
        self._sums = np.stack([b + c, c + a, a + b])
        self._n_dot_p = np.einsum("fi,fi->f", self.normals, a)
        pe = v[self.edge_ends[:, 0]]
        ep = np.einsum("eij,ej->ei", self.edge_dyads, pe)
        self._e_flat = self.edge_dyads.reshape(-1, 9)
        self._ep = ep
        self._pep = np.einsum("ei,ei->e", pe, ep)
        self._sym_p = ep + np.einsum("eji,ej->ei", self.edge_dyads, pe)

    @classmethod
    def from_mesh(cls, mesh: TriangleMesh, gm: float, origin: ArrayLike | None = None) -> PolyhedronField:
        """The field of ``mesh`` about ``origin`` (default its centre of mass, the gravity model's origin)."""
        o = mesh.centre_of_mass if origin is None else np.asarray(origin, dtype=np.float64)
        return cls(mesh.vertices - o, mesh.faces, gm)

    def evaluate(self, points: ArrayLike, chunk: int = 64) -> PolyhedronValues:
        """Potential, acceleration, solid-angle sum and Laplacian at points [m], shape (N, 3)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = len(p)
        pot, acc, omega = np.empty(n), np.empty((n, 3)), np.empty(n)
        f, nf = self.faces, self.normals
        e0, e1 = self.edge_ends[:, 0], self.edge_ends[:, 1]
        for s in range(0, n, chunk):
            x = p[s: s + chunk]
            x2 = np.einsum("ki,ki->k", x, x)[:, None]
            rn = np.sqrt(np.maximum(np.einsum("vi,vi->v", self.vertices, self.vertices)[None, :]
                                    - 2.0 * x @ self.vertices.T + x2, 0.0))  # (k, V) |p - x|
            li, lj, lk = rn[:, f[:, 0]], rn[:, f[:, 1]], rn[:, f[:, 2]]
            num = self._triple[None, :] - x @ self._cross_sum.T
            djk = self._dots[0][None, :] - x @ self._sums[0].T + x2
            dki = self._dots[1][None, :] - x @ self._sums[1].T + x2
            dij = self._dots[2][None, :] - x @ self._sums[2].T + x2
            w = 2.0 * np.arctan2(num, li * lj * lk + li * djk + lj * dki + lk * dij)  # (k, F)
            nr = self._n_dot_p[None, :] - x @ nf.T  # n_f . r_f
            a_face = (nr * w) @ nf
            u_face = np.einsum("kf,kf->k", nr * nr, w)
            a_len, b_len = rn[:, e0], rn[:, e1]
            le = np.log((a_len + b_len + self.edge_lengths) / (a_len + b_len - self.edge_lengths))
            lE = (le @ self._e_flat).reshape(-1, 3, 3)  # sum_e L_e E_e, per point
            a_edge = le @ self._ep - np.einsum("kij,kj->ki", lE, x)
            u_edge = le @ self._pep - np.einsum("ki,ki->k", x, le @ self._sym_p) + np.einsum("ki,kij,kj->k", x, lE, x)
            pot[s: s + chunk] = 0.5 * self.g_rho * (u_edge - u_face)
            acc[s: s + chunk] = self.g_rho * (a_face - a_edge)
            omega[s: s + chunk] = w.sum(axis=1)
        return PolyhedronValues(pot, acc, omega, self.g_rho)

    def acceleration(self, points: ArrayLike) -> NDArray[np.float64]:
        """Acceleration ``grad U`` [m/s^2] at points [m], shape (N, 3) -> (N, 3)."""
        return self.evaluate(points).acceleration



class FacePatch:
    """The part of a polyhedron's field due to some of its faces (exact; cheap for a few faces).

    The acceleration splits face by face (each edge term of :class:`PolyhedronField` into the
    parts of its two faces): ``a(x) = sum_f a_f(x)`` with
    ``a_f = G rho n_f [ (n_f . r_f) w_f - sum_(e in f) (n_e^f . r_e) L_e ]``, i.e. ``-G rho n_f``
    times the integral of ``1 / |y - x|`` over the face (``n_e^f`` the edge's outward normal in
    the face's plane, ``r_e`` from ``x`` to the edge's first vertex). The faces of any partition
    of the mesh sum to the whole field; each part alone is continuous, and smooth away from its
    own faces.

    Args:
        triangles: The faces' vertices [m], shape (F, 3, 3), counter-clockwise seen from outside.
        g_rho: ``G rho`` [1/s^2] of the whole body.

    """

    def __init__(self, triangles: ArrayLike, g_rho: float) -> None:
        t = np.asarray(triangles, dtype=np.float64)
        if t.ndim != 3 or t.shape[1:] != (3, 3) or not np.isfinite(t).all():
            raise GravityModelError(f"triangles must be finite, shape (F, 3, 3), got {t.shape}")
        self.triangles, self.g_rho = t, float(g_rho)
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        self.normals = n / np.linalg.norm(n, axis=1)[:, None]
        d = np.roll(t, -1, axis=1) - t  # edge e runs from vertex e to vertex e + 1
        self._len = np.linalg.norm(d, axis=2)
        en = np.cross(d, self.normals[:, None, :])
        self._en = en / np.linalg.norm(en, axis=2)[:, :, None]
        self._point: tuple[NDArray[np.float64], ...] | None = None

    def _point_terms(self) -> tuple[NDArray[np.float64], ...]:
        """Point-independent terms of :meth:`point_acceleration` (the sums expanded in ``x``)."""
        if self._point is None:
            t = self.triangles
            verts, idx = np.unique(t.reshape(-1, 3), axis=0, return_inverse=True)
            p0, p1, p2 = t[:, 0], t[:, 1], t[:, 2]
            self._point = (
                verts, np.einsum("vi,vi->v", verts, verts), idx.reshape(-1, 3),
                np.einsum("fi,fi->f", p0, np.cross(p1, p2)), np.cross(p0, p1) + np.cross(p1, p2) + np.cross(p2, p0),
                np.stack([np.einsum("fi,fi->f", p1, p2), np.einsum("fi,fi->f", p2, p0),
                          np.einsum("fi,fi->f", p0, p1)]),
                np.concatenate([p1 + p2, p2 + p0, p0 + p1]),
                np.einsum("fi,fi->f", self.normals, p0),
                np.einsum("fei,fei->fe", self._en, t), self._en.reshape(-1, 3),
            )
        return self._point

    def point_acceleration(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Acceleration [m/s^2] of these faces at one point ``x`` [m] (the fast path for one point at a time)."""
        verts, v2, idx, triple, cross_sum, dots, sums, n_p, en_p, en = self._point_terms()
        x2 = float(x @ x)
        rn = np.sqrt(np.maximum(v2 - 2.0 * (verts @ x) + x2, 0.0))[idx]  # (F, 3) |p - x| at the corners
        f = len(idx)
        sx = (sums @ x).reshape(3, f)
        l0, l1, l2 = rn[:, 0], rn[:, 1], rn[:, 2]
        den = l0 * l1 * l2 + l0 * (dots[0] - sx[0] + x2) + l1 * (dots[1] - sx[1] + x2) + l2 * (dots[2] - sx[2] + x2)
        w = 2.0 * np.arctan2(triple - cross_sum @ x, den)
        ab = rn + rn[:, [1, 2, 0]]
        le = np.log((ab + self._len) / (ab - self._len))
        s = (n_p - self.normals @ x) * w - np.einsum("fe,fe->f", en_p - (en @ x).reshape(f, 3), le)
        return self.g_rho * (s @ self.normals)  # type: ignore[no-any-return]

    @classmethod
    def from_field(cls, field: PolyhedronField, mask: ArrayLike) -> FacePatch:
        """The faces of ``field`` selected by ``mask`` (shape (F,) of bool)."""
        m = np.asarray(mask, dtype=bool)
        if m.shape != (len(field.faces),):
            raise GravityModelError(f"face mask must have shape ({len(field.faces)},), got {m.shape}")
        return cls(field.vertices[field.faces[m]], field.g_rho)

    def acceleration(self, points: ArrayLike, chunk: int = 128) -> NDArray[np.float64]:
        """Acceleration [m/s^2] of these faces at points [m], shape (N, 3) -> (N, 3) (chunks of points)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.empty_like(p)
        t, nf = self.triangles, self.normals
        for s in range(0, len(p), chunk):
            x = p[s: s + chunk]
            r = t[None] - x[:, None, None, :]  # (k, F, 3, 3)
            rn = np.sqrt(np.einsum("kfvi,kfvi->kfv", r, r))
            r0, r1, r2 = r[:, :, 0], r[:, :, 1], r[:, :, 2]
            l0, l1, l2 = rn[..., 0], rn[..., 1], rn[..., 2]
            num = np.einsum("kfi,kfi->kf", r0, np.cross(r1, r2))
            den = (l0 * l1 * l2 + l0 * np.einsum("kfi,kfi->kf", r1, r2) + l1 * np.einsum("kfi,kfi->kf", r2, r0)
                   + l2 * np.einsum("kfi,kfi->kf", r0, r1))
            w = 2.0 * np.arctan2(num, den)
            ab = rn + np.roll(rn, -1, axis=2)
            le = np.log((ab + self._len) / (ab - self._len))
            terms = np.einsum("fi,kfi->kf", nf, r0) * w - np.einsum("fei,kfei,kfe->kf", self._en, r, le)
            out[s: s + chunk] = self.g_rho * (terms @ nf)
        return out


_WORKER: PolyhedronField | None = None


def _init(field: PolyhedronField) -> None:
    global _WORKER
    _WORKER = field


def _chunk(points: NDArray[np.float64]) -> NDArray[np.float64]:
    assert _WORKER is not None
    return _WORKER.acceleration(points)


def exact_parallel(field: PolyhedronField, points: NDArray[np.float64], workers: int = 1,
                   progress: Callable[[int, int], None] | None = None) -> NDArray[np.float64]:
    """The exact field at points (N, 3) [m], in chunks of 512 over ``workers`` processes (Ctrl-C stops them)."""
    chunks = [points[s: s + 512] for s in range(0, len(points), 512)]
    out: list[NDArray[np.float64]] = []
    done = 0
    if workers <= 1 or len(chunks) <= 1:
        for c in chunks:
            out.append(field.acceleration(c))
            done += len(c)
            if progress:
                progress(done, len(points))
    else:
        with ProcessPoolExecutor(workers, initializer=_init, initargs=(field,)) as pool:
            try:
                for c, a in zip(chunks, pool.map(_chunk, chunks)):
                    out.append(a)
                    done += len(c)
                    if progress:
                        progress(done, len(points))
            except BaseException:
                pool.shutdown(wait=False, cancel_futures=True)
                raise
    return np.concatenate(out) if out else np.empty((0, 3))
