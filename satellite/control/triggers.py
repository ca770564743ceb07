"""The satellite's triggers: the registry of choices and the trigger values.

* :class:`Trigger`: the one definition of the choices ``none | greedy | maneuver`` (the CLI's
  ``--trigger`` values, :func:`satellite.orbit.simulate.simulate`'s argument, ``RunResult.trigger``).
* :class:`BandTriggers`: the trigger values for the band barrier in plain floats, for the
  integrator's event functions, through the plain formula functions :func:`band_values`
  (``h = (0.4R)^2 - (r - 2R)^2``, ``LF h = -2 (r - 2R) r_dot`` along the Kepler flow), :func:`band_xi`
  (the robust bound of eq. greedy_cond with ``|dh/dx| = 2 |r - 2R|``) and :func:`band_rate` (the rate
  bounds), which the compiled arcs (:mod:`satellite.orbit.kernel_parts`) call too. ``Xi_tau`` is
  :func:`isf_robot.core.xi_tau` (eq. trigger:int_time).

What each trigger does during a run is its policy, :mod:`satellite.control.policies`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from enum import Enum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from isf_robot.core import ClassK, UnknownNameError
from isf_robot.core.robust import robust_slack
from isf_robot.core.triggers import xi_tau
from satellite.compiled import inlined
from satellite.orbit.events import RateBound
from satellite.orbit.model import BAND_INNER, BAND_OUTER, OrbitModel

__all__ = ["Trigger", "TRIGGERS", "BandTriggers", "EventFn", "RateBound", "band_values", "band_xi", "band_rate",
           "xi_tau", "XI", "H", "RDOT", "CONTACT", "XITAU"]

EventFn = Callable[[float, NDArray[np.float64]], float]
"""An event function ``g(t, y)``."""



class Trigger(str, Enum):
    """When the safeguarding controller fires (compares and serialises as its name)."""

    NONE = "none"
    GREEDY = "greedy"
    MANEUVER = "maneuver"
    PERIODIC = "periodic"

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)

    @classmethod
    def parse(cls, name: str | Trigger) -> Trigger:
        """The trigger called ``name``.

        Raises:
            UnknownNameError: No such trigger (the message lists the valid names).

        """
        try:
            return cls(name)
        except ValueError:
            raise UnknownNameError("trigger", str(name), TRIGGERS) from None

    @property
    def needs_tau(self) -> bool:
        """Whether the trigger needs a fitted ``tau_p`` (:class:`satellite.control.tau.TauFit`)."""
        return self is Trigger.MANEUVER

    @property
    def description(self) -> str:
        """One line for help texts."""
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    Trigger.NONE: "no control: the run stops when the satellite leaves the band",
    Trigger.GREEDY: "an impulse whenever Xi reaches 0",
    Trigger.MANEUVER: "two-impulse maneuvers timed by a fitted tau_p (needs --tau)",
    Trigger.PERIODIC: "baseline station keeping: an impulse every --period-h hours whatever Xi, the run "
                      "stops at the first band exit",
}

TRIGGERS: tuple[str, ...] = tuple(t.value for t in Trigger)
"""Trigger names, in definition order."""


XI, H, RDOT, CONTACT, XITAU = 0, 1, 2, 3, 4
"""Event kinds of the compiled arcs (:attr:`satellite.orbit.events.Event.code`'s first item)."""


@inlined
def band_values(y: Any, r_centre: float, h_max: float) -> tuple[Any, Any, Any]:
    """``(r [m], h [m^2], LF h [m^2/s])`` at state(s) ``y``, shape (6,) or (6, k)."""
    r = np.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2])
    dr = r - r_centre
    return r, h_max - dr * dr, -2.0 * dr * (y[0] * y[3] + y[1] * y[4] + y[2] * y[5]) / r


@inlined
def band_xi(lfh: Any, r: Any, r_centre: float, d_bar: float, alpha_h: Any) -> Any:
    """``Xi = LF h - |dh/dx| d_bar + alpha(h)`` on the band, ``|dh/dx| = 2 |r - 2R|`` (paper, eq. greedy_cond).

    The core's robust slack (:func:`isf_robot.core.robust.robust_slack`) with no input term, for floats
    or arrays and compiled code; ``alpha_h`` is ``alpha(h)``.
    """
    return robust_slack(lfh, 0.0, 2.0 * abs(r - r_centre), d_bar, alpha_h)


