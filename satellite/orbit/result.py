"""What a satellite run reports: :class:`RunResult`, the sampled MIET figures, the settings.

Split from :mod:`satellite.orbit.simulate` (which re-exports :class:`RunResult` and
:func:`miet_estimate`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from isf_robot.core import JumpEvent, Linear, estimate_miet_constants, estimate_miet_rate
from satellite.control.controller import ResolvedControl
from satellite.control.triggers import BandTriggers, Trigger
from satellite.gravity.fields import model_name
from satellite.orbit.arcs import IntegratorSettings, Tracker
from satellite.orbit.model import BAND_INNER, BAND_OUTER, InitialOrbit, OrbitModel

__all__ = ["RunResult", "MietReport", "miet_estimate", "contact_report", "run_settings", "surface_barrier_report"]


@dataclass(frozen=True)
class RunResult:
    """Outcome of :func:`simulate`.

    Attributes:
        trigger: The trigger (compares equal to, and serialises as, its name).
        hours: Requested duration [h].
        simulated_h: Duration actually simulated [h] (shorter for ``none`` leaving the band).
        triggers: Number of impulses.
        kinds: Impulse counts by kind (``greedy``, ``safe``, ``tau``, ``periodic``).
        min_xi_tau: Smallest maneuver trigger value ``Xi_tau = (1 + dtau_p/dt) / 2`` over the run where
            the trigger evaluates it (at each gate, and at the step points and located events of the
            arcs after it; between them the event scan watches it), ``None`` for the other triggers
            (and a maneuver run that reached no gate). A ``tau`` impulse fires only where ``Xi_tau <= 0``,
            i.e. ``dtau_p/dt <= -1``: a minimum above 0 means no ``tau`` impulse could fire.
        min_h: Smallest barrier value over the trajectory [m^2].
        r_min_over_R: Smallest radius [R].
        r_max_over_R: Largest radius [R].
        total_dv: Sum of impulse magnitudes [m/s].
        min_inter_event_h: Shortest interval between impulses [h] (``None`` for < 2 impulses).
        mean_inter_event_h: Mean interval between impulses [h] (``None`` for < 2 impulses).
        miet_bound_h: Sampled MIET bound of Proposition 1, ``c / (L_Xi (B + d_bar))`` [h]: the
            largest gradient times the largest flow, sampled apart (vacuous here, kept for the paper).
        miet_estimate_h: Sampled MIET, ``c / sup |dXi/dt|`` with the rate bounded state by state
            (:func:`isf_robot.core.estimate_miet_rate`; see :func:`miet_estimate`) [h]. Compare
            with ``min_inter_event_h``.
        min_interval_s: The practical minimum inter-impulse interval [s] (0: none).
        min_interval_binds: Times ``Xi`` fell to 0 sooner than ``min_interval_s`` after the last
            impulse (the impulse was held; see :mod:`satellite.control.policies`).
        min_interval_overrides: Holds cut short because ``h`` reached the band's edge (the impulse
            fired there, sooner than ``min_interval_s``, so that the satellite stays in the band).
        shooting: The shooting controller's report (:func:`satellite.control.shooting.shooting_report`), or ``None``.
        surface_barrier: Report of the surface-clearance barrier (:func:`surface_barrier_report`),
            ``None`` when off; merged into :meth:`summary` when present.
        left_band_h: First time outside the band [h] (``None`` if it stayed in): the first
            falling zero of ``h``, watched on every arc (scanned between step points unless
            ``IntegratorSettings.event_scan`` is off).
        band_exits: Number of times ``h`` fell through 0 (``none`` stops at the first).
        contact: Surface contact report (see :func:`_contact_report`), ``None`` when off;
            merged into :meth:`summary` when present.
        wall_s: Wall time of the run [s].
        seed: Seed of the initial orbit.
        settings: Resolved settings (JSON-ready).
        events: The impulses.
        nfev: Right-hand-side evaluations.
        surface: Report of the optional surface check (:meth:`satellite.shape.surface_check.SurfaceCheck.report`),
            ``None`` when the check was off; merged into :meth:`summary` when present.

    """

    trigger: Trigger
    hours: float
    simulated_h: float
    triggers: int
    kinds: dict[str, int]
    min_h: float
    r_min_over_R: float
    r_max_over_R: float
    total_dv: float
    min_inter_event_h: float | None
    mean_inter_event_h: float | None
    miet_bound_h: float
    left_band_h: float | None
    wall_s: float
    seed: int
    settings: dict[str, Any]
    events: tuple[JumpEvent, ...] = field(repr=False)
    nfev: int = 0
    surface: dict[str, Any] | None = None
    band_exits: int = 0
    contact: dict[str, Any] | None = None
    miet_estimate_h: float | None = None
    min_interval_s: float = 0.0
    min_interval_binds: int = 0
    min_interval_overrides: int = 0
    shooting: dict[str, Any] | None = None
    surface_barrier: dict[str, Any] | None = None
    min_xi_tau: float | None = None

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary (everything but the event list; the surface keys when checked)."""
        keys = (
            "trigger", "hours", "simulated_h", "triggers", "kinds", "min_xi_tau", "min_h", "r_min_over_R",
            "r_max_over_R", "total_dv", "min_inter_event_h", "mean_inter_event_h", "miet_bound_h",
            "miet_estimate_h", "min_interval_s", "min_interval_binds", "min_interval_overrides",
            "left_band_h", "band_exits", "wall_s", "seed", "nfev", "settings",
        )
        out = {k: getattr(self, k) for k in keys}
        for extra in (self.surface, self.contact, self.shooting, self.surface_barrier):
            if extra is not None:
                out.update(extra)
        return out


