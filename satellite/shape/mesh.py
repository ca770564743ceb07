"""Closed triangle meshes of constant-density bodies: OBJ reading, checks and exact moments.

Every volume integral here is exact (up to floating-point rounding): the body is split into
the tetrahedra ``(origin, a, b, c)`` spanned by the origin and each outward-oriented face
``(a, b, c)``; their signed volumes add up to the body's, whatever the body's shape, as long
as the mesh is closed and consistently oriented (which :class:`TriangleMesh` enforces).

Monomial moments of a tetrahedron with a vertex at the origin use the closed form

    integral over T of exp(t . x) dx = 6 vol(T) * sum_n h_n(t.a, t.b, t.c) / (n + 3)!,

where ``h_n`` is the complete homogeneous symmetric polynomial of degree ``n``. Comparing
the coefficients of ``t_x^i t_y^j t_z^k`` (with ``n = i + j + k``) on both sides gives

    integral over T of x^i y^j z^k dx = det[a b c] * i! j! k! / (n + 3)!
                                        * [t^(i,j,k)] h_n(t.a, t.b, t.c),

and ``h_n(A, B, C)`` follows from ``h_n(C) = C h_{n-1}(C)``,
``h_n(B, C) = h_n(C) + B h_{n-1}(B, C)`` and ``h_n(A, B, C) = h_n(B, C) + A h_{n-1}(A, B, C)``,
each a product of a homogeneous polynomial in ``t`` by a linear form, vectorised over faces.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import factorial
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from satellite.errors import MeshError

__all__ = [
    "UNIT_SCALES",
    "TriangleMesh",
    "check_closed_oriented",
    "monomials",
]

UNIT_SCALES: dict[str, float] = {"km": 1000.0, "m": 1.0}
"""Length of one file unit in metres, by unit name accepted by :func:`parse_obj`."""


def monomials(degree: int) -> list[tuple[int, int, int]]:
    """Return the exponents ``(i, j, k)`` of the monomials ``x^i y^j z^k`` of a given degree.

    Args:
        degree: Total degree ``n = i + j + k >= 0``.

    Returns:
        The ``(n + 1)(n + 2) / 2`` exponent triples, ``i`` descending, then ``j`` descending.

    """
    return [
        (i, j, degree - i - j) for i in range(degree, -1, -1) for j in range(degree - i, -1, -1)
    ]


def _shift_maps(max_degree: int) -> list[NDArray[np.intp]]:
    """Index maps multiplying a degree-(n-1) homogeneous polynomial by x, y or z.

    Returns:
        For each ``n`` in ``1..max_degree``, an int array of shape (3, D_{n-1}) whose row ``d``
        gives, for each monomial of degree ``n - 1``, the position of that monomial times the
        ``d``-th coordinate in the degree-``n`` list of :func:`monomials`.

    """
    maps: list[NDArray[np.intp]] = [np.zeros((3, 0), dtype=np.intp)]
    for n in range(1, max_degree + 1):
        index = {e: p for p, e in enumerate(monomials(n))}
        rows = np.empty((3, len(monomials(n - 1))), dtype=np.intp)
        for p, (i, j, k) in enumerate(monomials(n - 1)):
            rows[0, p] = index[(i + 1, j, k)]
            rows[1, p] = index[(i, j + 1, k)]
            rows[2, p] = index[(i, j, k + 1)]
        maps.append(rows)
    return maps


def _times_linear(
    poly: NDArray[np.float64], vec: NDArray[np.float64], shift: NDArray[np.intp], size: int
) -> NDArray[np.float64]:
    """Multiply homogeneous polynomials by linear forms, one per face.

    Args:
        poly: Coefficients, shape (F, D_{n-1}).
        vec: Linear forms ``v . t``, shape (F, 3).
        shift: Index map from :func:`_shift_maps` for degree ``n``, shape (3, D_{n-1}).
        size: ``D_n``, the number of monomials of degree ``n``.

    Returns:
        Coefficients of ``(v . t) * poly``, shape (F, D_n).

    """
    out = np.zeros((poly.shape[0], size))
    for d in range(3):
        out[:, shift[d]] += poly * vec[:, d : d + 1]
    return out


def check_closed_oriented(faces: NDArray[np.intp], n_vertices: int) -> None:
    """Check that triangles form a closed, edge-manifold, consistently oriented surface.

    The test is edge pairing: every directed edge ``(i, j)`` of a face must appear exactly once,
    and its reverse ``(j, i)`` exactly once (in the neighbouring face).

    Args:
        faces: Vertex indices of the triangles, shape (F, 3), 0-based.
        n_vertices: Number of vertices, V.

    Raises:
        MeshError: With the first offending edge, if a face index is out of range, a face is
            degenerate (repeated vertex), an edge belongs to a single face (open mesh), to more
            than two faces (non-manifold), or two faces run along a shared edge in the same
            direction (inconsistent orientation).

    """
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.shape[0] < 4:
        raise MeshError(
            f"a closed triangle mesh needs at least 4 faces of shape (F, 3), got {faces.shape}"
        )
    if faces.min() < 0 or faces.max() >= n_vertices:
        raise MeshError(f"face vertex index out of range [0, {n_vertices - 1}]")
    bad = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    if bad.any():
        f = int(np.flatnonzero(bad)[0])
        raise MeshError(
            f"{int(bad.sum())} degenerate face(s) with a repeated vertex, "
            f"e.g. face {f}: {faces[f].tolist()}"
        )
    tail = faces.reshape(-1)
    head = faces[:, [1, 2, 0]].reshape(-1)
    nv = np.int64(n_vertices)
    lo = np.minimum(tail, head).astype(np.int64)
    hi = np.maximum(tail, head).astype(np.int64)
    undirected, counts = np.unique(lo * nv + hi, return_counts=True)
    if (counts == 1).any():
        key = int(undirected[counts == 1][0])
        raise MeshError(
            f"mesh is not closed: {int((counts == 1).sum())} boundary edge(s) belong to a single "
            f"face, e.g. edge ({key // n_vertices}, {key % n_vertices}); "
            "a closed surface is required"
        )
    if (counts > 2).any():
        key = int(undirected[counts > 2][0])
        raise MeshError(
            f"mesh is not 2-manifold: {int((counts > 2).sum())} edge(s) shared by more than two "
            f"faces, e.g. edge ({key // n_vertices}, {key % n_vertices})"
        )
    directed, dcounts = np.unique(tail.astype(np.int64) * nv + head, return_counts=True)
    if (dcounts > 1).any():
        key = int(directed[dcounts > 1][0])
        i, j = key // n_vertices, key % n_vertices
        owners = np.flatnonzero(((tail == i) & (head == j)).reshape(-1, 3).any(axis=1)).tolist()
        raise MeshError(
            f"mesh is inconsistently oriented: {int((dcounts > 1).sum())} edge(s) run the same "
            f"direction in both of their faces, e.g. edge ({i}, {j}) in faces {owners}; "
            "flip the offending faces so that all normals point outward"
        )


@dataclass(frozen=True)
class TriangleMesh:
    """A closed, consistently oriented triangle mesh of a constant-density body.

    Construct with :meth:`from_arrays` or :func:`parse_obj`, which check the mesh, drop
    unreferenced vertices and orient the faces outward (positive volume). Vertex coordinates
    are in metres, in the mesh's own frame.

    Attributes:
        vertices: Vertex positions [m], shape (V, 3), all referenced by a face.
        faces: Triangles as 0-based vertex indices, shape (F, 3), counter-clockwise seen from
            outside (outward normals).

    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.intp]
    _cache: dict[str, object] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_arrays(cls, vertices: ArrayLike, faces: ArrayLike) -> TriangleMesh:
        """Build a checked mesh from vertex and face arrays.

        Unreferenced vertices are dropped (and the faces renumbered). A mesh that is closed and
        consistently oriented with inward normals (negative volume) is flipped to outward.

        Args:
            vertices: Vertex positions [m], shape (V, 3).
            faces: Triangles as 0-based vertex indices, shape (F, 3).

        Returns:
            The checked mesh.

        Raises:
            MeshError: If the arrays have the wrong shapes, hold non-finite values, or the
                surface is open, non-manifold, inconsistently oriented or of zero volume.

        """
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces)
        if v.ndim != 2 or v.shape[1] != 3:
            raise MeshError(f"vertices must have shape (V, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3:
            raise MeshError(f"faces must have shape (F, 3) (triangles), got {f.shape}")
        if not np.issubdtype(f.dtype, np.integer):
            raise MeshError(f"faces must hold integer vertex indices, got dtype {f.dtype}")
        if not np.isfinite(v).all():
            raise MeshError("vertices hold NaN or infinite coordinates")
        f = f.astype(np.intp)
        check_closed_oriented(f, v.shape[0])
        used = np.unique(f)
        renumber = np.full(v.shape[0], -1, dtype=np.intp)
        renumber[used] = np.arange(used.size)
        v = v[used].copy()
        f = renumber[f]
        mesh = cls(v, f)
        vol = mesh.volume
        scale = float(np.ptp(v, axis=0).max())
        if not abs(vol) > 1e-12 * scale**3:
            raise MeshError(f"mesh encloses no volume (signed volume {vol:.3e} m^3)")
        if vol < 0.0:
            mesh = cls(v, f[:, ::-1].copy())
        mesh.vertices.setflags(write=False)
        mesh.faces.setflags(write=False)
        return mesh

    def monomial_moments(
        self, max_degree: int, origin: ArrayLike | None = None, scale: float = 1.0
    ) -> NDArray[np.float64]:
        """Exact volume integrals of all monomials up to a given degree.

        Args:
            max_degree: Highest total degree ``n = i + j + k``, >= 0.
            origin: Point ``o`` [m] the coordinates are taken from, shape (3,); default the
                mesh origin.
            scale: Length ``L`` [m] the coordinates are divided by (for conditioning).

        Returns:
            ``M[i, j, k] = integral over the body of u^i v^j w^k dV`` with
            ``(u, v, w) = (x - o) / L`` dimensionless and ``dV`` in [m^3]; shape
            (max_degree + 1,) * 3, zero where ``i + j + k > max_degree``.

        """
        if max_degree < 0:
            raise MeshError(f"max_degree must be >= 0, got {max_degree}")
        o = np.zeros(3) if origin is None else np.asarray(origin, dtype=np.float64).reshape(3)
        p = (self.vertices - o) / float(scale)
        a, b, c = p[self.faces[:, 0]], p[self.faces[:, 1]], p[self.faces[:, 2]]
        det = np.einsum("fi,fi->f", a, np.cross(b, c))
        shifts = _shift_maps(max_degree)
        ones = np.ones((det.size, 1))
        h_c, h_bc, h_abc = ones, ones, ones
        out = np.zeros((max_degree + 1,) * 3)
        out[0, 0, 0] = det.sum() / 6.0 * scale**3
        for n in range(1, max_degree + 1):
            size = (n + 1) * (n + 2) // 2
            h_c = _times_linear(h_c, c, shifts[n], size)
            h_bc = h_c + _times_linear(h_bc, b, shifts[n], size)
            h_abc = h_bc + _times_linear(h_abc, a, shifts[n], size)
            sums = det @ h_abc
            for p_idx, (i, j, k) in enumerate(monomials(n)):
                weight = factorial(i) * factorial(j) * factorial(k) / factorial(n + 3)
                out[i, j, k] = weight * sums[p_idx] * scale**3
        return out

    @property
    def volume(self) -> float:
        """Enclosed volume [m^3] (positive for outward faces)."""
        if "volume" not in self._cache:
            p = self.vertices
            a, b, c = p[self.faces[:, 0]], p[self.faces[:, 1]], p[self.faces[:, 2]]
            self._cache["volume"] = float(np.einsum("fi,fi->", a, np.cross(b, c)) / 6.0)
        return float(self._cache["volume"])  # type: ignore[arg-type]

    @property
    def volume_equivalent_radius(self) -> float:
        """Radius [m] of the sphere of the same volume, ``(3 V / (4 pi))^(1/3)``."""
        return float((3.0 * self.volume / (4.0 * np.pi)) ** (1.0 / 3.0))

    @property
    def centre_of_mass(self) -> NDArray[np.float64]:
        """Centroid of the volume [m], shape (3,): the centre of mass at constant density."""
        m = self.monomial_moments(1)
        return np.array([m[1, 0, 0], m[0, 1, 0], m[0, 0, 1]]) / m[0, 0, 0]

    def second_moments(self, origin: ArrayLike | None = None) -> NDArray[np.float64]:
        """Second volume moments ``S = integral of (x - o)(x - o)^T dV`` [m^5], shape (3, 3).

        Args:
            origin: Reference point [m], shape (3,); default the centre of mass.

        """
        o = self.centre_of_mass if origin is None else np.asarray(origin, dtype=np.float64)
        m = self.monomial_moments(2, origin=o)
        return np.array(
            [
                [m[2, 0, 0], m[1, 1, 0], m[1, 0, 1]],
                [m[1, 1, 0], m[0, 2, 0], m[0, 1, 1]],
                [m[1, 0, 1], m[0, 1, 1], m[0, 0, 2]],
            ]
        )

    def inertia_tensor(
        self, mass_kg: float, origin: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Inertia tensor [kg m^2] of the body at constant density, shape (3, 3).

        ``I = rho (tr(S) 1 - S)`` with ``S`` from :meth:`second_moments` and ``rho = m / V``;
        the diagonal holds ``Ixx = integral of (y^2 + z^2) dm`` etc., and the off-diagonal the
        products of inertia with the minus sign, ``I[0, 1] = -integral of x y dm``.

        Args:
            mass_kg: Body mass [kg], > 0.
            origin: Reference point [m], shape (3,); default the centre of mass.

        """
        s = self.second_moments(origin)
        rho = mass_kg / self.volume
        return rho * (np.trace(s) * np.eye(3) - s)

    def translated(self, offset: ArrayLike) -> TriangleMesh:
        """Return the mesh moved by ``offset`` [m], shape (3,)."""
        v = self.vertices + np.asarray(offset, dtype=np.float64).reshape(3)
        v.setflags(write=False)
        return TriangleMesh(v, self.faces)


def parse_obj(path: str | Path, units: str = "km") -> TriangleMesh:
    """Read a closed triangle mesh from a Wavefront OBJ file (uncached; :func:`satellite.shape.cache.read_obj` caches).

    Only ``v`` and ``f`` records are used (texture and normal indices in ``f i/j/k`` records
    are ignored; negative, relative indices are supported; polygons with more than three
    vertices are split as fans). No unit detection is attempted: the Gaskell Itokawa shape
    model is in kilometres, hence the default.

    Args:
        path: OBJ file.
        units: Length unit of the file's coordinates, ``"km"`` or ``"m"``.

    Returns:
        The checked mesh, in metres, unreferenced vertices dropped, faces outward.

    Raises:
        FileNotFoundError: If the file does not exist.
        MeshError: If the unit is unknown, a record is malformed, or the mesh is not a closed,
            consistently oriented 2-manifold surface.

    """
    if units not in UNIT_SCALES:
        raise MeshError(f"unknown length unit {units!r}; valid units: {', '.join(UNIT_SCALES)}")
    path = Path(path)
    verts: list[list[float]] = []
    faces: list[tuple[int, int, int]] = []
    with path.open("r", encoding="utf-8", errors="replace") as fh:
        for lineno, line in enumerate(fh, start=1):
            parts = line.split()
            if not parts:
                continue
            tag = parts[0]
            try:
                if tag == "v":
                    verts.append([float(parts[1]), float(parts[2]), float(parts[3])])
                elif tag == "f":
                    idx = []
                    for token in parts[1:]:
                        k = int(token.split("/", 1)[0])
                        if k == 0:
                            raise ValueError("index 0")
                        idx.append(k - 1 if k > 0 else len(verts) + k)
                    if len(idx) < 3:
                        raise ValueError("fewer than 3 vertices")
                    faces.extend((idx[0], idx[q], idx[q + 1]) for q in range(1, len(idx) - 1))
            except (ValueError, IndexError) as exc:
                raise MeshError(
                    f"{path}:{lineno}: malformed {tag!r} record ({exc}): {line.strip()[:80]}"
                ) from None
    if not faces:
        raise MeshError(f"{path}: no faces ('f' records) found")
    return TriangleMesh.from_arrays(
        np.array(verts) * UNIT_SCALES[units], np.array(faces, dtype=np.intp)
    )
