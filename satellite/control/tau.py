"""Inter-event time data and the fitted ``tau_p(h)`` (paper, Section IV-B, Fig. fit).

Data: for each radius of a grid across the band and ``N`` random states per radius, apply the
safeguarding controller once, propagate the truth model until the greedy trigger fires
(``Xi <= 0``) and record the elapsed time. A random state has a direction uniform on the sphere,
an orbital plane through it with uniform orientation (the pre-jump velocity only fixes the plane;
the controller sets the speed), and a uniform body rotation phase. A run that has not
triggered after ``max_hours`` is recorded as ``max_hours`` (censored; the count is kept).
The statistic per radius is the median (as in the paper).

Fit: ``h = (0.4R)^2 - (r - 2R)^2`` takes each value at two radii (``2R -+ delta``); all medians
are fitted together by least squares with a polynomial in ``s = h / h_max`` of degree
``degree`` (default 2), ``tau_p(h) = sum_k a_k s^k`` [s], whose derivative
``dtau_p/dh = (sum_k k a_k s^(k-1)) / h_max`` [s / m^2] is exact. Outside ``[0, h_max]`` the
polynomial is extended linearly from the nearest end (``h`` slightly below 0 can occur within the
event tolerance).
"""

from __future__ import annotations

import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from satellite.compiled import inlined
from satellite.control.controller import ControlParams, make_controller, resolve_control
from satellite.control.triggers import BandTriggers
from satellite.errors import SatelliteError
from satellite.gravity.fields import DEFAULT_GRAVITY, load_field
from satellite.orbit.model import BAND_INNER, BAND_OUTER, OrbitModel

__all__ = [
    "tau_slope",
    "TAU_FORMAT",
    "DEFAULT_RADII",
    "TauFileError",
    "TauData",
    "TauFit",
    "collect_tau",
    "fit_tau",
    "load_tau",
    "check_tau_controller",
    "time_to_trigger",
]

TAU_FORMAT = "isf-satellite-tau/1"
"""Value of the ``format`` key of a tau file."""

DEFAULT_RADII: tuple[float, ...] = tuple(round(BAND_INNER + 0.05 * k, 10) for k in range(17))
"""Default radius grid [R]: 1.60, 1.65, ..., 2.40."""


class TauFileError(SatelliteError):
    """A tau file is missing, unreadable, or not an ``isf-satellite tau`` output."""


@dataclass(frozen=True)
class TauData:
    """Time-to-trigger samples.

    Attributes:
        radii_over_R: Grid [R], shape (k,).
        times_h: Times to trigger [h], shape (k, N).
        max_hours: Censoring time [h].
        seed: Seed of the random states.
        spin: Whether the body turned.
        wall_s: Wall time of the collection [s].
        workers: Processes used.
        disturbance_scale: Factor on the non-Kepler gravity (see :class:`OrbitModel`).

    """

    radii_over_R: NDArray[np.float64]
    times_h: NDArray[np.float64]
    max_hours: float
    seed: int
    spin: bool
    wall_s: float
    workers: int
    disturbance_scale: float = 1.0

    @property
    def medians_h(self) -> NDArray[np.float64]:
        """Median time to trigger per radius [h], shape (k,)."""
        return np.median(self.times_h, axis=1)

    @property
    def censored(self) -> NDArray[np.int64]:
        """Number of samples per radius that reached ``max_hours`` without a trigger."""
        return np.sum(self.times_h >= self.max_hours, axis=1)


@inlined
def tau_slope(tp: Any, h: float) -> float:
    """``d tau_p / d h`` [s/m^2] at ``h`` [m^2] of a packed fit (:attr:`TauFit.packed`); ``s = h / h_max`` in [0, 1]."""
    hm = tp[2]
    s = min(max(h / hm, 0.0), 1.0)
    acc = 0.0
    for m in range(len(tp) - 1, 2, -1):
        acc = acc * s + tp[m]
    return acc / hm  # type: ignore[no-any-return]


