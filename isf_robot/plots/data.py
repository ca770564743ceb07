"""What the static figures draw: small typed series, checked at construction, and two helpers.

The figures (:mod:`isf_robot.plots.figures`) take these and nothing else, so they know no
engine, no recording format and no satellite model: the command line fills them from
recordings (:mod:`isf_robot.record.figure_data`) or from a tau file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from isf_robot.core import ConfigError

__all__ = ["RunSeries", "StrategyBars", "OrbitSeries", "TauSamples", "on_intervals", "break_gaps",
           "intervention_unit"]


def _vec(name: str, a: object, n: int | None = None, dtype: type = float) -> np.ndarray:
    arr: np.ndarray = np.asarray(a, dtype=dtype).reshape(-1)
    if n is not None and arr.size != n:
        raise ConfigError(f"{name} must have shape ({n},) like t, got ({arr.size},)")
    return arr


def on_intervals(t: np.ndarray, on: np.ndarray, dt: np.ndarray | float) -> list[tuple[float, float]]:
    """Time intervals ``[start, end)`` [s] during which ``on`` holds.

    Step ``k`` covers ``[t[k], t[k] + dt[k])`` (a sampled-data step holds its mode for one
    period), so a run of on-steps ``k..m`` gives ``(t[k], t[m] + dt[m])``.

    Args:
        t: Step times [s], shape (N,), increasing.
        on: Mode per step, shape (N,).
        dt: Step lengths [s], shape (N,) or one number.

    """
    t = np.asarray(t, dtype=float).reshape(-1)
    on = np.asarray(on, dtype=bool).reshape(-1)
    dts = np.broadcast_to(np.asarray(dt, dtype=float), t.shape)
    if on.shape != t.shape:
        raise ConfigError(f"on must have shape ({t.size},) like t, got {on.shape}")
    edges = np.diff(np.concatenate(([False], on, [False])).astype(np.int8))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(float(t[a]), float(t[b] + dts[b])) for a, b in zip(starts, ends)]


def break_gaps(t: np.ndarray, y: np.ndarray, max_gap: float) -> tuple[np.ndarray, np.ndarray]:
    """``(t, y)`` with a NaN row inserted wherever consecutive times are more than ``max_gap`` apart.

    A line plot then stops at each gap instead of joining its two sides with a straight segment.
    """
    t = np.asarray(t, dtype=float).reshape(-1)
    y = np.asarray(y, dtype=float)
    gaps = np.flatnonzero(np.diff(t) > max_gap) + 1
    if not gaps.size:
        return t, y
    nan_row = np.full((gaps.size,) + y.shape[1:], np.nan)
    return np.insert(t, gaps, np.nan), np.insert(y, gaps, nan_row, axis=0)


def intervention_unit(unit: str) -> str:
    """The unit of the intervention ``integral |u - u_nom|^2 dt`` for a command in ``unit``."""
    return {"rad/s": "rad\u00b2/s", "N m": "N\u00b2m\u00b2s"}.get(unit, f"({unit})\u00b2 s")


@dataclass(frozen=True)
class RunSeries:
    """Time series of one arm run.

    Attributes:
        label: Name in legends and titles (e.g. ``"panda_pole isf seed 0"``).
        strategy: Strategy name (``nominal``, ``cbf``, ``isf``).
        t: Control-step times [s], shape (N,).
        dt: Control-step lengths [s], shape (N,).
        h: True-geometry minimum barrier ``min(dist - margin)`` per step [m], shape (N,).
        on: Filter on at the step, shape (N,).
        correction: ``|u - u_nom|`` per step [``unit``], shape (N,).
        xi_t: Times of the ``min Xi_on`` samples [s], shape (M,) (M = 0 without a trigger).
        xi: ``min Xi_on`` (the on trigger fires at ``<= 0``), shape (M,).
        c: The off threshold (the filter turns off at ``Xi_on >= c``); NaN when not applicable.
        unit: The command's unit: ``rad/s`` (joint velocities) or ``N m`` (joint torques, the torque level).

    """

    label: str
    strategy: str
    t: np.ndarray
    dt: np.ndarray
    h: np.ndarray
    on: np.ndarray
    correction: np.ndarray
    xi_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    xi: np.ndarray = field(default_factory=lambda: np.zeros(0))
    c: float = math.nan
    unit: str = "rad/s"

    def __post_init__(self) -> None:
        t = _vec("t", self.t)
        n = t.size
        object.__setattr__(self, "t", t)
        for name in ("dt", "h", "correction"):
            object.__setattr__(self, name, _vec(name, getattr(self, name), n))
        object.__setattr__(self, "on", _vec("on", self.on, n, bool))
        xi_t = _vec("xi_t", self.xi_t)
        object.__setattr__(self, "xi_t", xi_t)
        object.__setattr__(self, "xi", _vec("xi", self.xi, xi_t.size))
        object.__setattr__(self, "c", float(self.c))

    @property
    def intervals(self) -> list[tuple[float, float]]:
        """The on-intervals ``[start, end)`` [s] (:func:`on_intervals`)."""
        return on_intervals(self.t, self.on, self.dt)


@dataclass(frozen=True)
class StrategyBars:
    """Per-episode figures of one strategy (one value per seed), for bars with min-max whiskers.

    Attributes:
        strategy: Strategy name.
        duty_cycle: Fraction of time the filter is on, shape (k,).
        on_switches: Number of off -> on switches, shape (k,).
        intervention: ``sum_k |u_k - u_nom,k|^2 dt_k`` over the run [rad^2/s], shape (k,).
        min_barrier: Smallest true-geometry barrier [m], shape (k,).

    """

    strategy: str
    duty_cycle: np.ndarray
    on_switches: np.ndarray
    intervention: np.ndarray
    min_barrier: np.ndarray

    FIELDS = ("duty_cycle", "on_switches", "intervention", "min_barrier")

    def __post_init__(self) -> None:
        k = _vec("duty_cycle", self.duty_cycle).size
        if k == 0:
            raise ConfigError(f"strategy {self.strategy!r}: no episode")
        for name in self.FIELDS:
            object.__setattr__(self, name, _vec(name, getattr(self, name), k))


@dataclass(frozen=True)
class OrbitSeries:
    """A satellite run: radius, trigger function and impulses.

    Attributes:
        label: Title.
        t_h: Sample times [h], shape (N,).
        r_over_R: Radius over the reference radius, shape (N,).
        band: The safe band's edges ``(inner, outer)`` [R].
        xi_t_h: Times of the ``Xi`` samples [h], shape (M,).
        xi: The greedy trigger function ``Xi`` (an impulse at ``Xi <= 0``), shape (M,).
        impulse_t_h: Impulse times [h], shape (K,).
        impulse_kind: Kind of each impulse (``greedy``, ``first``, ``second``...), shape (K,).

    """

    label: str
    t_h: np.ndarray
    r_over_R: np.ndarray
    band: tuple[float, float]
    xi_t_h: np.ndarray
    xi: np.ndarray
    impulse_t_h: np.ndarray
    impulse_kind: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        t = _vec("t_h", self.t_h)
        object.__setattr__(self, "t_h", t)
        object.__setattr__(self, "r_over_R", _vec("r_over_R", self.r_over_R, t.size))
        xt = _vec("xi_t_h", self.xi_t_h)
        object.__setattr__(self, "xi_t_h", xt)
        object.__setattr__(self, "xi", _vec("xi", self.xi, xt.size))
        it = _vec("impulse_t_h", self.impulse_t_h)
        object.__setattr__(self, "impulse_t_h", it)
        kinds = tuple(str(k) for k in self.impulse_kind) or ("impulse",) * it.size
        if len(kinds) != it.size:
            raise ConfigError(f"impulse_kind must have {it.size} entries like impulse_t_h, got {len(kinds)}")
        object.__setattr__(self, "impulse_kind", kinds)
        lo, hi = (float(v) for v in self.band)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ConfigError(f"band must be (inner, outer) with inner < outer, got {self.band!r}")
        object.__setattr__(self, "band", (lo, hi))


@dataclass(frozen=True)
class TauSamples:
    """Time-to-trigger data of ``isf-satellite tau`` and its fitted ``tau_p``.

    Attributes:
        radii_over_R: Radius grid [R], shape (k,).
        times_h: Times to trigger [h], shape (k, n).
        max_hours: Censoring time [h] (samples at it did not trigger).
        fit_r_over_R: Radii at which the fit is drawn [R], shape (m,).
        fit_tau_h: The fitted ``tau_p`` at those radii [h], shape (m,).
        label: Title.

    """

    radii_over_R: np.ndarray
    times_h: np.ndarray
    max_hours: float
    fit_r_over_R: np.ndarray
    fit_tau_h: np.ndarray
    label: str = "tau_p"

    def __post_init__(self) -> None:
        r = _vec("radii_over_R", self.radii_over_R)
        times = np.asarray(self.times_h, dtype=float)
        if times.ndim != 2 or times.shape[0] != r.size or times.shape[1] < 1:
            raise ConfigError(f"times_h must have shape ({r.size}, n >= 1), got {times.shape}")
        object.__setattr__(self, "radii_over_R", r)
        object.__setattr__(self, "times_h", times)
        fr = _vec("fit_r_over_R", self.fit_r_over_R)
        object.__setattr__(self, "fit_r_over_R", fr)
        object.__setattr__(self, "fit_tau_h", _vec("fit_tau_h", self.fit_tau_h, fr.size))
        object.__setattr__(self, "max_hours", float(self.max_hours))

    @property
    def medians_h(self) -> np.ndarray:
        """Median time to trigger per radius [h], shape (k,)."""
        return np.median(self.times_h, axis=1)
