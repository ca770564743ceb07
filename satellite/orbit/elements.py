"""Osculating Kepler elements of a state (two-body problem).

Standard relations (e.g. Bate, Mueller and White, *Fundamentals of Astrodynamics*, 1971,
Chapter 2): specific angular momentum ``H = r x v``, eccentricity vector
``e = v x H / mu - r / |r|``, semi-latus rectum ``p = |H|^2 / mu``, vis-viva
``|v|^2 = mu (2 / |r| - 1 / a)``, conic ``|r| = p / (1 + e cos nu)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["OrbitalElements", "osculating_elements"]


@dataclass(frozen=True)
class OrbitalElements:
    """Osculating elements.

    Attributes:
        p: Semi-latus rectum [m].
        e: Eccentricity (>= 0).
        a: Semi-major axis [m] (``inf`` for a parabola, negative for a hyperbola).
        inclination: Angle between ``H`` and the z axis [rad].
        nu: True anomaly [rad] in (-pi, pi]; 0 for a circular orbit.
        periapsis: ``p / (1 + e)`` [m].
        apoapsis: ``p / (1 - e)`` [m] (``inf`` when ``e >= 1``).
        h_vec: Specific angular momentum ``r x v`` [m^2/s], shape (3,).

    """

    p: float
    e: float
    a: float
    inclination: float
    nu: float
    periapsis: float
    apoapsis: float
    h_vec: np.ndarray


def osculating_elements(x: ArrayLike, mu: float) -> OrbitalElements:
    """Osculating elements of the state ``x = [r, v]`` [m, m/s] about a point mass ``mu``.

    Args:
        x: State, shape (6,).
        mu: Gravitational parameter [m^3/s^2].

    Returns:
        The elements (true anomaly signed by the sign of ``r . v``).

    """
    s = np.asarray(x, dtype=float)
    r_vec, v_vec = s[:3], s[3:]
    r = float(np.linalg.norm(r_vec))
    hv = np.cross(r_vec, v_vec)
    hn = float(np.linalg.norm(hv))
    p = hn * hn / mu
    e_vec = np.cross(v_vec, hv) / mu - r_vec / r
    e = float(np.linalg.norm(e_vec))
    energy = 0.5 * float(v_vec @ v_vec) - mu / r
    a = math.inf if energy == 0.0 else -mu / (2.0 * energy)
    inc = math.acos(max(-1.0, min(1.0, hv[2] / hn))) if hn > 0 else 0.0
    if e < 1e-12:
        nu = 0.0
    else:
        cos_nu = max(-1.0, min(1.0, float(e_vec @ r_vec) / (e * r)))
        nu = math.acos(cos_nu)
        if float(r_vec @ v_vec) < 0.0:
            nu = -nu
    rp = p / (1.0 + e)
    ra = p / (1.0 - e) if e < 1.0 else math.inf
    return OrbitalElements(p, e, a, inc, nu, rp, ra, hv)
