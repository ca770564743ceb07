"""Orbit dynamics around Itokawa: Kepler model, spherical-harmonic truth, spinning body, band.

Frames and units (SI throughout: m, s, m/s, m/s^2):

* The **inertial frame** has its origin at the asteroid's centre of mass and its z axis along
  the spin pole (body +z of the Gaskell frame). The state is ``x = [r, v]``, shape (6,).
* The **body frame** is the gravity table's frame (Gaskell axes, centre of mass). It turns about
  z at the rate ``omega = 2 pi / 12.1324 h`` (Demura et al. 2006, via
  ``/shared/data/itokawa/README.md``): ``r_body = Rz(-theta(t)) r``, ``theta = theta0 + omega t``.
  The sense follows the pole convention (rotation positive about +z); Itokawa's rotation is
  retrograde with respect to its heliocentric orbit, which is a statement about the pole's
  direction, not about this sense. ``spin=False`` freezes the body (``omega = 0``).
* **Truth flow**: ``r_dot = v``, ``v_dot = Rz(theta) a_SH(r_body)``, with ``a_SH`` the
  body-frame field (which includes the point-mass term): any model of :mod:`satellite.gravity.fields`
  (the command line's default is the tabulated exact polyhedron field; this class's default,
  kept for the paper's comparison, is the degree-8 series). The **model flow** used by the trigger
  and by the controller is Kepler only, ``v_dot = -mu r / |r|^3`` (the paper's model); the
  difference is the disturbance ``d`` (paper, Section III-B).
* **Band and barrier** (paper, Section III-B): ``1.6 R <= |r| <= 2.4 R`` with
  ``h(x) = (0.4 R)^2 - (|r| - 2 R)^2`` [m^2], ``R`` the volume-equivalent radius of the gravity
  table (161.93 m for Itokawa).

The spherical-harmonic series converges only outside the Brillouin sphere (311.7 m = 1.925 R
for Itokawa, see :mod:`satellite.gravity.spherical`); the band's inner part (down to 1.6 R) lies inside
it, and the body's long-axis tips reach inside the band. The paper used the series throughout
the band; ``--gravity sh8`` still does, the default field is valid everywhere (REPRODUCTION.md).
Surface contact is watched by :mod:`satellite.control.contact`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from isf_robot.core import Barrier, ConfigError
from satellite.compiled import inlined
from satellite.gravity.fields import DEFAULT_GRAVITY, load_field

__all__ = [
    "SPIN_PERIOD_H",
    "BAND_INNER",
    "BAND_OUTER",
    "BAND_CENTRE",
    "OrbitModel",
    "BandBarrier",
    "InitialOrbit",
    "to_body",
    "truth_from_body",
]

SPIN_PERIOD_H = 12.1324
"""Itokawa's rotation period [h] (Demura et al. 2006)."""

BAND_INNER = 1.6
"""Inner edge of the safe band in units of R (paper, Section III-B)."""

BAND_OUTER = 2.4
"""Outer edge of the safe band in units of R (paper, Section III-B)."""

BAND_CENTRE = 2.0
"""Centre of the band in units of R; the barrier's half-width is 0.4 R."""


@inlined
def to_body(theta: float, px: float, py: float) -> tuple[float, float, float, float]:
    """``(cos theta, sin theta, x_body, y_body)`` of an inertial position's x, y with the body turned by ``theta``."""
    c = math.cos(theta)
    s = math.sin(theta)
    return c, s, c * px + s * py, c * py - s * px


