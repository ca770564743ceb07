"""Body shapes for the surface check: the model interface, the ellipsoid, winding numbers.

Shape models live in the body frame of the gravity model (origin at the centre of mass, the
mesh's axes, metres; see :mod:`satellite.gravity.spherical`):

* :class:`satellite.shape.mesh_surface.MeshSurface`: a closed triangle mesh (the Gaskell shape model),
  exact inside/outside (see that module).
* :class:`EllipsoidSurface`: a simple stand-in for the shape (runs use the shipped mesh), the triaxial
  ellipsoid of the published dimensions 535 x 294 x 209 m (Fujiwara et al. 2006), axes along body x, y, z.

Clearance is the **radial clearance**: the distance from the point to the nearest surface
crossing along the line through the centre of mass and the point, positive outside and negative
inside. For a surface that is star-shaped about the centre of mass it is ``|r| - r_s(r_hat)``,
with ``r_s`` the surface radius in that direction; it is an upper bound on the Euclidean
distance to the surface (equal to it where the surface is normal to the radius).

The check of a trajectory against a shape is :mod:`satellite.shape.surface_check`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from isf_robot.core import ConfigError

__all__ = ["ITOKAWA_DIMENSIONS_M", "SurfaceModel", "EllipsoidSurface", "winding_numbers"]

ITOKAWA_DIMENSIONS_M = (535.0, 294.0, 209.0)
"""Itokawa's overall dimensions along body x, y, z [m] (Fujiwara et al. 2006)."""


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
            name="ellipsoid 535 x 294 x 209 m (Fujiwara et al. 2006)",
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