class TauFit:
    """``tau_p(h)`` as a polynomial in ``s = h / h_max``.

    Args:
        coef_s: Coefficients ``a_k`` [s], lowest degree first.
        h_max: ``(0.4 R)^2`` [m^2], > 0.

    """

    def __init__(self, coef_s: list[float] | NDArray[np.float64], h_max: float) -> None:
        c = np.asarray(coef_s, dtype=float)
        if c.ndim != 1 or c.size < 1 or not np.all(np.isfinite(c)):
            raise TauFileError("tau fit coefficients must be a non-empty list of finite numbers")
        if not (math.isfinite(h_max) and h_max > 0.0):
            raise TauFileError(f"tau fit h_max must be positive, got {h_max}")
        self.coef = [float(v) for v in c]
        self.h_max = float(h_max)
        self._dcoef = [k * self.coef[k] for k in range(1, len(self.coef))]
        d1 = sum(k * abs(a) for k, a in enumerate(self.coef)) / self.h_max
        d2 = sum(k * (k - 1) * abs(a) for k, a in enumerate(self.coef)) / self.h_max**2
        self.slope_bounds = (d1, d2)
        """``(d1, d2)``: ``|tau_p'| <= d1`` [s/m^2] and ``|tau_p''| <= d2`` [s/m^4] on ``s`` in [0, 1]."""
        self._tp = [d1, d2, self.h_max, *(self._dcoef or [0.0])]
        self.packed = np.array(self._tp, dtype=np.float64)
        """``d1, d2, h_max`` and the coefficients of ``d tau_p / d s``, lowest degree first (:func:`tau_slope`)."""
        self.controller: str | None = None  # the safeguarding controller of the data (set by load_tau)

    def _poly(self, s: float) -> float:
        acc = 0.0
        for a in reversed(self.coef):
            acc = acc * s + a
        return acc

    def _dpoly(self, s: float) -> float:
        acc = 0.0
        for a in reversed(self._dcoef):
            acc = acc * s + a
        return acc  # (the tangent continuation of tau_p; the slope the trigger uses is tau_slope's)

    def tau_p(self, h: float) -> float:
        """Expected inter-event time [s] after an impulse at barrier value ``h`` [m^2]."""
        s = h / self.h_max
        if s < 0.0:
            return self._poly(0.0) + self._dpoly(0.0) * s
        if s > 1.0:
            return self._poly(1.0) + self._dpoly(1.0) * (s - 1.0)
        return self._poly(s)

    def dtau_dh(self, h: float) -> float:
        """``d tau_p / d h`` [s / m^2] (:func:`tau_slope`)."""
        return tau_slope(self._tp, h)

    def describe(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {"basis": "polynomial in s = h / h_max, tau_p in seconds", "coef_s": self.coef, "h_max": self.h_max}


def distinct_h_levels(radii_over_R: Any) -> int:
    """Distinct values of ``h`` over the radii (``r`` and ``4R - r`` give the same ``h``)."""
    return int(np.unique(np.round(np.abs(np.asarray(radii_over_R, dtype=float) - 2.0), 9)).size)


def fit_tau(data: TauData, h_max: float, R: float, degree: int = 2) -> TauFit:
    """Least-squares polynomial fit of the per-radius medians against ``s = h / h_max``.

    Args:
        data: Samples.
        h_max: ``(0.4 R)^2`` [m^2].
        R: Reference radius [m].
        degree: Polynomial degree, >= 1.

    """
    if degree < 1:
        raise SatelliteError(f"fit degree must be >= 1, got {degree}")
    r = data.radii_over_R * R
    s = (h_max - (r - 2.0 * R) ** 2) / h_max
    distinct = distinct_h_levels(data.radii_over_R)
    if degree >= distinct:
        raise SatelliteError(f"fit degree {degree} needs at least {degree + 1} distinct barrier levels; the "
                             f"radii give {distinct} (r and 4R - r share h), so the degree must be <= {distinct - 1}")
    coef = np.polynomial.polynomial.polyfit(s, data.medians_h * 3600.0, degree)
    return TauFit(np.asarray(coef, dtype=float), h_max)


_FIELD_CACHE: dict[Any, Any] = {}


def _worker_model(spin: bool, phase: float, scale: float = 1.0, gravity: str = DEFAULT_GRAVITY) -> OrbitModel:
    field = _FIELD_CACHE.get(("field", gravity))
    if field is None:

        field = _FIELD_CACHE[("field", gravity)] = load_field(gravity)
    return OrbitModel(field, spin=spin, body_phase=phase, disturbance_scale=scale)


def time_to_trigger(
    radius_over_R: float,
    seed: tuple[int, ...],
    *,
    spin: bool = True,
    control: ControlParams | None = None,
    max_hours: float = 100.0,
    disturbance_scale: float = 1.0,
    gravity: str = DEFAULT_GRAVITY,
) -> float:
    """Time [h] from one controller impulse at a random state of radius ``radius_over_R`` to the trigger.

    Args:
        radius_over_R: Radius [R].
        seed: Entropy for the random direction, plane and body phase.
        spin: Body spin.
        control: Trigger settings.
        max_hours: Censoring time [h].
        disturbance_scale: Factor on the non-Kepler gravity.
        gravity: Truth gravity model name (:func:`satellite.gravity.fields.load_field`).

    """
    rng = np.random.default_rng(list(seed))
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    w = rng.normal(size=3)
    w -= (w @ u) * u
    w /= np.linalg.norm(w)
    phase = float(rng.uniform(0.0, 2.0 * math.pi))
    model = _worker_model(spin, phase, disturbance_scale, gravity)
    key = ("resolved", control)
    resolved = _FIELD_CACHE.get(key)
    if resolved is None:
        resolved = _FIELD_CACHE[key] = resolve_control(model, control)
    ctrl = make_controller(model, resolved)
    r = radius_over_R * model.R
    x = np.concatenate([r * u, math.sqrt(model.mu / r) * w])
    y = ctrl.apply_jump(0.0, x, "greedy").x_after
    trig = BandTriggers(model, ctrl.alpha, resolved.d_bar)

    def ev(t: float, yy: NDArray[np.float64]) -> float:
        return trig.xi(t, yy)

    ev.terminal = True  # type: ignore[attr-defined]
    ev.direction = -1.0  # type: ignore[attr-defined]
    from scipy.integrate import solve_ivp  # here: a run that needs no tau data skips the import

    sol = solve_ivp(
        model.truth_rhs, (0.0, max_hours * 3600.0), y, method="DOP853", rtol=1e-10, atol=1e-12,
        max_step=1200.0, events=[ev],
    )
    if sol.status == 1:
        return float(sol.t_events[0][0]) / 3600.0
    return float(max_hours)


def _task(args: tuple[Any, ...]) -> tuple[int, list[float]]:
    radius, index, seed, sample_ids, spin, control, max_hours, scale, gravity = args
    out = [
        time_to_trigger(
            radius, (seed, index, j), spin=spin, control=control, max_hours=max_hours, disturbance_scale=scale,
            gravity=gravity,
        )
        for j in sample_ids
    ]
    return index, out


def collect_tau(
    samples: int = 100,
    *,
    radii_over_R: tuple[float, ...] = DEFAULT_RADII,
    seed: int = 0,
    workers: int | None = None,
    spin: bool = True,
    control: ControlParams | None = None,
    max_hours: float = 100.0,
    chunk: int = 10,
    disturbance_scale: float = 1.0,
    gravity: str = DEFAULT_GRAVITY,
) -> TauData:
    """Collect time-to-trigger samples over the radius grid, in parallel processes.

    Results do not depend on ``workers`` or ``chunk`` (each sample has its own seed).

    Args:
        samples: States per radius, >= 1.
        radii_over_R: Radius grid [R], each inside the band.
        seed: Base seed.
        workers: Processes (default ``os.cpu_count()``; 1 runs in this process).
        spin: Body spin.
        control: Trigger settings.
        max_hours: Censoring time [h], > 0.
        chunk: Samples per task.
        disturbance_scale: Factor on the non-Kepler gravity.
        gravity: Truth gravity model name (:func:`satellite.gravity.fields.load_field`; default the
            tabulated exact field, as the command line; ``"sh8"``: the paper's degree-8 series).

    """
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise SatelliteError(f"samples must be a positive integer, got {samples!r}")
    if not radii_over_R or any(not (BAND_INNER <= r <= BAND_OUTER) for r in radii_over_R):
        raise SatelliteError(f"radii must lie in [{BAND_INNER}, {BAND_OUTER}] R, got {radii_over_R}")
    if not (math.isfinite(max_hours) and max_hours > 0):
        raise SatelliteError(f"max_hours must be positive, got {max_hours}")
    workers = workers or os.cpu_count() or 1
    if workers < 1:
        raise SatelliteError(f"workers must be >= 1, got {workers}")
    wall0 = time.perf_counter()
    tasks = []
    for i, rad in enumerate(radii_over_R):
        for start in range(0, samples, chunk):
            ids = list(range(start, min(samples, start + chunk)))
            tasks.append((float(rad), i, int(seed), ids, spin, control, float(max_hours), float(disturbance_scale),
                          gravity))
    times = np.zeros((len(radii_over_R), samples))
    if workers == 1:
        results = map(_task, tasks)
        for (_, _, _, ids, *_), (i, vals) in zip(tasks, results):
            times[i, ids] = vals
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for (_, _, _, ids, *_), (i, vals) in zip(tasks, pool.map(_task, tasks)):
                times[i, ids] = vals
    return TauData(
        np.asarray(radii_over_R, dtype=float), times, float(max_hours), int(seed), bool(spin),
        time.perf_counter() - wall0, int(workers), float(disturbance_scale),
    )


def tau_document(data: TauData, fit: TauFit, settings: dict[str, Any]) -> dict[str, Any]:
    """JSON document written by ``isf-satellite tau``."""
    return {
        "format": TAU_FORMAT,
        "samples": int(data.times_h.shape[1]),
        "seed": data.seed,
        "spin": data.spin,
        "disturbance_scale": data.disturbance_scale,
        "max_hours": data.max_hours,
        "radii_over_R": data.radii_over_R.tolist(),
        "h_over_h_max": [1.0 - ((r - 2.0) / 0.4) ** 2 for r in data.radii_over_R.tolist()],
        "median_h": data.medians_h.tolist(),
        "censored": data.censored.tolist(),
        "times_h": data.times_h.tolist(),
        "fit": fit.describe(),
        "settings": settings,
        "wall_s": data.wall_s,
        "workers": data.workers,
    }


def check_tau_controller(tau: Any, controller: str) -> None:
    """Refuse a ``tau_p`` fit made with another safeguarding controller than the run's (``None`` passes).

    Raises:
        ConfigError: The fit's ``controller`` (set by :func:`load_tau`) differs from ``controller``.

    """
    made = getattr(tau, "controller", None)
    if made is not None and made != controller:
        raise SatelliteError(f"the tau_p fit was made with the {made} controller but the run uses {controller}; "
                             f"fit one with `isf-satellite tau --controller {controller}`")


def load_tau(path: str | Path) -> TauFit:
    """Read the fit from a file written by ``isf-satellite tau``.

    Raises:
        TauFileError: Missing file, invalid JSON, or not a tau file.

    """
    p = Path(path)
    if not p.is_file():
        raise TauFileError(f"tau file not found: {p}")
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise TauFileError(f"{p}: not a tau file (invalid JSON: {exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != TAU_FORMAT:
        raise TauFileError(
            f"{p}: not a tau file (expected \"format\": \"{TAU_FORMAT}\"; make one with `isf-satellite tau`)"
        )
    fit = doc.get("fit")
    if not isinstance(fit, dict) or "coef_s" not in fit or "h_max" not in fit:
        raise TauFileError(f"{p}: tau file lacks fit.coef_s / fit.h_max")
    try:
        out = TauFit(fit["coef_s"], float(fit["h_max"]))
    except (TypeError, ValueError) as exc:
        raise TauFileError(f"{p}: bad tau fit ({exc})") from None
    settings = doc.get("settings")
    out.controller = str(settings.get("controller", "kepler")) if isinstance(settings, dict) else "kepler"
    return out
