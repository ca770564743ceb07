"""Harmonic coefficients of a constant-density body from its shape, by exact integration.

Convention (fully normalised, 4-pi geodesy normalisation, no Condon-Shortley phase): in the
body frame, with ``r = |r|``, latitude ``phi`` and longitude ``lambda``, the potential is

    U(r) = GM / r * sum_{n=0}^{N} (R / r)^n sum_{m=0}^{n}
               Pbar_nm(sin phi) (Cbar_nm cos(m lambda) + Sbar_nm sin(m lambda)),

    Pbar_nm = sqrt((2 - delta_m0) (2n + 1) (n - m)! / (n + m)!) P_nm,

``P_nm(t) = (1 - t^2)^(m/2) d^m P_n / dt^m`` (no ``(-1)^m``). ``U`` is positive (``U = GM / r``
for a point mass) and the acceleration is its gradient, ``a = grad U``. The series converges
outside the body's Brillouin sphere (radius 311.7 m for Itokawa) and is only an approximation
closer in; it is not the gravity inside the body.

For a constant-density body of volume ``V`` whose origin is its centre of mass,

    Cbar_nm + i Sbar_nm = 1 / ((2n + 1) V R^n) * integral over the body of
                          Nbar_nm r^n P_nm(sin phi) exp(i m lambda) dV,

and ``r^n P_nm(sin phi) cos(m lambda)``, ``r^n P_nm(sin phi) sin(m lambda)`` are homogeneous
harmonic polynomials of degree ``n`` in ``x, y, z`` (solid harmonics, built by
:func:`solid_harmonics`), so the coefficients are exact linear combinations of the body's
monomial moments (:meth:`satellite.shape.mesh.TriangleMesh.monomial_moments`).

The field built from these coefficients, and its evaluation, is :mod:`satellite.gravity.spherical`; the
JSON table they are stored in is :mod:`satellite.gravity.harmonics_io`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from satellite.errors import GravityModelError
from satellite.shape.mesh import TriangleMesh

__all__ = [
    "G_CODATA2018",
    "ITOKAWA_MASS_KG",
    "MAX_DEGREE",
    "PolyhedronHarmonics",
    "check_degree",
    "normalisation",
    "solid_harmonics",
    "polyhedron_harmonics",
]

G_CODATA2018 = 6.67430e-11
"""Newtonian constant of gravitation [m^3 kg^-1 s^-2] (CODATA 2018)."""

ITOKAWA_MASS_KG = 3.51e10
"""Mass of 25143 Itokawa [kg] (Fujiwara et al. 2006, Science 312:1330)."""

MAX_DEGREE = 20
"""Highest degree accepted. The monomial forms used here lose accuracy as the degree grows
(alternating sums with large coefficients); at degree 20 the coefficients of a test body still
agree with an independent quadrature to about 1e-13."""


def check_degree(degree: int) -> int:
    """Return ``degree`` as an int after checking ``0 <= degree <= MAX_DEGREE``.

    Raises:
        GravityModelError: Not an integer, or out of range.

    """
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)):
        raise GravityModelError(f"degree must be an integer, got {degree!r}")
    if not 0 <= int(degree) <= MAX_DEGREE:
        raise GravityModelError(f"degree must be in [0, {MAX_DEGREE}], got {degree}")
    return int(degree)


def normalisation(n: int, m: int) -> float:
    """Full (4-pi) normalisation factor ``Nbar_nm = Pbar_nm / P_nm``.

    Args:
        n: Degree, >= 0.
        m: Order, ``0 <= m <= n``.

    Returns:
        ``sqrt((2 - delta_m0) (2n + 1) (n - m)! / (n + m)!)``.

    """
    ratio = math.factorial(n - m) / math.factorial(n + m)
    return math.sqrt((1.0 if m == 0 else 2.0) * (2 * n + 1) * ratio)


def solid_harmonics(degree: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unnormalised solid harmonics as dense monomial coefficient arrays.

    ``V_nm(x, y, z) = r^n P_nm(sin phi) cos(m lambda)`` and
    ``W_nm(x, y, z) = r^n P_nm(sin phi) sin(m lambda)``
    (no Condon-Shortley phase), from ``V_mm + i W_mm = (2m - 1)!! (x + i y)^m`` and
    ``(n - m) V_nm = (2n - 1) z V_{n-1,m} - (n + m - 1) r^2 V_{n-2,m}`` (same for ``W``).

    Args:
        degree: Highest degree ``N``, ``0 <= N <= MAX_DEGREE``.

    Returns:
        ``(V, W)``, each of shape (N+1, N+1, N+1, N+1, N+1): ``V[n, m, i, j, k]`` is the coefficient
        of ``x^i y^j z^k`` in ``V_nm`` (zero for ``m > n``).

    """
    nmax = check_degree(degree)
    d = nmax + 1
    v = np.zeros((d, d, d, d, d))
    w = np.zeros((d, d, d, d, d))

    def times(p: NDArray[np.float64], axis: int, power: int = 1) -> NDArray[np.float64]:
        out = np.zeros_like(p)
        src = [slice(None)] * 3
        dst = [slice(None)] * 3
        src[axis] = slice(0, d - power)
        dst[axis] = slice(power, d)
        out[tuple(dst)] = p[tuple(src)]
        return out

    def times_r2(p: NDArray[np.float64]) -> NDArray[np.float64]:
        return times(p, 0, 2) + times(p, 1, 2) + times(p, 2, 2)

    v[0, 0, 0, 0, 0] = 1.0
    for m in range(1, d):
        f = 2 * m - 1
        v[m, m] = f * (times(v[m - 1, m - 1], 0) - times(w[m - 1, m - 1], 1))
        w[m, m] = f * (times(w[m - 1, m - 1], 0) + times(v[m - 1, m - 1], 1))
    for m in range(d):
        for n in range(m + 1, d):
            for arr in (v, w):
                nxt = (2 * n - 1) * times(arr[n - 1, m], 2)
                if n - 2 >= m:
                    nxt -= (n + m - 1) * times_r2(arr[n - 2, m])
                arr[n, m] = nxt / (n - m)
    return v, w


