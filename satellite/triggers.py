"""The satellite's triggers: the registry of choices and the trigger values.

* :class:`Trigger`: the one definition of the choices ``none | greedy | maneuver`` (the CLI's
  ``--trigger`` values, :func:`satellite.simulate.simulate`'s argument, ``RunResult.trigger``).
* :class:`BandTriggers`: the trigger values for the band barrier in plain floats, for the
  integrator's event functions. The formulas are the core's: ``Xi`` is
  :func:`isf_robot.core.triggers.xi_on_scalar` with no input term (eq. greedy_cond) and
  ``Xi_tau`` is :func:`isf_robot.core.xi_tau` (eq. trigger:int_time); only the band's Lie data
  are computed here: ``h = (0.4R)^2 - (r - 2R)^2``, ``LF h = -2 (r - 2R) r_dot`` along the Kepler
  flow and ``|dh/dx| = 2 |r - 2R|``.

What each trigger does during a run is its policy, :mod:`satellite.policies`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from isf_robot.core import ClassK, UnknownNameError, xi_tau
from isf_robot.core.triggers import xi_on_scalar
from satellite.model import OrbitModel

__all__ = ["Trigger", "TRIGGERS", "BandTriggers", "EventFn"]

EventFn = Callable[[float, NDArray[np.float64]], float]
"""An event function ``g(t, y)`` of ``solve_ivp``."""


class Trigger(str, Enum):
    """When the safeguarding controller fires (compares and serialises as its name)."""

    NONE = "none"
    GREEDY = "greedy"
    MANEUVER = "maneuver"

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
        """Whether the trigger needs a fitted ``tau_p`` (:class:`satellite.tau.TauFit`)."""
        return self is Trigger.MANEUVER

    @property
    def description(self) -> str:
        """One line for help texts."""
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    Trigger.NONE: "no control: the run stops when the satellite leaves the band",
    Trigger.GREEDY: "an impulse whenever Xi reaches 0",
    Trigger.MANEUVER: "two-impulse maneuvers timed by a fitted tau_p (needs --tau)",
}

TRIGGERS: tuple[str, ...] = tuple(t.value for t in Trigger)
"""Trigger names, in definition order."""


class BandTriggers:
    """Band-barrier trigger values in plain floats, for the integrator's event functions.

    Same values as :meth:`EventTriggeredImpulsiveController.xi` and
    :meth:`ManeuverScheduler.xi_tau` for the band barrier and the Kepler flow (a test checks it),
    through the core's scalar formulas and without array work.

    Args:
        model: Supplies R.
        alpha: Class-K function [m^2/s per m^2].
        d_bar: Disturbance bound [m/s^2].

    """

    def __init__(self, model: OrbitModel, alpha: ClassK, d_bar: float) -> None:
        self.r_centre = model.r_centre
        self.h_max = model.h_max
        self.alpha = alpha
        self.d_bar = d_bar

    def parts(self, y: NDArray[np.float64]) -> tuple[float, float, float]:
        """Return ``(r [m], h [m^2], LF h [m^2/s])`` at state ``y``, shape (6,)."""
        px, py, pz, vx, vy, vz = y.tolist()
        r = math.sqrt(px * px + py * py + pz * pz)
        dr = r - self.r_centre
        return r, self.h_max - dr * dr, -2.0 * dr * (px * vx + py * vy + pz * vz) / r

    def xi(self, t: float, y: NDArray[np.float64]) -> float:
        """Greedy trigger ``Xi`` [m^2/s] (core :func:`~isf_robot.core.triggers.xi_on_scalar`)."""
        r, h, lfh = self.parts(y)
        return xi_on_scalar(lfh, 0.0, 2.0 * abs(r - self.r_centre), h, self.alpha, self.d_bar)

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
