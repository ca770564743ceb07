"""Safeguarding impulsive controller (the paper, Section III-C) and its margin (``c`` of Section III-A).

At the current radius ``r`` the controller aims at the apsis ``r_t = 2R + 0.5 (r - 2R)``:

* ``r >= 2R``: ``r_t`` becomes the new **periapsis** and the satellite is placed at true anomaly
  ``nu = -pi + (pi / 2) (r - 2R) / (0.4 R)`` (from -pi at 2R to -pi/2 at 2.4R);
* ``r < 2R``: ``r_t`` becomes the new **apoapsis**, ``nu = (pi / 2) (2R - r) / (0.4 R)``
  (from 0 at 2R to pi/2 at 1.6R).

The conic ``r = p / (1 + e cos nu)`` with ``r_t = p / (1 + e)`` (periapsis) gives
``e = (r - r_t) / (r_t - r cos nu)``; with ``r_t = p / (1 - e)`` (apoapsis)
``e = (r_t - r) / (r_t + r cos nu)``; then ``p = r (1 + e cos nu)``. The new velocity, in the
current orbital plane, is ``v+ = (mu / H) e sin(nu) r_hat + (H / r) t_hat`` with
``H = sqrt(mu p)`` and ``t_hat = k_hat x r_hat`` (``k_hat`` the current angular-momentum
direction, so the sense of motion is kept); the impulse is ``v+ - v``. When the velocity is
(almost) radial the plane is undefined; the controller then uses the plane through ``r`` and
the z axis (or the x axis when ``r`` is along z). Only the Kepler model is used (as in the paper).

Trigger (eq. greedy_cond): ``Xi(x) = LF h - |dh/dx| d_bar + alpha(h)`` with
``LF h = -2 (r - 2R) r_dot`` and ``|dh/dx| = 2 |r - 2R|``. After an impulse, ``h`` is unchanged
and ``r_dot = (mu / H) e sin nu`` depends on ``r`` only, so ``Xi(G(x, K(x)))`` is a function of
``r`` alone (:meth:`SafeguardingController.post_jump_xi`); the margin ``c`` is chosen from it.
The trigger values used during a run are :class:`satellite.control.triggers.BandTriggers`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from isf_robot.core import ClassK, ConfigError, EventTriggeredImpulsiveController, Linear, UnknownNameError, ZenoGuard
from isf_robot.core.triggers import xi_on_scalar
from satellite.control.shooting import ShootingController, ShootingParams, plane_basis
from satellite.control.triggers import BandTriggers
from satellite.orbit.model import BAND_INNER, BAND_OUTER, BandBarrier, OrbitModel

__all__ = [
    "CONTROLLERS",
    "SafeguardingController",
    "ControlParams",
    "ResolvedControl",
    "resolve_control",
    "make_controller",
    "jump_map",
]


CONTROLLERS: tuple[str, ...] = ("kepler", "shooting")
"""Safeguarding controllers: ``kepler`` (the paper's, :class:`SafeguardingController`) and
``shooting`` (:class:`satellite.control.shooting.ShootingController`, issue 14 item 5)."""


class SafeguardingController:
    """The paper's impulsive safeguarding controller ``K(x)`` (Kepler model only).

    Args:
        model: Supplies R and mu.

    """

    def __init__(self, model: OrbitModel) -> None:
        self.mu = model.mu
        self.r_centre = model.r_centre
        self.half_width = model.half_width

    def target(self, r: float) -> tuple[float, float, str]:
        """Target apsis ``r_t`` [m], true anomaly ``nu`` [rad] and ``"periapsis"``/``"apoapsis"``."""
        dr = r - self.r_centre
        r_t = self.r_centre + 0.5 * dr
        if dr >= 0.0:
            return r_t, -math.pi + 0.5 * math.pi * dr / self.half_width, "periapsis"
        return r_t, 0.5 * math.pi * (-dr) / self.half_width, "apoapsis"

    def conic(self, r: float) -> tuple[float, float, float]:
        """Semi-latus rectum ``p`` [m], eccentricity ``e`` and true anomaly ``nu`` [rad] after the jump."""
        r_t, nu, kind = self.target(r)
        cn = math.cos(nu)
        if kind == "periapsis":
            e = (r - r_t) / (r_t - r * cn)
        else:
            e = (r_t - r) / (r_t + r * cn)
        return r * (1.0 + e * cn), e, nu

    def post_jump_speeds(self, r: float) -> tuple[float, float]:
        """Radial and transverse speed after the jump at radius ``r`` [m/s]."""
        p, e, nu = self.conic(r)
        hh = math.sqrt(self.mu * p)
        return self.mu / hh * e * math.sin(nu), hh / r

    def post_jump_xi(self, r: float, alpha: ClassK, d_bar: float = 0.0) -> float:
        """``Xi(G(x, K(x)))`` at radius ``r`` [m^2/s] (independent of the pre-jump velocity).

        The core's formula (:func:`~isf_robot.core.triggers.xi_on_scalar`) with the band's Lie
        data after the jump: ``LF h = -2 (r - 2R) v_r+``, ``|dh/dx| = 2 |r - 2R|``.
        """
        v_r, _ = self.post_jump_speeds(r)
        dr = r - self.r_centre
        return xi_on_scalar(-2.0 * dr * v_r, 0.0, 2.0 * abs(dr), self.half_width**2 - dr * dr, alpha, d_bar)

    def velocity_after(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Velocity ``v+`` [m/s] after the jump at state ``x``, shape (3,)."""
        r, rhat, that = plane_basis(x)
        v_r, v_t = self.post_jump_speeds(r)
        return v_r * rhat + v_t * that

    def __call__(self, t: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Impulse ``dv = v+ - v`` [m/s], shape (3,)."""
        return self.velocity_after(x) - np.asarray(x[3:6], dtype=float)


def jump_map(x: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Impulsive jump ``G(x, dv) = [r, v + dv]``, shape (6,)."""
    out = np.array(x, dtype=float)
    out[3:6] += v
    return out


@dataclass(frozen=True)
class ControlParams:
    """Trigger and margin settings (the paper gives none of them).

    Attributes:
        alpha_gain: Gain of ``alpha(h) = gain * h`` [1/s]; default (``None``) the mean motion of
            the circular orbit at 2R, ``sqrt(mu / (2R)^3)`` (2.62e-4 1/s for Itokawa): ``h`` may
            shrink at most at the natural orbital rate.
        d_bar: Disturbance bound in ``Xi`` (default 0). ``h`` depends on position only and the
            disturbance acts on the velocity equation, so ``dh/dx . d = 0`` exactly and the
            robust term is not needed for safety; a positive value adds conservatism.
        c: Post-jump margin [m^2/s]; default (``None``) ``c_fraction`` times the smallest
            ``Xi(G(x, K(x)))`` over the band (sampled on 4001 radii).
        c_fraction: Fraction used for the default ``c``, in (0, 1].
        controller: Safeguarding controller, one of :data:`CONTROLLERS` (default the paper's
            ``kepler``). ``c`` is the paper's controller's in both cases (the shooting controller
            keeps only candidates with ``Xi(G(x, v)) >= c`` and always has the paper's impulse).
        shooting: Settings of the ``shooting`` controller (ignored by ``kepler``).

    """

    alpha_gain: float | None = None
    d_bar: float = 0.0
    c: float | None = None
    c_fraction: float = 0.5
    controller: str = "kepler"
    shooting: ShootingParams = ShootingParams()

    def __post_init__(self) -> None:
        if self.controller not in CONTROLLERS:
            raise UnknownNameError("controller", str(self.controller), CONTROLLERS)
        if not isinstance(self.shooting, ShootingParams):
            raise ConfigError(f"shooting must be a ShootingParams, got {type(self.shooting).__name__}")
        if self.alpha_gain is not None and not (math.isfinite(self.alpha_gain) and self.alpha_gain > 0.0):
            raise ConfigError(f"alpha gain must be positive [1/s], got {self.alpha_gain}")
        if not (math.isfinite(self.d_bar) and self.d_bar >= 0.0):
            raise ConfigError(f"d_bar must be >= 0, got {self.d_bar}")
        if self.c is not None and not (math.isfinite(self.c) and self.c > 0.0):
            raise ConfigError(f"c must be positive [m^2/s], got {self.c}")
        if not (0.0 < self.c_fraction <= 1.0):
            raise ConfigError(f"c_fraction must be in (0, 1], got {self.c_fraction}")


@dataclass(frozen=True)
class ResolvedControl:
    """Settings with defaults filled in.

    Attributes:
        alpha_gain: [1/s].
        d_bar: Disturbance bound used in ``Xi``.
        c: Post-jump margin [m^2/s].
        min_post_jump_xi: Smallest sampled ``Xi(G(x, K(x)))`` over the band [m^2/s].
        argmin_r_over_R: Radius of that minimum [R].
        controller: Safeguarding controller name (:data:`CONTROLLERS`).
        shooting: Shooting settings (used by ``shooting``).

    """

    alpha_gain: float
    d_bar: float
    c: float
    min_post_jump_xi: float
    argmin_r_over_R: float
    controller: str = "kepler"
    shooting: ShootingParams = ShootingParams()

    def describe(self) -> dict[str, object]:
        """The controller's settings for a run's report: empty for ``kepler`` (the paper's, the default)."""
        if self.controller == "kepler":
            return {}
        return {"controller": self.controller, "shooting": self.shooting.describe()}


def resolve_control(model: OrbitModel, params: ControlParams | None = None, samples: int = 4001) -> ResolvedControl:
    """Fill in the defaults and check that the controller meets ``Xi(G(x, K(x))) >= c`` on the band.

    Raises:
        ConfigError: The sampled post-jump ``Xi`` is not positive somewhere on the band, or the
            given ``c`` exceeds its minimum (the run would fail its post-jump check).

    """
    params = params or ControlParams()
    gain = params.alpha_gain if params.alpha_gain is not None else model.mean_motion_centre()
    alpha = Linear(gain)
    ctrl = SafeguardingController(model)
    radii = np.linspace(BAND_INNER, BAND_OUTER, samples) * model.R
    vals = np.array([ctrl.post_jump_xi(float(r), alpha, params.d_bar) for r in radii])
    i = int(np.argmin(vals))
    low = float(vals[i])
    if not low > 0.0:
        raise ConfigError(
            f"the safeguarding controller gives Xi(G(x,K(x))) = {low:.3g} <= 0 at r = "
            f"{radii[i] / model.R:.4f} R with alpha gain {gain:g} and d_bar {params.d_bar:g}; "
            "no positive margin c exists (lower d_bar or raise alpha)"
        )
    c = params.c if params.c is not None else params.c_fraction * low
    if c > low:
        raise ConfigError(
            f"c = {c:g} exceeds the smallest post-jump Xi over the band, {low:g} at r = "
            f"{radii[i] / model.R:.4f} R; the post-jump check would fail"
        )
    return ResolvedControl(gain, params.d_bar, c, low, float(radii[i] / model.R), params.controller, params.shooting)


def make_controller(
    model: OrbitModel, resolved: ResolvedControl, *, tol: float = 1e-9, zeno: ZenoGuard | None = None
) -> EventTriggeredImpulsiveController:
    """Core controller: Kepler flow model, jump ``[r, v + dv]``, band barrier, safeguarding ``K``.

    ``K`` is the paper's :class:`SafeguardingController` or, for ``resolved.controller ==
    "shooting"``, a :class:`satellite.control.shooting.ShootingController` over the run's truth field
    (``model``, with its body phase) that has the paper's impulse among its candidates.
    """
    paper = SafeguardingController(model)
    k: object = paper
    if resolved.controller == "shooting":
        trig = BandTriggers(model, Linear(resolved.alpha_gain), resolved.d_bar)
        k = ShootingController(model, trig, resolved.c, resolved.shooting, paper)
    return EventTriggeredImpulsiveController(
        flow_model=model.kepler_rhs,
        jump_map=jump_map,
        barrier=BandBarrier(model),
        controller=k,  # type: ignore[arg-type]
        alpha=Linear(resolved.alpha_gain),
        c=resolved.c,
        d_bar=resolved.d_bar,
        tol=tol,
        zeno=zeno,
    )