@inlined
def band_rate(kind: int, ya: Any, yb: Any, dt: Any, a: float, r_inner: float, r_outer: float, half_width: float,
              r_centre: float, alpha_slope: float, d_bar: float, d1: float, d2: float) -> Any:
    """Bound on ``|dg/dt|`` of the band's event ``kind`` (:data:`H`, :data:`XI`, :data:`RDOT`, :data:`XITAU`).

    Over intervals of length ``dt`` with end states ``ya``, ``ya`` (shape (6,) or (6, k)); the bounds of
    :class:`BandTriggers` (its docstring derives them); ``d1``, ``d2`` bound ``|tau_p'|``, ``|tau_p''|``.
    """
    ra = np.sqrt(ya[0] * ya[0] + ya[1] * ya[1] + ya[2] * ya[2])
    rb = np.sqrt(yb[0] * yb[0] + yb[1] * yb[1] + yb[2] * yb[2])
    v = 0.5 * (np.sqrt(ya[3] * ya[3] + ya[4] * ya[4] + ya[5] * ya[5])
               + np.sqrt(yb[3] * yb[3] + yb[4] * yb[4] + yb[5] * yb[5])) + 0.5 * a * dt
    b = v * v / r_inner + a
    rda = abs(ya[0] * ya[3] + ya[1] * ya[4] + ya[2] * ya[5]) / ra
    rdb = abs(yb[0] * yb[3] + yb[1] * yb[4] + yb[2] * yb[5]) / rb
    p = np.minimum(v, 0.5 * (rda + rdb) + 0.5 * b * dt)
    d = np.minimum(half_width, 0.5 * (abs(ra - r_centre) + abs(rb - r_centre)) + 0.5 * p * dt)
    if kind == H:
        return 2.0 * d * p
    if kind == RDOT:
        return p * p + r_outer * b
    lfh_rate = 2.0 * p * p + 2.0 * d * b
    if kind == XI:
        return lfh_rate + alpha_slope * 2.0 * d * p + 2.0 * d_bar * p
    lfh = 2.0 * d * p
    return 0.5 * (d2 * lfh * lfh + d1 * lfh_rate)


