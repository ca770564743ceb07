"""The integration loop's pieces: one inter-event arc of the truth flow, and what it records.

The truth flow (spherical harmonics, spinning body) is integrated by ``scipy.integrate.solve_ivp``
(DOP853) once per inter-event arc, with terminal events for the triggers, so every impulse is
applied at a located event and no integration step straddles an impulse. Which events an arc
watches is the trigger policy's business (:mod:`satellite.policies`); here:

* :class:`ArcIntegrator`: integrate one arc, fail loudly on an integrator failure, pass the
  arc to the :class:`Tracker` and (when on) to the surface check;
* :class:`Tracker`: the radius extremes over the step points and every located event (apses
  included, so they are the trajectory's extremes), the right-hand-side count, and the
  samples sent to observers (:class:`SatelliteSample`, at most one per sample interval).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from isf_robot.core import IsfError, Observers
from satellite.model import OrbitModel
from satellite.surface import SurfaceCheck
from satellite.triggers import BandTriggers, EventFn

__all__ = [
    "IntegratorSettings",
    "SatelliteSample",
    "SimulationError",
    "Tracker",
    "ArcIntegrator",
    "event",
    "surface_samples",
]


class SimulationError(IsfError):
    """The integrator failed (e.g. step size underflow)."""


@dataclass(frozen=True)
class IntegratorSettings:
    """``solve_ivp`` settings (SI units).

    Attributes:
        rtol: Relative tolerance.
        atol: Absolute tolerance.
        max_step_s: Largest step [s] (default 1200 s, about 1/20 of the 6.65 h period at 2R).

    """

    rtol: float = 1e-10
    atol: float = 1e-12
    max_step_s: float = 1200.0


@dataclass(frozen=True)
class SatelliteSample:
    """One output sample of a run, passed to ``Observer.on_step``.

    Samples are taken at integrator step points, at most one per ``sample_interval_s``.

    Attributes:
        t: Time [s].
        position: Inertial position [m], length 3.
        velocity: Inertial velocity [m/s], length 3.
        r: Radius [m].
        h: Barrier value [m^2].
        xi: Greedy trigger value ``Xi`` [m^2/s].
        xi_tau: Maneuver trigger value (``nan`` unless in the second phase after the gate).
        phase: ``"none"``, ``"greedy"``, or for maneuvers ``"first"``, ``"second"`` (before the
            gate), ``"second-gated"`` (after it).
        body_angle: Body rotation angle [rad].

    """

    t: float
    position: tuple[float, float, float]
    velocity: tuple[float, float, float]
    r: float
    h: float
    xi: float
    xi_tau: float
    phase: str
    body_angle: float


def event(fn: EventFn, terminal: bool, direction: float) -> EventFn:
    """A ``solve_ivp`` event function calling ``fn(t, y)`` with the given ``terminal``/``direction``."""

    def ev(t: float, y: NDArray[np.float64]) -> float:
        return fn(t, y)

    ev.terminal = terminal  # type: ignore[attr-defined]
    ev.direction = direction  # type: ignore[attr-defined]
    return ev


class Tracker:
    """Running extremes, samples for observers, and bookkeeping of one run.

    Args:
        model: Supplies the body angle of the samples.
        trig: Trigger values of the samples.
        obs: The run's observers (samples are built only when there are some).
        interval: Smallest spacing of the samples [s].

    Attributes:
        r_min: Smallest radius so far [m].
        r_max: Largest radius so far [m].
        nfev: Right-hand-side evaluations so far.

    """

    def __init__(self, model: OrbitModel, trig: BandTriggers, obs: Observers, interval: float) -> None:
        self.model = model
        self.trig = trig
        self.obs = obs
        self.interval = interval
        self.r_min = math.inf
        self.r_max = -math.inf
        self.t_next = 0.0
        self.nfev = 0

    def radius(self, y: NDArray[np.float64]) -> None:
        """Account for one state ``y``, shape (6,)."""
        r = math.sqrt(float(y[0] ** 2 + y[1] ** 2 + y[2] ** 2))
        self.r_min = min(self.r_min, r)
        self.r_max = max(self.r_max, r)

    def arc(self, sol: Any, phase: str, xi_tau: EventFn | None) -> None:
        """Account for one ``solve_ivp`` solution: extremes, evaluations, samples."""
        self.nfev += int(sol.nfev)
        ys = sol.y
        r = np.sqrt(ys[0] ** 2 + ys[1] ** 2 + ys[2] ** 2)
        self.r_min = min(self.r_min, float(r.min()))
        self.r_max = max(self.r_max, float(r.max()))
        for evs in sol.y_events:
            for y in evs:
                self.radius(y)
        if not self.obs:
            return
        for k, t in enumerate(sol.t):
            if t + 1e-9 < self.t_next:
                continue
            self.t_next = t + self.interval
            self.emit(float(t), ys[:, k], phase, xi_tau)

    def emit(self, t: float, y: NDArray[np.float64], phase: str, xi_tau: EventFn | None) -> None:
        """Send the sample at ``(t, y)`` to the observers."""
        r, h, _ = self.trig.parts(y)
        xt = float(xi_tau(t, y)) if xi_tau is not None else math.nan
        self.obs.on_step(
            SatelliteSample(
                t=t,
                position=(float(y[0]), float(y[1]), float(y[2])),
                velocity=(float(y[3]), float(y[4]), float(y[5])),
                r=r,
                h=h,
                xi=self.trig.xi(t, y),
                xi_tau=xt,
                phase=phase,
                body_angle=self.model.body_phase + self.model.omega * t,
            )
        )


def surface_samples(check: SurfaceCheck, sol: Any, t0: float) -> None:
    """Feed one arc to the surface check: grid multiples of its step, events and both ends.

    Args:
        check: The run's surface check.
        sol: ``solve_ivp`` solution with dense output.
        t0: Start of the arc [s].

    """
    t1 = float(sol.t[-1])
    step = check.step_s
    grid = np.arange(math.ceil(t0 / step), math.floor(t1 / step) + 1) * step
    extra = [t0, t1] + [float(x) for ev in sol.t_events for x in ev]
    times = np.unique(np.concatenate([grid, np.asarray(extra)]))
    times = times[(times >= t0) & (times <= t1)]
    check.add(times, sol.sol(times)[:3].T)


class ArcIntegrator:
    """Integrates the truth flow over one arc and records it.

    Args:
        model: Supplies the truth right-hand side.
        settings: ``solve_ivp`` settings.
        track: Records every arc.
        check: Surface check, or ``None`` (off). When on, each arc keeps the integrator's dense
            output (same steps, so the same trajectory) for the check's samples.

    """

    def __init__(
        self, model: OrbitModel, settings: IntegratorSettings, track: Tracker, check: SurfaceCheck | None
    ) -> None:
        self.rhs: Callable[[float, NDArray[np.float64]], NDArray[np.float64]] = model.truth_rhs
        self.settings = settings
        self.track = track
        self.check = check

    def __call__(
        self, t0: float, t1: float, y0: NDArray[np.float64], events: list[EventFn], phase: str,
        xi_tau: EventFn | None,
    ) -> Any:
        """Integrate from ``(t0, y0)`` to ``t1`` [s] or the first terminal event.

        Args:
            t0: Start time [s].
            t1: End time [s].
            y0: Start state, shape (6,).
            events: Event functions (see :func:`event`).
            phase: Phase label of the arc's samples.
            xi_tau: ``Xi_tau`` for the samples, or ``None`` (``nan`` in the samples).

        Returns:
            The ``solve_ivp`` solution (``status`` 1 when a terminal event stopped it).

        Raises:
            SimulationError: The integrator failed.

        """
        s = self.settings
        sol = solve_ivp(
            self.rhs, (t0, t1), y0, method="DOP853", rtol=s.rtol, atol=s.atol,
            max_step=s.max_step_s, events=events, dense_output=self.check is not None,
        )
        if sol.status == -1:
            raise SimulationError(f"integration failed at t = {sol.t[-1] / 3600:.4g} h: {sol.message}")
        self.track.arc(sol, phase, xi_tau)
        if self.check is not None:
            surface_samples(self.check, sol, t0)
        return sol
