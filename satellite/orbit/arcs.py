"""The integration loop's pieces: one inter-event arc of the truth flow, and what it records.

The truth flow (spinning body) is integrated by :func:`satellite.orbit.events.integrate` (DOP853
steps, as ``solve_ivp``) once per inter-event arc, with terminal events for the triggers, so
every impulse is applied at a located event and no integration step straddles an impulse; events
with a rate bound are scanned inside every step, so a crossing between step points is not
missed. Which events an arc watches is the trigger policy's business (:mod:`satellite.control.policies`);
here:

* :class:`ArcIntegrator`: integrate one arc, fail loudly on an integrator failure, watch every
  arc for band exits (``h`` falling through 0, non-terminal: the run goes on and reports them),
  pass the arc to the :class:`Tracker` and (when on) to the surface check;
* :class:`Tracker`: the radius extremes over the step points and every located event (apses
  included, so they are the trajectory's extremes), the band exits, the right-hand-side count,
  and the samples sent to observers (:class:`SatelliteSample`, at most one per sample interval).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from isf_robot.core import IsfError, Observers
from satellite.control.contact import ContactWatch
from satellite.control.triggers import CONTACT, BandTriggers, EventFn
from satellite.orbit.events import Event, IntegrationFailed, event, integrate
from satellite.orbit.fast_arcs import FastArcs
from satellite.orbit.model import OrbitModel
from satellite.shape.surface_check import SurfaceCheck

__all__ = [
    "IntegratorSettings",
    "SatelliteSample",
    "SimulationError",
    "Tracker",
    "ArcIntegrator",
    "Event",
    "event",
    "surface_samples",
]


class SimulationError(IsfError):
    """The integrator failed (e.g. step size underflow)."""


@dataclass(frozen=True)
class IntegratorSettings:
    """Integrator settings (SI units).

    Attributes:
        rtol: Relative tolerance.
        atol: Absolute tolerance.
        max_step_s: Largest step [s] (default 1200 s, about 1/20 of the 6.65 h period at 2R).
        event_scan: Scan every step for crossings between step points (rate bounds; see
            :mod:`satellite.orbit.events`). ``False`` sees events at step points only, as ``solve_ivp``.
        scan_min_dt_s: Shortest interval the scan splits [s].

    """

    rtol: float = 1e-10
    atol: float = 1e-12
    max_step_s: float = 1200.0
    event_scan: bool = True
    scan_min_dt_s: float = 1e-2


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
        scan_points: Interior points evaluated by the event scan so far.
        band_exits: Times [s] at which ``h`` fell through 0.
        contacts: Times [s] of surface contacts (first entry of each pass into the shape).
        envelope_passes: Passes inside the contact envelope (necessary for contact).
        min_pass_clearance: Smallest radial clearance [m] sampled during those passes.
        surface_h: ``h_s`` of the surface barrier at many states, ``(t (k,), y (6, k)) -> (k,)``, or
            ``None`` (no surface barrier).
        surface_h_min: Smallest ``h_s`` at step points and located events [m].
        xi_tau_min: Smallest ``Xi_tau`` where the maneuver trigger evaluates it: at each gate and at
            the step points and located events of the arcs after it (``inf`` before any).

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
        self.scan_points = 0
        self.band_exits: list[float] = []
        self.contacts: list[float] = []
        self.envelope_passes = 0
        self.min_pass_clearance = math.inf
        self.surface_h: Callable[[Any, NDArray[np.float64]], NDArray[np.float64]] | None = None
        self.surface_h_min = math.inf
        self.xi_tau_min = math.inf

    def note_xi_tau(self, value: float) -> None:
        """Account for one value of ``Xi_tau`` (the maneuver trigger's test at a gate)."""
        self.xi_tau_min = min(self.xi_tau_min, float(value))

    def radius(self, y: NDArray[np.float64]) -> None:
        """Account for one state ``y``, shape (6,)."""
        r = math.sqrt(float(y[0] ** 2 + y[1] ** 2 + y[2] ** 2))
        self.r_min = min(self.r_min, r)
        self.r_max = max(self.r_max, r)

    def arc(self, sol: Any, phase: str, xi_tau: EventFn | None) -> None:
        """Account for one ``solve_ivp`` solution: extremes, evaluations, ``Xi_tau``'s minimum, samples."""
        self.nfev += int(sol.nfev)
        self.scan_points += int(getattr(sol, "scan_points", 0))
        ys = sol.y
        r = np.sqrt(ys[0] ** 2 + ys[1] ** 2 + ys[2] ** 2)
        self.r_min = min(self.r_min, float(r.min()))
        self.r_max = max(self.r_max, float(r.max()))
        for evs in sol.y_events:
            for y in evs:
                self.radius(y)
        if self.surface_h is not None:  # the surface barrier's smallest value at step points and events
            self.surface_h_min = min(self.surface_h_min, float(self.surface_h(sol.t, ys).min()))
            for te, evs in zip(sol.t_events, sol.y_events):
                if len(te):
                    self.surface_h_min = min(self.surface_h_min, float(self.surface_h(te, evs.T).min()))
        if xi_tau is not None:  # the maneuver trigger's smallest value at step points and events
            for k, t in enumerate(sol.t):
                self.note_xi_tau(xi_tau(float(t), ys[:, k]))
            for te, evs in zip(sol.t_events, sol.y_events):
                for t, y in zip(te, evs):
                    self.note_xi_tau(xi_tau(float(t), y))
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
        sol: Arc solution with dense output (:class:`satellite.orbit.events.ArcSolution`).
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
        settings: Integrator settings.
        track: Records every arc.
        check: Surface check, or ``None`` (off). When on, each arc keeps the integrator's dense
            output (same steps, so the same trajectory) for the check's samples.
        exit_watch: The band-exit event (``h`` falling, non-terminal) added to every arc, or
            ``None``.
        contact: The surface contact watch, or ``None`` (surface ignored).
        contact_stop: End the run at the first contact (else count contacts and go on).

    Attributes:
        stopped: Time [s] of the contact that ended the run, else ``None``.

    """

    def __init__(
        self, model: OrbitModel, settings: IntegratorSettings, track: Tracker, check: SurfaceCheck | None,
        exit_watch: Event | None = None, contact: ContactWatch | None = None, contact_stop: bool = False,
    ) -> None:
        self.rhs: Callable[[float, NDArray[np.float64]], NDArray[np.float64]] = model.truth_rhs
        self.settings = settings
        self.track = track
        self.check = check
        self.exit_watch = exit_watch
        self.contact = contact
        self.contact_stop = contact_stop
        self.stopped: float | None = None
        self._contact_ev = (event(contact.g, False, 0.0, contact.rate, contact.batch, (CONTACT, 0.0, None))
                            if contact is not None else None)
        self.fast = FastArcs.make(model, track.trig, contact)
        self._in_contact = False
        self._in_env = False

    def __call__(
        self, t0: float, t1: float, y0: NDArray[np.float64], events: list[Event], phase: str,
        xi_tau: EventFn | None,
    ) -> Any:
        """Integrate from ``(t0, y0)`` to ``t1`` [s] or the first terminal event.

        Args:
            t0: Start time [s].
            t1: End time [s].
            y0: Start state, shape (6,).
            events: Events (see :func:`satellite.orbit.events.event`); their rate bounds are dropped
                when the settings turn the scan off.
            phase: Phase label of the arc's samples.
            xi_tau: ``Xi_tau`` for the samples, or ``None`` (``nan`` in the samples).

        Returns:
            The :class:`satellite.orbit.events.ArcSolution` (``status`` 1 when a terminal event
            stopped it), with the caller's events only.

        Raises:
            SimulationError: The integrator failed.

        """
        s = self.settings
        extra = [w for w in (self.exit_watch, self._contact_ev) if w is not None]
        watched = list(events) + extra
        dense = self.check is not None or self.contact is not None
        try:
            sol = None
            if self.fast is not None:
                sol = self.fast.integrate(t0, t1, y0, watched, rtol=s.rtol, atol=s.atol, max_step=s.max_step_s,
                                          dense=dense, min_dt=s.scan_min_dt_s, scan=s.event_scan)
            if sol is None:
                if not s.event_scan:
                    watched = [event(e.fn, e.terminal, e.direction) for e in watched]
                sol = integrate(self.rhs, t0, t1, y0, watched, rtol=s.rtol, atol=s.atol, max_step=s.max_step_s,
                                dense=dense, min_dt=s.scan_min_dt_s)
        except IntegrationFailed as exc:
            raise SimulationError(f"integration failed at t = {exc.t / 3600:.4g} h: {exc}") from None
        if self._contact_ev is not None:
            sol.y_events.pop()
            self._contacts(sol, t0, y0, sol.t_events.pop())
        if self.exit_watch is not None:
            self.track.band_exits.extend(float(t) for t in sol.t_events.pop() if t <= sol.t[-1])
            sol.y_events.pop()
        self.track.arc(sol, phase, xi_tau)
        if self.check is not None:
            surface_samples(self.check, sol, t0)
        return sol

    def _contacts(self, sol: Any, t0: float, y0: NDArray[np.float64], crossings: NDArray[np.float64]) -> None:
        """Check the arc's passes inside the envelope; count contacts; truncate the arc at a stop.

        A pass or a contact that goes on across an impulse (the position is continuous) counts once.
        """
        c = self.contact
        assert c is not None
        t1 = float(sol.t[-1])
        for a, b in c.passes(t0, t1, c.g(t0, y0), crossings):
            continued = a == t0
            tc, clear = c.first_contact(sol.sol, a, b)
            self.track.min_pass_clearance = min(self.track.min_pass_clearance, clear)
            self.track.envelope_passes += 0 if continued and self._in_env else 1
            if tc is not None and not (tc == t0 and self._in_contact):
                self.track.contacts.append(tc)
                if self.contact_stop:
                    self.stopped = tc
                    _truncate(sol, tc)
                    return
        y1 = sol.y[:, -1]
        self._in_env = c.g(t1, y1) < 0.0
        # outside the envelope is outside the shape: the exact inside test only within it
        self._in_contact = self._in_env and bool(c.surface.inside(c.body_point(t1, y1)))


def _truncate(sol: Any, tc: float) -> None:
    """Cut an arc solution at ``tc`` [s] (a contact that ends the run): no later points or events."""
    keep = sol.t < tc
    y_end = np.asarray(sol.sol(tc), dtype=float)
    sol.t = np.append(sol.t[keep], tc)
    sol.y = np.column_stack([sol.y[:, keep], y_end])
    for i, te in enumerate(sol.t_events):
        m = te <= tc
        sol.t_events[i] = te[m]
        sol.y_events[i] = sol.y_events[i][m]
    sol.status = 2
