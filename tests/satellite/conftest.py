"""Synthetic closed meshes and independent oracles for the satellite tests.

The tests run in pytest's importlib mode, so they cannot import this module: the helpers are
handed out by the ``helpers`` fixture, and the raw Itokawa shape file by ``itokawa_obj`` (which
skips the test when ``../shared/data/itokawa/itokawa_low.obj`` is absent: only the test that checks
the shipped mesh against the raw file needs it; the others use the shipped mesh).
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from satellite.shape.mesh import TriangleMesh


def box_mesh(a: float = 1.0, b: float = 1.0, c: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Box of sides a, b, c centred at the origin; 12 outward triangles."""
    v = np.array(
        [[x, y, z] for x in (-a / 2, a / 2) for y in (-b / 2, b / 2) for z in (-c / 2, c / 2)]
    )
    # vertex index = 4*ix + 2*iy + iz
    quads = [
        (0, 1, 3, 2),  # x = -a/2, normal -x
        (4, 6, 7, 5),  # x = +a/2
        (0, 4, 5, 1),  # y = -b/2
        (2, 3, 7, 6),  # y = +b/2
        (0, 2, 6, 4),  # z = -c/2
        (1, 5, 7, 3),  # z = +c/2
    ]
    f = []
    for q in quads:
        f += [(q[0], q[1], q[2]), (q[0], q[2], q[3])]
    return v, np.array(f)