class BandTriggers:
    """Band-barrier trigger values in plain floats, for the integrator's event functions.

    Same values as :meth:`EventTriggeredImpulsiveController.xi` and
    :meth:`ManeuverScheduler.xi_tau` for the band barrier and the Kepler flow (a test checks it),
    through the core's scalar formulas and without array work.

    With ``accel_bound`` given, the ``*_rate`` methods bound each value's time derivative along
    the truth flow over an interval (for :mod:`satellite.orbit.events`' certified scan). On an interval
    of length ``dt`` with end states ``y_a``, ``y_b``, as long as the trajectory is in the band
    (``1.6 R <= r <= 2.4 R``, where ``|a| <= A``):

    * speed ``|v| <= V = (|v_a| + |v_b|) / 2 + A dt / 2`` (a bound ``g_a + K (t - a)`` from the
      left and ``g_b + K (b - t)`` from the right give ``(g_a + g_b) / 2 + K dt / 2``);
    * ``|r_ddot| <= B = V^2 / 1.6R + A``, since ``r_ddot = (|v|^2 - r_dot^2) / r + r_hat . a``;
    * ``|r_dot| <= P = min(V, (|r_dot_a| + |r_dot_b|) / 2 + B dt / 2)``;
    * ``|r - 2R| <= D = min(0.4 R, (|dr_a| + |dr_b|) / 2 + P dt / 2)``;
    * ``|dh/dt| = |LF h| = 2 |r - 2R| |r_dot| <= 2 D P``;
    * ``|d(LF h)/dt| = |2 r_dot^2 + 2 (r - 2R) r_ddot| <= 2 P^2 + 2 D B``;
    * ``|dXi/dt| <= |d(LF h)/dt| + max alpha' |dh/dt| + 2 d_bar P``;
    * ``|d(r . v)/dt| = |r_dot^2 + r r_ddot| <= P^2 + 2.4 R B``;
    * ``|dXi_tau/dt| = |tau_p'' (LF h)^2 + tau_p' d(LF h)/dt| / 2``.

    Args:
        model: Supplies R.
        alpha: Class-K function [m^2/s per m^2].
        d_bar: Disturbance bound [m/s^2].
        accel_bound: ``A``, a bound on the truth acceleration [m/s^2] in the band, or ``None``
            (no rate bounds: events are seen at step points only).

    """

    def __init__(self, model: OrbitModel, alpha: ClassK, d_bar: float, accel_bound: float | None = None) -> None:
        self.r_centre = model.r_centre
        self.h_max = model.h_max
        self.alpha = alpha
        self.d_bar = d_bar
        self.accel_bound = accel_bound
        self.r_inner = BAND_INNER * model.R
        self.r_outer = BAND_OUTER * model.R
        self.half_width = model.half_width
        hs = np.linspace(0.0, self.h_max, 1001)
        slopes = np.array([alpha.derivative(float(h)) for h in hs])
        self.alpha_slope = 1.05 * float(np.max(slopes)) if np.all(np.isfinite(slopes)) else math.inf

    def parts(self, y: NDArray[np.float64]) -> tuple[float, float, float]:
        """Return ``(r [m], h [m^2], LF h [m^2/s])`` at state ``y``, shape (6,) (:func:`band_values`)."""
        return band_values(y.tolist(), self.r_centre, self.h_max)

    def xi(self, t: float, y: NDArray[np.float64]) -> float:
        """Greedy trigger ``Xi`` [m^2/s] (:func:`band_xi`)."""
        r, h, lfh = self.parts(y)
        return band_xi(lfh, r, self.r_centre, self.d_bar, self.alpha(h))

    def h(self, t: float, y: NDArray[np.float64]) -> float:
        """Barrier value [m^2]."""
        return self.parts(y)[1]

    def r_dot(self, t: float, y: NDArray[np.float64]) -> float:
        """Radial speed ``r . v`` [m^2/s] (scaled; only its sign matters) for apsis detection."""
        px, py, pz, vx, vy, vz = y.tolist()
        return px * vx + py * vy + pz * vz

    def xi_tau_fn(self, dtau_dh: Callable[[float], float]) -> EventFn:
        """Event function ``Xi_tau`` (core :func:`~isf_robot.core.xi_tau`) for a fitted ``tau_p``.

        Args:
            dtau_dh: ``tau_p'(h)`` [s/m^2].

        """

        def xi_tau_event(t: float, y: NDArray[np.float64]) -> float:
            _, h, lfh = self.parts(y)
            return xi_tau(dtau_dh(h), lfh)

        return xi_tau_event

    # -- many points at once (the event scan's grids) -------------------------------------
    def xi_batch(self, t: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """``Xi`` at states ``y``, shape (6, k) -> (k,) (:func:`band_xi`)."""
        r, h, lfh = band_values(y, self.r_centre, self.h_max)
        return band_xi(lfh, r, self.r_centre, self.d_bar, self.alpha.vector(h))  # type: ignore[no-any-return]

    def h_batch(self, t: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """``h`` at states ``y``, shape (6, k) -> (k,)."""
        return band_values(y, self.r_centre, self.h_max)[1]  # type: ignore[no-any-return]

    def r_dot_batch(self, t: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        """``r . v`` at states ``y``, shape (6, k) -> (k,)."""
        return y[0] * y[3] + y[1] * y[4] + y[2] * y[5]

    # -- rate bounds (see the class docstring; :func:`band_rate`); states (6,) or (6, k) ----
    def rate(self, kind: int, ya: NDArray[np.float64], yb: NDArray[np.float64], dt: Any, d1: float = 0.0,
             d2: float = 0.0) -> Any:
        """:func:`band_rate` of this band (floats for one interval, arrays for many)."""
        if ya.ndim == 1:
            ya, yb, dt = ya.tolist(), yb.tolist(), float(dt)
        return band_rate(kind, ya, yb, dt, float(self.accel_bound), self.r_inner,  # type: ignore[arg-type]
                         self.r_outer, self.half_width, self.r_centre, self.alpha_slope, self.d_bar, d1, d2)

    def h_rate(self, ya: NDArray[np.float64], yb: NDArray[np.float64], dt: Any) -> Any:
        """Bound on ``|dh/dt| = |LF h|`` [m^2/s] over the interval(s)."""
        return self.rate(H, ya, yb, dt)

    def xi_rate(self, ya: NDArray[np.float64], yb: NDArray[np.float64], dt: Any) -> Any:
        """Bound on ``|dXi/dt|`` [m^2/s^2] over the interval(s)."""
        return self.rate(XI, ya, yb, dt)

    def apsis_rate(self, ya: NDArray[np.float64], yb: NDArray[np.float64], dt: Any) -> Any:
        """Bound on ``|d(r . v)/dt| = |r_dot^2 + r r_ddot|`` [m^2/s^2] over the interval(s)."""
        return self.rate(RDOT, ya, yb, dt)

    def xi_tau_rate(self, d1: float, d2: float) -> RateBound:
        """Rate bound of ``Xi_tau`` given ``|tau_p'| <= d1`` [s/m^2] and ``|tau_p''| <= d2`` [s/m^4]."""

        def rate(ya: NDArray[np.float64], yb: NDArray[np.float64], dt: Any) -> Any:
            return self.rate(XITAU, ya, yb, dt, d1, d2)

        return rate

    def rates(self) -> dict[str, RateBound | None]:
        """The rate bounds by name (``h``, ``xi``, ``apsis``), ``None`` each without ``accel_bound``."""
        if self.accel_bound is None:
            return {"h": None, "xi": None, "apsis": None}
        xi = self.xi_rate if math.isfinite(self.alpha_slope) else None
        return {"h": self.h_rate, "xi": xi, "apsis": self.apsis_rate}