@inlined
def truth_from_body(c: float, s: float, qx: float, qy: float, qz: float, bx: float, by: float, bz: float,
                    mu: float, k: float) -> tuple[float, float, float]:
    """Inertial truth acceleration from the body-frame field ``b`` at the body-frame point ``q``.

    ``a = Rz(theta) [a_K + k (b - a_K)]`` with ``a_K = -mu q / |q|^3`` (``k = 1``: the field itself), and
    ``c, s`` the cosine and sine of the body angle (:func:`to_body`).
    """
    if k != 1.0:
        r2 = qx * qx + qy * qy + qz * qz
        g = -mu / (r2 * math.sqrt(r2))
        bx, by, bz = g * qx + k * (bx - g * qx), g * qy + k * (by - g * qy), g * qz + k * (bz - g * qz)
    return c * bx - s * by, s * bx + c * by, bz


class OrbitModel:
    """Kepler model and gravity truth of an orbit about a spinning body.

    Args:
        field: Gravity model (the interface of :mod:`satellite.gravity.fields`); default the valid
            one, :data:`satellite.gravity.fields.DEFAULT_GRAVITY` (the tabulated exact polyhedron field,
            as ``isf-satellite run``); ``load_field("sh8")`` gives the paper's degree-8 series.
        spin: Whether the body turns (default True).
        spin_period_h: Rotation period [h], > 0.
        body_phase: Body rotation angle ``theta0`` at ``t = 0`` [rad].
        disturbance_scale: Factor ``k`` on the non-Kepler part of the truth,
            ``a = a_Kepler + k (a_SH - a_Kepler)`` (default 1: the full field). An
            experiment knob for studying how the results depend on the disturbance's size.

    Attributes:
        R: Reference (volume-equivalent) radius [m].
        mu: Gravitational parameter ``GM`` [m^3/s^2].
        omega: Spin rate [rad/s] (0 without spin).

    """

    def __init__(
        self,
        field: Any = None,
        *,
        spin: bool = True,
        spin_period_h: float = SPIN_PERIOD_H,
        body_phase: float = 0.0,
        disturbance_scale: float = 1.0,
    ) -> None:
        if not (math.isfinite(disturbance_scale) and disturbance_scale >= 0.0):
            raise ConfigError(f"disturbance_scale must be >= 0, got {disturbance_scale}")
        if not (math.isfinite(spin_period_h) and spin_period_h > 0.0):
            raise ConfigError(f"spin_period_h must be a positive number of hours, got {spin_period_h}")
        if not math.isfinite(body_phase):
            raise ConfigError(f"body_phase must be finite (radians), got {body_phase}")
        if field is None:
            field = load_field(DEFAULT_GRAVITY)
        self.field = field
        self.R = float(self.field.r_ref_m)
        self.mu = float(self.field.gm)
        self.spin = bool(spin)
        self.spin_period_h = float(spin_period_h)
        self.omega = 2.0 * math.pi / (spin_period_h * 3600.0) if spin else 0.0
        self.body_phase = float(body_phase)
        self.disturbance_scale = float(disturbance_scale)
        self.r_centre = BAND_CENTRE * self.R
        self.half_width = (BAND_OUTER - BAND_CENTRE) * self.R
        self.h_max = self.half_width**2

    # -- band -----------------------------------------------------------------------------
    def h_of_r(self, r: float) -> float:
        """Barrier value ``(0.4 R)^2 - (r - 2R)^2`` [m^2] at radius ``r`` [m]."""
        dr = r - self.r_centre
        return self.h_max - dr * dr

    def period_at(self, r: float) -> float:
        """Kepler period of a circular orbit of radius ``r`` [m], in [s]."""
        return 2.0 * math.pi * math.sqrt(r**3 / self.mu)

    def mean_motion_centre(self) -> float:
        """Mean motion of the circular orbit at the band centre 2R [rad/s]."""
        return math.sqrt(self.mu / self.r_centre**3)

    # -- flows ----------------------------------------------------------------------------
    def kepler_rhs(self, t: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Model flow ``F(x) = [v, -mu r / |r|^3]``, shape (6,)."""
        px, py, pz, vx, vy, vz = x.tolist()
        r2 = px * px + py * py + pz * pz
        k = -self.mu / (r2 * math.sqrt(r2))
        return np.array([vx, vy, vz, k * px, k * py, k * pz])

    def truth_rhs(self, t: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Truth flow: the gravity model of the spinning body (body frame turned), shape (6,)."""
        px, py, pz, vx, vy, vz = x.tolist()
        c, s, qx, qy = to_body(self.body_phase + self.omega * t, px, py)
        bx, by, bz = self.field.acceleration((qx, qy, pz)).tolist()
        ax, ay, az = truth_from_body(c, s, qx, qy, pz, bx, by, bz, self.mu, self.disturbance_scale)
        return np.array([vx, vy, vz, ax, ay, az])

    def truth_acceleration(self, t: float, r: NDArray[np.float64]) -> NDArray[np.float64]:
        """Inertial acceleration of the truth model at position ``r`` [m], shape (3,)."""
        return self.truth_rhs(t, np.concatenate([np.asarray(r, dtype=float), np.zeros(3)]))[3:]

    def disturbance(self, t: float, r: NDArray[np.float64]) -> NDArray[np.float64]:
        """``d = a_truth - a_Kepler`` [m/s^2] at position ``r`` (inertial, [m]), shape (3,)."""
        r = np.asarray(r, dtype=float)
        return self.truth_acceleration(t, r) + self.mu * r / float(np.linalg.norm(r)) ** 3

    def disturbance_bound(self, samples: int = 4000, seed: int = 0) -> float:
        """Largest sampled ``|d|`` [m/s^2] over the band (positions uniform in direction and radius).

        A sampled bound (used for the MIET bound's ``d_bar``), not a proof.
        """
        rng = np.random.default_rng(seed)
        u = rng.normal(size=(samples, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        rad = rng.uniform(BAND_INNER, BAND_OUTER, size=samples) * self.R
        pts = u * rad[:, None]
        a = self.field.acceleration_batch(pts) + self.mu * pts / (rad**3)[:, None]
        return self.disturbance_scale * float(np.max(np.linalg.norm(a, axis=1)))

    def accel_bound(self, samples: int = 4000, seed: int = 0, factor: float = 2.0) -> float:
        """Bound ``A`` on the truth acceleration [m/s^2] in the band, for the event scan's rate bounds.

        ``mu / (1.6 R)^2`` (the Kepler part at the inner edge) plus ``factor`` times the sampled
        largest non-Kepler part (:meth:`disturbance_bound`): a sampled bound with a safety
        factor, not a proof (the non-Kepler part is smooth in the band, and its sampled maximum
        moves by well under a factor 2 between 400 and 40000 samples).
        """
        return self.mu / (BAND_INNER * self.R) ** 2 + factor * self.disturbance_bound(samples, seed)

    def with_phase(self, body_phase: float) -> OrbitModel:
        """Same model with another body phase at ``t = 0`` [rad]."""
        return OrbitModel(
            self.field, spin=self.spin, spin_period_h=self.spin_period_h, body_phase=body_phase,
            disturbance_scale=self.disturbance_scale,
        )


class BandBarrier(Barrier):
    """``h(x) = (0.4 R)^2 - (|r| - 2R)^2`` on the state ``x = [r, v]`` (paper, Section III-B).

    ``dh/dx = [-2 (|r| - 2R) r / |r|, 0, 0, 0]``: h depends on position only, so along any flow
    ``h_dot = -2 (|r| - 2R) r_dot`` with ``r_dot = r . v / |r|``, whatever the force model.

    Args:
        model: Supplies R.

    """

    name = "band"

    def __init__(self, model: OrbitModel) -> None:
        self.r_centre = model.r_centre
        self.h_max = model.h_max

    def value(self, x: NDArray[np.float64], t: float = 0.0) -> float:
        """Return ``h(x)`` [m^2]."""
        r = math.sqrt(float(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]))
        dr = r - self.r_centre
        return self.h_max - dr * dr

    def gradient(self, x: NDArray[np.float64], t: float = 0.0) -> NDArray[np.float64]:
        """Return ``dh/dx``, shape (6,) [m]."""
        p = np.asarray(x[:3], dtype=float)
        r = float(np.linalg.norm(p))
        g = np.zeros(6)
        g[:3] = -2.0 * (r - self.r_centre) * p / r
        return g


@dataclass(frozen=True)
class InitialOrbit:
    """Initial state of a run: a Kepler orbit through a point of the band.

    Defaults: radius 2R (the band centre, where ``h`` is largest), the Kepler circular speed,
    inclination 45 deg to the body's equator (neither equatorial, where the C22 term acts most,
    nor polar), and node, argument of latitude and body phase drawn from the seed. The paper
    gives no initial state or inclination.

    Attributes:
        radius_over_R: Initial radius in units of R, inside [1.6, 2.4].
        inclination_deg: Inclination to the body's equator (inertial x-y plane) [deg], in [0, 180].
        speed_factor: Initial speed as a multiple of the circular speed at that radius, > 0.
        seed: Draws the node, the argument of latitude (both uniform in [0, 2 pi)) and the
            body's rotation phase (uniform in [0, 2 pi)).
        raan_deg: Overrides the drawn node [deg] when given.
        arg_lat_deg: Overrides the drawn argument of latitude [deg] when given.
        body_phase_deg: Overrides the drawn body phase [deg] when given.

    """

    radius_over_R: float = BAND_CENTRE
    inclination_deg: float = 45.0
    speed_factor: float = 1.0
    seed: int = 0
    raan_deg: float | None = None
    arg_lat_deg: float | None = None
    body_phase_deg: float | None = None

    def __post_init__(self) -> None:
        if not (BAND_INNER <= self.radius_over_R <= BAND_OUTER):
            raise ConfigError(
                f"initial radius must lie in the band [{BAND_INNER}, {BAND_OUTER}] R, got {self.radius_over_R}"
            )
        if not (0.0 <= self.inclination_deg <= 180.0):
            raise ConfigError(f"inclination must be in [0, 180] degrees, got {self.inclination_deg}")
        if not (math.isfinite(self.speed_factor) and self.speed_factor > 0.0):
            raise ConfigError(f"speed_factor must be positive, got {self.speed_factor}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ConfigError(f"seed must be a non-negative integer, got {self.seed!r}")

    def angles(self) -> tuple[float, float, float]:
        """Return ``(raan, argument of latitude, body phase)`` [rad] (drawn or overridden)."""
        draws = np.random.default_rng(int(self.seed)).uniform(0.0, 2.0 * math.pi, size=3)
        raan = math.radians(self.raan_deg) if self.raan_deg is not None else float(draws[0])
        u = math.radians(self.arg_lat_deg) if self.arg_lat_deg is not None else float(draws[1])
        ph = math.radians(self.body_phase_deg) if self.body_phase_deg is not None else float(draws[2])
        return raan, u, ph

    def state(self, model: OrbitModel) -> NDArray[np.float64]:
        """Inertial state ``[r, v]`` [m, m/s], shape (6,), for ``model``'s R and mu."""
        raan, u, _ = self.angles()
        inc = math.radians(self.inclination_deg)
        r = self.radius_over_R * model.R
        speed = self.speed_factor * math.sqrt(model.mu / r)
        # Perifocal-like basis of the orbital plane: node line n, in-plane normal m.
        n = np.array([math.cos(raan), math.sin(raan), 0.0])
        m = np.array([-math.sin(raan) * math.cos(inc), math.cos(raan) * math.cos(inc), math.sin(inc)])
        rhat = math.cos(u) * n + math.sin(u) * m
        that = -math.sin(u) * n + math.cos(u) * m
        return np.concatenate([r * rhat, speed * that])

    def body_phase(self) -> float:
        """Body rotation angle at ``t = 0`` [rad]."""
        return self.angles()[2]