class PolyhedronHarmonics(NamedTuple):
    """Normalised coefficients of a constant-density polyhedron (see :func:`polyhedron_harmonics`).

    Attributes:
        C: ``Cbar_nm``, shape (N+1, N+1), zero above the diagonal.
        S: ``Sbar_nm``, shape (N+1, N+1), zero above the diagonal and in column 0.
        r_ref_m: Reference radius [m] = volume-equivalent radius.
        volume_m3: Volume of the mesh [m^3].
        centre_of_mass_m: Centre of mass in the mesh's frame [m], shape (3,); the coefficients
            are about this point.

    """

    C: NDArray[np.float64]
    S: NDArray[np.float64]
    r_ref_m: float
    volume_m3: float
    centre_of_mass_m: NDArray[np.float64]


def polyhedron_harmonics(mesh: TriangleMesh, degree: int) -> PolyhedronHarmonics:
    """Fully normalised harmonic coefficients of a constant-density closed mesh, exactly.

    The origin is the centre of mass, the axes are the mesh's, and the reference radius is the
    volume-equivalent radius ``R``. Moments are taken of ``(x - x_cm) / R`` for conditioning, so
    ``Cbar_nm = Nbar_nm / ((2n + 1) V) * sum_ijk V_nm[i, j, k] M[i, j, k]``.

    Args:
        mesh: Checked, closed, outward-oriented mesh [m].
        degree: Highest degree ``N``, ``0 <= N <= MAX_DEGREE``.

    Returns:
        The coefficients and the reference quantities.

    """
    nmax = check_degree(degree)
    com = mesh.centre_of_mass
    r_ref = mesh.volume_equivalent_radius
    moments = mesh.monomial_moments(nmax, origin=com, scale=r_ref)
    volume = float(moments[0, 0, 0])
    v, w = solid_harmonics(nmax)
    c = np.zeros((nmax + 1, nmax + 1))
    s = np.zeros((nmax + 1, nmax + 1))
    for n in range(nmax + 1):
        for m in range(n + 1):
            factor = normalisation(n, m) / ((2 * n + 1) * volume)
            c[n, m] = factor * float(np.sum(v[n, m] * moments))
            if m > 0:
                s[n, m] = factor * float(np.sum(w[n, m] * moments))
    c[0, 0] = 1.0  # exact by construction; avoid a last-digit rounding
    return PolyhedronHarmonics(c, s, float(r_ref), float(mesh.volume), com)
