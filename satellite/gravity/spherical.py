"""Spherical-harmonic gravity field of a body, evaluated in the body frame.

Convention (fully normalised, 4-pi geodesy normalisation, no Condon-Shortley phase; see
:mod:`satellite.gravity.harmonics`, which also computes the coefficients of a constant-density body from
its shape): in the body frame, with ``r = |r|``, latitude ``phi`` and longitude ``lambda``,

    U(r) = GM / r * sum_{n=0}^{N} (R / r)^n sum_{m=0}^{n}
               Pbar_nm(sin phi) (Cbar_nm cos(m lambda) + Sbar_nm sin(m lambda)).

``U`` is positive (``U = GM / r`` for a point mass) and the acceleration is its gradient,
``a = grad U``. The series converges outside the body's Brillouin sphere (radius 311.7 m for
Itokawa) and is only an approximation closer in; it is not the gravity inside the body.

Conventions of :meth:`GravityField.from_mesh`: origin at the centre of mass, the mesh's own
axes, ``R`` = volume-equivalent radius, ``GM = G * mass``. Tables on disk:
:mod:`satellite.gravity.harmonics_io`.

Itokawa (Gaskell 64-level mesh ``itokawa_low.obj``, 3.51e10 kg, degree 8), as committed in
``satellite/data/itokawa_degree8.json``: volume 1.778560e7 m^3, R = 161.930 m,
GM = 2.342679 m^3/s^2, centre of mass at (0.358, 0.035, -0.107) m in the mesh frame,
Cbar20 = -0.14701, Cbar22 = +0.22134, Sbar22 = -0.02174 (unnormalised C20 = -0.32872,
C22 = 0.14287). Generating it takes about 0.7 s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from satellite.errors import GravityModelError
from satellite.gravity.harmonics import (
    G_CODATA2018,
    ITOKAWA_MASS_KG,
    check_degree,
    normalisation,
    polyhedron_harmonics,
    solid_harmonics,
)
from satellite.gravity.harmonics_io import read_default_table, read_table, table_arrays, table_dict, write_table
from satellite.shape.cache import read_obj
from satellite.shape.mesh import TriangleMesh

__all__ = ["GravityField", "load_default_field"]


class GravityField:
    """Spherical-harmonic gravity field evaluated in the body frame.

    See the module docstring for the convention. The potential and the acceleration are
    evaluated as polynomials of the Kelvin-inverted point ``q = R r / |r|^2``: with
    ``H(q) = sum_nm Nbar_nm (Cbar_nm V_nm(q) + Sbar_nm W_nm(q))`` (so that ``U = GM H(q) / r``)
    and ``K = sum_n (2n + 1) H_n`` (``H_n`` the degree-``n`` part),

        a = grad U = GM / r^2 * ((R / r) grad H(q) - (r_vec / r) K(q)).

    Degree 0 (``Cbar00 = 1``) gives exactly the Kepler acceleration ``-GM r_vec / r^3``.

    Args:
        C: ``Cbar_nm``, shape (N+1, N+1) (entries above the diagonal must be zero).
        S: ``Sbar_nm``, shape (N+1, N+1) (zero above the diagonal and in column 0).
        r_ref_m: Reference radius ``R`` [m], > 0.
        gm: Gravitational parameter ``GM`` [m^3/s^2], > 0.

    Raises:
        GravityModelError: On bad shapes, non-finite values, non-zero entries where the
            convention has none, or non-positive ``R`` or ``GM``.

    """

    def __init__(self, C: ArrayLike, S: ArrayLike, r_ref_m: float, gm: float) -> None:
        c = np.array(C, dtype=np.float64)
        s = np.array(S, dtype=np.float64)
        if c.ndim != 2 or c.shape[0] != c.shape[1] or s.shape != c.shape:
            raise GravityModelError(
                f"C and S must be square (N+1, N+1) arrays, got {c.shape} and {s.shape}"
            )
        degree = check_degree(c.shape[0] - 1)
        if not (np.isfinite(c).all() and np.isfinite(s).all()):
            raise GravityModelError("C and S must be finite")
        if np.any(np.triu(c, 1)) or np.any(np.triu(s, 1)) or np.any(s[:, 0]):
            raise GravityModelError(
                "C[n][m] and S[n][m] must be zero for m > n, and S[n][0] must be zero"
            )
        if not (math.isfinite(r_ref_m) and r_ref_m > 0.0):
            raise GravityModelError(f"r_ref_m must be a positive length in metres, got {r_ref_m}")
        if not (math.isfinite(gm) and gm > 0.0):
            raise GravityModelError(f"gm must be a positive GM in m^3/s^2, got {gm}")
        c.setflags(write=False)
        s.setflags(write=False)
        self._degree = degree
        self._c = c
        self._s = s
        self._r_ref = float(r_ref_m)
        self._gm = float(gm)
        self._build_tables()

    # ------------------------------------------------------------------ construction helpers
    def _build_tables(self) -> None:
        d = self._degree + 1
        v, w = solid_harmonics(self._degree)
        norm = np.array(
            [[normalisation(n, m) if m <= n else 0.0 for m in range(d)] for n in range(d)]
        )
        h = np.einsum("nm,nmijk->ijk", norm * self._c, v) + np.einsum(
            "nm,nmijk->ijk", norm * self._s, w
        )
        e = np.arange(d)
        total = e[:, None, None] + e[None, :, None] + e[None, None, :]
        tables = np.zeros((4, d, d, d))
        tables[0, :-1] = h[1:] * e[1:, None, None]  # dH/dx
        tables[1, :, :-1] = h[:, 1:] * e[None, 1:, None]  # dH/dy
        tables[2, :, :, :-1] = h[:, :, 1:] * e[None, None, 1:]  # dH/dz
        tables[3] = h * (2 * total + 1)  # K
        self._h_table = h
        # Single-point evaluation contracts k, then j, then i with three 2-D np.dot calls
        # (faster than batched matmul on such tiny arrays): T[row, i, j, k] -> (4 d d, d).
        self._accel_table = np.ascontiguousarray(tables.reshape(4 * d * d, d))
        self._pot_table = np.ascontiguousarray(h.reshape(d * d, d))
        self._batch_table = tables.reshape(4, -1).T.copy()  # (d^3, 4)
        self._exponents = e.astype(np.float64)
        self._d = d

    @classmethod
    def from_mesh(
        cls,
        mesh: TriangleMesh | str | Path,
        degree: int,
        mass_kg: float = ITOKAWA_MASS_KG,
        units: str = "km",
    ) -> GravityField:
        """Field of a constant-density body from its closed triangle mesh.

        Args:
            mesh: A :class:`~satellite.shape.mesh.TriangleMesh` [m], or an OBJ file path.
            degree: Highest degree and order ``N``, ``0 <= N <= MAX_DEGREE``.
            mass_kg: Body mass [kg], > 0 (default Itokawa's).
            units: Length unit of an OBJ file, ``"km"`` or ``"m"`` (ignored for a mesh object).

        Returns:
            The field about the centre of mass, in the mesh's axes, ``R`` = volume-equivalent
            radius, ``GM = G_CODATA2018 * mass_kg``.

        """
        if not (math.isfinite(mass_kg) and mass_kg > 0.0):
            raise GravityModelError(f"mass must be a positive number of kg, got {mass_kg}")
        degree = check_degree(degree)
        if not isinstance(mesh, TriangleMesh):
            mesh = read_obj(mesh, units=units)
        harm = polyhedron_harmonics(mesh, degree)
        return cls(harm.C, harm.S, harm.r_ref_m, G_CODATA2018 * mass_kg)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> GravityField:
        """Build from a table mapping (see :func:`satellite.gravity.harmonics_io.table_arrays`)."""
        return cls(*table_arrays(data))

    @classmethod
    def from_json(cls, path: str | Path) -> GravityField:
        """Read a table written by :meth:`to_json` (or the ``isf-satellite gravity`` command)."""
        return cls.from_dict(read_table(path))

    def to_dict(self, provenance: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Return the JSON-ready table (see :func:`satellite.gravity.harmonics_io.table_dict`)."""
        return table_dict(self._c, self._s, self._r_ref, self._gm, provenance)

    def to_json(self, path: str | Path, provenance: Mapping[str, Any] | None = None) -> None:
        """Write the table as JSON (see :meth:`to_dict`); floats are written round-trip exact."""
        write_table(path, self.to_dict(provenance))

    # ------------------------------------------------------------------ read-only data
    @property
    def degree(self) -> int:
        """Highest degree and order ``N``."""
        return self._degree

    @property
    def r_ref_m(self) -> float:
        """Reference radius ``R`` [m]."""
        return self._r_ref

    @property
    def gm(self) -> float:
        """Gravitational parameter ``GM`` [m^3/s^2]."""
        return self._gm

    @property
    def C(self) -> NDArray[np.float64]:  # noqa: N802
        """``Cbar_nm``, read-only, shape (N+1, N+1)."""
        return self._c

    @property
    def S(self) -> NDArray[np.float64]:  # noqa: N802
        """``Sbar_nm``, read-only, shape (N+1, N+1)."""
        return self._s

    def __repr__(self) -> str:
        return f"GravityField(degree={self._degree}, r_ref_m={self._r_ref:.6g}, gm={self._gm:.6g})"

    # ------------------------------------------------------------------ evaluation
    def potential(self, r_body: ArrayLike) -> float | NDArray[np.float64]:
        """Gravitational potential ``U`` [m^2/s^2], positive convention (``a = grad U``).

        Args:
            r_body: Position(s) in the body frame [m], shape (3,) or (k, 3), outside the body.

        Returns:
            ``U`` as a float for shape (3,), else shape (k,).

        """
        p = np.asarray(r_body, dtype=np.float64)
        if p.shape == (3,):
            x, y, z = p.tolist()
            r2 = x * x + y * y + z * z
            if not r2 > 0.0:
                raise GravityModelError(f"position must be finite and non-zero, got {p.tolist()} m")
            r = math.sqrt(r2)
            f = self._r_ref / r2
            pw = np.array([x * f, y * f, z * f])[:, None] ** self._exponents
            d = self._d
            val = np.dot(np.dot(np.dot(self._pot_table, pw[2]).reshape(d, d), pw[1]), pw[0])
            return self._gm / r * float(val)
        pts = self._points(p)
        r2 = np.einsum("ki,ki->k", pts, pts)
        if not (r2 > 0.0).all():
            raise GravityModelError("positions must be finite and non-zero")
        r = np.sqrt(r2)
        mono = self._monomials(pts * (self._r_ref / r2)[:, None])
        return self._gm / r * (mono @ self._h_table.reshape(-1))

    def acceleration(self, r_body: ArrayLike) -> NDArray[np.float64]:
        """Gravitational acceleration ``a = grad U`` [m/s^2] in the body frame.

        Cheap for a single point (a few numpy calls on tiny arrays: about 4.3 us at degree 8 on
        the development machine); shape (k, 3) input is passed to :meth:`acceleration_batch`.
        Inside an integrator, :meth:`acceleration_xyz` skips the array wrapping.

        Args:
            r_body: Position in the body frame [m], shape (3,) (or (k, 3)), outside the body.

        Returns:
            Acceleration [m/s^2], shape (3,) (or (k, 3)).

        """
        p = np.asarray(r_body, dtype=np.float64)
        if p.shape != (3,):
            return self.acceleration_batch(p)
        x, y, z = p.tolist()
        return np.array(self.acceleration_xyz(x, y, z))

    def acceleration_xyz(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        """Acceleration ``a = grad U`` [m/s^2] at one body-frame point given as plain floats.

        The fastest entry point (about 3.5 us at degree 8 on the development machine): no array
        in or out.

        Args:
            x: Body-frame x [m].
            y: Body-frame y [m].
            z: Body-frame z [m].

        Returns:
            ``(a_x, a_y, a_z)`` [m/s^2] in the body frame.

        Raises:
            GravityModelError: If the point is the origin or not finite.

        """
        r2 = x * x + y * y + z * z
        if not r2 > 0.0:
            raise GravityModelError(f"position must be finite and non-zero, got {[x, y, z]} m")
        r = math.sqrt(r2)
        f = self._r_ref / r2
        pw = np.array([x * f, y * f, z * f])[:, None] ** self._exponents
        d = self._d
        dot = np.dot
        gx, gy, gz, k = dot(
            dot(dot(self._accel_table, pw[2]).reshape(4 * d, d), pw[1]).reshape(4, d), pw[0]
        ).tolist()
        rho = self._r_ref / r
        g = self._gm / r2
        k /= r
        return (g * (rho * gx - x * k), g * (rho * gy - y * k), g * (rho * gz - z * k))

    def acceleration_batch(self, r_body: ArrayLike) -> NDArray[np.float64]:
        """Acceleration ``a = grad U`` [m/s^2] at many points.

        Args:
            r_body: Positions in the body frame [m], shape (k, 3).

        Returns:
            Accelerations [m/s^2], shape (k, 3).

        """
        pts = self._points(np.asarray(r_body, dtype=np.float64))
        r2 = np.einsum("ki,ki->k", pts, pts)
        if not (r2 > 0.0).all():
            raise GravityModelError("positions must be finite and non-zero")
        r = np.sqrt(r2)
        out = np.empty_like(pts)
        chunk = 4096
        for start in range(0, pts.shape[0], chunk):
            sl = slice(start, start + chunk)
            q = pts[sl] * (self._r_ref / r2[sl])[:, None]
            vals = self._monomials(q) @ self._batch_table  # (k, 4)
            rho = (self._r_ref / r[sl])[:, None]
            out[sl] = (self._gm / r2[sl])[:, None] * (
                rho * vals[:, :3] - pts[sl] / r[sl][:, None] * vals[:, 3:4]
            )
        return out

    def _points(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        if p.ndim != 2 or p.shape[1] != 3:
            raise GravityModelError(
                f"positions must have shape (3,) or (k, 3) in metres, got {p.shape}"
            )
        return p

    def _monomials(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """All ``q_x^i q_y^j q_z^k`` for ``i, j, k < N+1``, shape (k, (N+1)^3), C order."""
        pw = q[:, :, None] ** self._exponents  # (k, 3, d)
        d = self._d
        m = pw[:, 0, :, None, None] * pw[:, 1, None, :, None] * pw[:, 2, None, None, :]
        return m.reshape(q.shape[0], d * d * d)


def load_default_field() -> GravityField:
    """Return the committed degree-8 Itokawa field (``satellite/data/itokawa_degree8.json``).

    Generated by :meth:`GravityField.from_mesh` from Gaskell's 64-level shape model
    (HAY-A-AMICA-5-ITOKAWASHAPE-V1.0) with mass 3.51e10 kg; see the file's ``provenance`` key.
    """
    return GravityField.from_dict(read_default_table())