@dataclass(frozen=True)
class MietReport:
    """The sampled MIET figures of a run (see :func:`miet_estimate`).

    Attributes:
        bound_s: Proposition 1, ``c / (L_Xi (B + d_bar))`` [s].
        estimate_s: ``c / sup |dXi/dt|``, the rate bounded state by state [s].
        lipschitz_xi: Largest sampled ``|dXi/dx|``.
        rate_bound: Largest sampled ``|dXi/dx F(x)| + |dXi/dv| d_bar`` [m^2/s^2].
        d_flow: Largest sampled disturbance ``|d|`` over the band [m/s^2].

    """

    bound_s: float
    estimate_s: float
    lipschitz_xi: float
    rate_bound: float
    d_flow: float


def miet_estimate(
    model: OrbitModel, resolved: ResolvedControl, samples: int = 2000, seed: int = 0
) -> MietReport:
    """Sampled MIET (paper, Proposition 1) on the band with bounded-orbit speeds, two ways.

    States are drawn with radius uniform in the band, uniform directions, and speeds uniform up
    to the escape speed at 1.6R (a faster satellite is on no bound orbit through the band). The
    flow is the Kepler model and ``d_bar`` the largest sampled non-Kepler acceleration over the
    band (it enters the velocity equation only). Both figures come from the core:
    :func:`isf_robot.core.estimate_miet_constants` (the proposition's product ``L_Xi (B +
    d_bar)``, whose factors peak at different states: ~0.02 s, vacuous) and
    :func:`isf_robot.core.estimate_miet_rate` (``|dXi/dt|`` bounded at each state: the same
    argument, ~10 s at the default gain). Sampled, not proofs: the run reports its measured
    shortest interval beside them.
    """
    rng = np.random.default_rng(seed)
    trig = BandTriggers(model, Linear(resolved.alpha_gain), resolved.d_bar)
    v_max = math.sqrt(2.0 * model.mu / (BAND_INNER * model.R))
    u = rng.normal(size=(samples, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    w = rng.normal(size=(samples, 3))
    w /= np.linalg.norm(w, axis=1)[:, None]
    rad = rng.uniform(BAND_INNER, BAND_OUTER, samples) * model.R
    spd = rng.uniform(0.0, v_max, samples)
    states = np.hstack([u * rad[:, None], w * spd[:, None]])
    d_flow = model.disturbance_bound(samples=samples, seed=seed)

    def xi(x: NDArray[np.float64]) -> float:
        return trig.xi(0.0, x)

    def flow(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return model.kepler_rhs(0.0, x)

    consts = estimate_miet_constants(xi, flow, states, resolved.c, d_flow)
    rate = estimate_miet_rate(xi, flow, states, resolved.c, d_flow, disturbed=(3, 4, 5))
    return MietReport(consts.bound_s, rate.bound_s, consts.lipschitz_xi, rate.rate_bound, d_flow)


def contact_report(mode: str, watch: Any, track: Tracker, stopped: float | None,
                   jumps: Sequence[JumpEvent] = (), simulated_s: float = 0.0) -> dict[str, Any] | None:
    """The contact report of a run (``None`` when off).

    Keys: ``contact_mode``, ``contact_model``, ``surface_contacts`` (passes into the shape),
    ``first_contact_h``, ``contact_stopped`` (the run ended at a contact), ``envelope_passes``
    and ``min_pass_clearance_m`` (smallest radial clearance sampled inside the envelope; < 0 is a
    depth); and the run's physical part, its flight before the first contact (all of it without
    one): ``physical_h`` [h], ``triggers_physical`` and ``total_dv_physical`` [m/s] (the impulses
    before that time).
    """
    if watch is None:
        return None
    clear = track.min_pass_clearance
    end = track.contacts[0] if track.contacts else simulated_s
    before = [float(np.linalg.norm(j.v)) for j in jumps if j.t < end]
    return {
        "contact_mode": mode, "contact_model": watch.surface.name, "surface_contacts": len(track.contacts),
        "first_contact_h": track.contacts[0] / 3600.0 if track.contacts else None,
        "contact_stopped": stopped is not None, "envelope_passes": track.envelope_passes,
        "min_pass_clearance_m": clear if math.isfinite(clear) else None,
        "physical_h": end / 3600.0, "triggers_physical": len(before),
        "total_dv_physical": float(sum(before)),
    }


def run_settings(
    resolved: ResolvedControl, model: OrbitModel, initial: InitialOrbit, integ: IntegratorSettings
) -> dict[str, Any]:
    """The resolved settings reported in :attr:`RunResult.settings` (JSON-ready)."""
    return {
        "alpha_gain": resolved.alpha_gain,
        "c": resolved.c,
        "d_bar": resolved.d_bar,
        "min_post_jump_xi": resolved.min_post_jump_xi,
        "spin": model.spin,
        "spin_period_h": model.spin_period_h,
        "gravity_degree": getattr(model.field, "degree", None),
        "gravity_model": model_name(model.field),
        "disturbance_scale": model.disturbance_scale,
        "R_m": model.R,
        "mu": model.mu,
        "inclination_deg": initial.inclination_deg,
        "radius_over_R": initial.radius_over_R,
        "speed_factor": initial.speed_factor,
        "rtol": integ.rtol,
        "atol": integ.atol,
        "max_step_s": integ.max_step_s,
        "event_scan": integ.event_scan,
        "scan_min_dt_s": integ.scan_min_dt_s,
    }


def surface_barrier_report(sfilter: Any, track: Tracker, fires: int = 0) -> dict[str, Any] | None:
    """The surface barrier's report (``None`` when off).

    Keys: ``surface_barrier`` (the envelope: name, centre, semi-axes, exponent),
    ``surface_clearance_m``, ``surface_c`` [m/s], ``surface_min_h_m`` (smallest ``h_s`` at step
    points and located events; ``Xi_s >= 0`` between impulses keeps it from falling through 0) and
    ``surface_filtered`` (impulses the filter changed from the nominal controller's) and
    ``surface_impulses`` (impulses fired by the surface trigger, ``fires``).
    """
    if sfilter is None:
        return None
    low = track.surface_h_min
    return {
        "surface_barrier": sfilter.surface.envelope.describe(), "surface_clearance_m": sfilter.surface.clearance_m,
        "surface_c": sfilter.c_s, "surface_min_h_m": low if math.isfinite(low) else None,
        "surface_filtered": sfilter.filtered, "surface_impulses": int(fires),
    }