def icosphere(subdivisions: int = 2, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Subdivided icosahedron projected on a sphere (keeps the icosahedral symmetry)."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [
        (-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0),
        (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
        (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1),
    ]  # fmt: skip
    verts = [np.array(p, dtype=float) / np.linalg.norm(p) for p in v]
    faces = [
        (0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
        (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
        (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
        (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1),
    ]  # fmt: skip
    for _ in range(subdivisions):
        cache: dict[tuple[int, int], int] = {}

        def mid(i: int, j: int, cache: dict[tuple[int, int], int] = cache) -> int:
            key = (min(i, j), max(i, j))
            if key not in cache:
                p = verts[i] + verts[j]
                verts.append(p / np.linalg.norm(p))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.array(verts) * radius, np.array(faces)


def rotation(ax: float, ay: float, az: float) -> np.ndarray:
    """Rotation matrix Rz(az) Ry(ay) Rx(ax)."""
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """Write a plain OBJ (1-based faces)."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(vertices, dtype=float).tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def simplex_quadrature(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (barycentric u, shape (P, 3)) and weights on the unit simplex, exact to `order`.

    Collapsed (Duffy) coordinates with Gauss-Legendre in each direction: the Jacobian
    (1-s)^2 (1-t) is polynomial, so the rule is exact for polynomials of degree <= order.
    """
    p = (order + 3) // 2 + 1
    x, w = np.polynomial.legendre.leggauss(p)
    x, w = (x + 1) / 2, w / 2
    s, t, u = np.meshgrid(x, x, x, indexing="ij")
    ws, wt, wu = np.meshgrid(w, w, w, indexing="ij")
    u1 = s
    u2 = (1 - s) * t
    u3 = (1 - s) * (1 - t) * u
    jac = (1 - s) ** 2 * (1 - t)
    pts = np.stack([u1.ravel(), u2.ravel(), u3.ravel()], axis=1)
    return pts, (ws * wt * wu * jac).ravel()


def pbar_table(nmax: int, t: np.ndarray) -> np.ndarray:
    """Fully normalised associated Legendre functions (no Condon-Shortley phase).

    Standard column recursion, independent of the library's Cartesian recursion.
    Returns shape (nmax+1, nmax+1, *t.shape).
    """
    t = np.asarray(t, dtype=float)
    u = np.sqrt(np.clip(1 - t * t, 0.0, None))
    p = np.zeros((nmax + 1, nmax + 1) + t.shape)
    p[0, 0] = 1.0
    for m in range(1, nmax + 1):
        fac = math.sqrt(3.0) if m == 1 else math.sqrt((2 * m + 1) / (2 * m))
        p[m, m] = fac * u * p[m - 1, m - 1]
    for m in range(nmax + 1):
        for n in range(m + 1, nmax + 1):
            a = math.sqrt((2 * n - 1) * (2 * n + 1) / ((n - m) * (n + m)))
            p[n, m] = a * t * p[n - 1, m]
            if n - 2 >= m:
                b = math.sqrt(
                    (2 * n + 1) * (n + m - 1) * (n - m - 1) / ((n - m) * (n + m) * (2 * n - 3))
                )
                p[n, m] -= b * p[n - 2, m]
    return p


def potential_reference(
    c: np.ndarray, s: np.ndarray, r_ref: float, gm: float, pts: np.ndarray
) -> np.ndarray:
    """Textbook spherical-harmonic sum of the potential at points (k, 3)."""
    pts = np.atleast_2d(pts)
    r = np.linalg.norm(pts, axis=1)
    lat_sin = pts[:, 2] / r
    lon = np.arctan2(pts[:, 1], pts[:, 0])
    nmax = c.shape[0] - 1
    p = pbar_table(nmax, lat_sin)
    total = np.zeros(len(r))
    for n in range(nmax + 1):
        for m in range(n + 1):
            total += (
                (r_ref / r) ** n * p[n, m] * (c[n, m] * np.cos(m * lon) + s[n, m] * np.sin(m * lon))
            )
    return gm / r * total


def coefficients_by_quadrature(vertices: np.ndarray, faces: np.ndarray, nmax: int) -> tuple:
    """C, S, r_ref by numerical quadrature of Pbar_nm over the tetrahedra (origin = centroid)."""
    pts_u, w = simplex_quadrature(nmax)
    a, b, cc = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    det = np.einsum("fi,fi->f", a, np.cross(b, cc))
    vol = det.sum() / 6
    com = ((det / 6)[:, None] * (a + b + cc) / 4).sum(axis=0) / vol
    a, b, cc = a - com, b - com, cc - com
    det = np.einsum("fi,fi->f", a, np.cross(b, cc))
    r_ref = (3 * vol / (4 * math.pi)) ** (1 / 3)
    x = (
        pts_u[None, :, 0:1] * a[:, None, :]
        + pts_u[None, :, 1:2] * b[:, None, :]
        + pts_u[None, :, 2:3] * cc[:, None, :]
    )
    wt = (det[:, None] * w[None, :]).ravel()
    x = x.reshape(-1, 3)
    r = np.linalg.norm(x, axis=1)
    r = np.where(r == 0, 1e-300, r)
    p = pbar_table(nmax, x[:, 2] / r)
    lon = np.arctan2(x[:, 1], x[:, 0])
    c = np.zeros((nmax + 1, nmax + 1))
    s = np.zeros((nmax + 1, nmax + 1))
    for n in range(nmax + 1):
        for m in range(n + 1):
            base = wt * (r / r_ref) ** n * p[n, m]
            c[n, m] = (base * np.cos(m * lon)).sum() / ((2 * n + 1) * vol)
            s[n, m] = (base * np.sin(m * lon)).sum() / ((2 * n + 1) * vol)
    return c, s, r_ref, vol


def lumpy_body() -> TriangleMesh:
    """An asymmetric closed body: a stretched, rotated, shifted icosphere with a bump."""
    v, f = icosphere(2)
    v = v * np.array([1.3, 0.8, 0.6])
    v[0] *= 1.25
    v[17] *= 0.9
    v = v @ rotation(0.3, 0.5, 0.7).T + np.array([0.2, -0.1, 0.05])
    return TriangleMesh.from_arrays(v * 100.0, f)


@pytest.fixture(scope="session")
def helpers() -> SimpleNamespace:
    """The mesh builders and oracles of this module."""
    return SimpleNamespace(
        box_mesh=box_mesh,
        icosphere=icosphere,
        rotation=rotation,
        write_obj=write_obj,
        simplex_quadrature=simplex_quadrature,
        pbar_table=pbar_table,
        potential_reference=potential_reference,
        coefficients_by_quadrature=coefficients_by_quadrature,
        lumpy_body=lumpy_body,
    )


@pytest.fixture(scope="session")
def itokawa_obj() -> Path:
    """Path of the raw Itokawa shape file; skips the test when it is absent (the shipped mesh needs no file)."""
    from satellite.shape.mesh_surface import default_shape_path

    path = default_shape_path()
    if not path.is_file():
        pytest.skip(f"raw shape file absent: {path} (only regenerating and checking the shipped files need it)")
    return path


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark the tests that read the raw shape file ``shape_file`` (``.ci/run`` runs them beside ../shared)."""
    for item in items:
        if "itokawa_obj" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.shape_file)
