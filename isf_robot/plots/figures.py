"""The static figures: a run, a comparison, a satellite run, the tau_p data.

Each function returns a :class:`matplotlib.figure.Figure` (write it with
:func:`isf_robot.plots.output.save_figure`). The filter's on-intervals are shaded orange, the
colour the robot has while the filter is on in the Rerun view and in rendered videos.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from isf_robot.core import ConfigError

from .data import OrbitSeries, RunSeries, StrategyBars, TauSamples, break_gaps, intervention_unit
from .output import new_figure

__all__ = ["run_figure", "compare_figure", "satellite_figure", "tau_figure", "ON_COLOR", "strategy_color"]

ON_COLOR = "#ff8c00"
"""Shade of the on-intervals (the robot's tint while the filter is on)."""
_STRATEGY_COLORS = {"nominal": "#7f7f7f", "cbf": "#1f77b4", "isf": "#d62728"}
_GREY = "#888888"


def strategy_color(name: str) -> str:
    """Colour of a strategy in every figure."""
    return _STRATEGY_COLORS.get(name, "#2ca02c")


def _shade_on(ax: Any, run: RunSeries, label: bool = True) -> None:
    for i, (a, b) in enumerate(run.intervals):
        ax.axvspan(a, b, color=ON_COLOR, alpha=0.25, lw=0, label="filter on" if (label and i == 0) else None)


def _gap(t: np.ndarray) -> float:
    """Largest spacing still drawn as one line: 1.5 median steps."""
    d = np.diff(t)
    return 1.5 * float(np.median(d)) if d.size else math.inf


def _h_axis(ax: Any, run: RunSeries, title: str | None = None) -> None:
    _shade_on(ax, run)
    ax.plot(run.t, run.h, color=strategy_color(run.strategy), lw=1.2, label="min h (true geometry)")
    ax.axhline(0.0, color="k", lw=0.8, ls="--", label="h = 0")
    ax.set_ylabel("min h [m]")
    if title:
        ax.set_title(title, fontsize=10, loc="left")
    ax.grid(alpha=0.3)


def run_figure(run: RunSeries) -> Any:
    """h(t) with the on-intervals shaded; min Xi_on with its thresholds 0 and c; |u - u_nom|.

    Args:
        run: One arm run.

    """
    rows = 3 if run.xi.size else 2
    fig = new_figure(8.0, 2.1 * rows + 0.4)
    axes = fig.subplots(rows, 1, sharex=True)
    _h_axis(axes[0], run, f"{run.label}: duty cycle {np.mean(run.on):.2f}, {len(run.intervals)} on-interval(s)")
    axes[0].legend(loc="upper right", fontsize=8)
    if run.xi.size:
        ax = axes[1]
        _shade_on(ax, run, label=False)
        xt, xv = break_gaps(run.xi_t, run.xi, _gap(run.xi_t))
        ax.plot(xt, xv, color="#1f77b4", lw=1.0, label="min Xi_on")
        ax.axhline(0.0, color="k", lw=0.8, ls="--", label="0: on at or below")
        if math.isfinite(run.c):
            ax.axhline(run.c, color="#2ca02c", lw=0.9, ls="--", label=f"c = {run.c:g}: off at or above")
            hi = max(4.0 * run.c, 0.1)
            finite = xv[np.isfinite(xv)]
            lo = min(float(finite.min()), -run.c) if finite.size else -run.c
            ax.set_ylim(max(lo, -hi) - 0.1 * hi, hi)  # the thresholds stay readable beside large Xi values
        ax.set_ylabel("min Xi_on")
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3)
    ax = axes[-1]
    _shade_on(ax, run, label=False)
    ax.plot(run.t, run.correction, color="#9467bd", lw=1.0)
    ax.set_ylabel(f"|u - u_nom| [{run.unit}]")
    ax.set_xlabel("time [s]")
    ax.grid(alpha=0.3)
    return fig


LABEL_PAD_PT = 3.0
"""Gap [pt] between a bar's value label and the end of its whisker (or of the bar without one)."""


def _bars(ax: Any, bars: Sequence[StrategyBars], name: str, title: str) -> None:
    """Bars of the mean, whiskers of the range, the mean's value written beyond the whisker's cap.

    A label sits above the cap (the largest value) of a bar with a mean >= 0, below the lowest
    value of a bar with a negative mean, :data:`LABEL_PAD_PT` away; the y range leaves room for it.
    """
    x = np.arange(len(bars))
    vals = [np.asarray(getattr(b, name), dtype=float) for b in bars]
    mean = np.array([float(np.mean(v)) for v in vals])
    low = np.array([float(np.min(v)) for v in vals])
    high = np.array([float(np.max(v)) for v in vals])
    err = np.vstack((mean - low, high - mean))
    ax.bar(x, mean, color=[strategy_color(b.strategy) for b in bars], yerr=err if np.any(err) else None,
           capsize=4, width=0.6)
    for xi, m, lo, hi in zip(x, mean, low, high):
        up = m >= 0
        ax.annotate(f"{m:.3g}", (xi, max(hi, m) if up else min(lo, m)), ha="center", va="bottom" if up else "top",
                    fontsize=8, xytext=(0, LABEL_PAD_PT if up else -LABEL_PAD_PT), textcoords="offset points")
    ax.set_xticks(x, [b.strategy for b in bars])
    ax.set_title(title, fontsize=9)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.grid(axis="y", alpha=0.3)
    top, bottom = max(0.0, float(np.max(np.maximum(high, mean)))), min(0.0, float(np.min(np.minimum(low, mean))))
    span = (top - bottom) or max(abs(top), abs(bottom), 1.0)
    room = 0.3 * span  # a label is ~11 pt of an axes of ~150 pt
    below = room if np.any(mean < 0) else 0.05 * span
    above = room if np.any(mean >= 0) else 0.05 * span
    ax.set_ylim(bottom - below, top + above)


def compare_figure(runs: Sequence[RunSeries], bars: Sequence[StrategyBars], title: str = "") -> Any:
    """One h(t) panel per strategy (on-intervals shaded, shared axes) above bars per strategy.

    Args:
        runs: One run per strategy to draw over time (e.g. the first seed of each).
        bars: Figures of every episode per strategy: duty cycle, switches, intervention and
            min h, the mean as the bar and the range over episodes as whiskers.
        title: Figure title.

    """
    if not runs or not bars:
        raise ConfigError("a comparison figure needs at least one run and one strategy")
    units = sorted({run.unit for run in runs})
    if len(units) > 1:
        raise ConfigError(f"the runs' commands have different units ({', '.join(units)}): compare one level at a time")
    n = len(runs)
    fig = new_figure(9.0, 1.6 * n + 2.8)
    grid = fig.add_gridspec(n + 1, 4, height_ratios=[1.0] * n + [1.5])
    first: Any = None
    keyed = next((i for i, run in enumerate(runs) if run.intervals), 0)  # its legend shows the shading too
    for i, run in enumerate(runs):
        ax = fig.add_subplot(grid[i, :], sharex=first, sharey=first)
        first = first or ax
        _h_axis(ax, run, f"{run.label}: duty cycle {np.mean(run.on):.2f}, {len(run.intervals)} on-interval(s)")
        if i == keyed:
            ax.legend(loc="upper right", fontsize=8)
        if i < n - 1:
            ax.tick_params(labelbottom=False)
        else:
            ax.set_xlabel("time [s]")
    k = max(len(b.duty_cycle) for b in bars)
    spec = (("duty_cycle", "duty cycle"), ("on_switches", "on switches"),
            ("intervention", f"intervention \u222b|u \u2212 u_nom|\u00b2 dt [{intervention_unit(runs[0].unit)}]"),
            ("min_barrier", "min h [m]"))
    for j, (name, label) in enumerate(spec):
        _bars(fig.add_subplot(grid[n, j]), bars, name, label)
    if title:
        fig.suptitle(f"{title} ({k} episode(s) per strategy{', whiskers: range' if k > 1 else ''})", fontsize=11)
    return fig


def satellite_figure(orbit: OrbitSeries, hours: float = 150.0) -> Any:
    """The paper's satellite figure: r(t) inside the band, and Xi(t) with a star at each trigger.

    Args:
        orbit: The run.
        hours: Time span drawn from the start [h] (the paper shows the first 150 h).

    """
    if not (math.isfinite(hours) and hours > 0):
        raise ConfigError(f"hours must be a positive number, got {hours}")
    fig = new_figure(8.0, 5.0)
    ax_r, ax_x = fig.subplots(2, 1, sharex=True)
    keep = orbit.t_h <= hours
    lo, hi = orbit.band
    ax_r.axhspan(lo, hi, color="#2ca02c", alpha=0.08, lw=0, label=f"safe band [{lo:g}, {hi:g}] R")
    for edge in orbit.band:
        ax_r.axhline(edge, color="#2ca02c", lw=0.9, ls="--")
    ax_r.plot(orbit.t_h[keep], orbit.r_over_R[keep], color="#1f77b4", lw=0.9, label="r / R")
    ax_r.set_ylim(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo))
    ax_r.set_ylabel("distance r / R")
    ax_r.set_title(orbit.label, fontsize=10, loc="left")
    ax_r.legend(loc="upper right", fontsize=8)
    ax_r.grid(alpha=0.3)
    xkeep = orbit.xi_t_h <= hours
    ax_x.plot(orbit.xi_t_h[xkeep], orbit.xi[xkeep], color="#1f77b4", lw=0.9, label="Xi")
    ax_x.axhline(0.0, color="k", lw=0.8, ls="--")
    ikeep = orbit.impulse_t_h <= hours
    if np.any(ikeep):
        ts = orbit.impulse_t_h[ikeep]
        kinds = np.asarray(orbit.impulse_kind)[ikeep]
        for kind in dict.fromkeys(kinds.tolist()):
            sel = kinds == kind
            ax_x.plot(ts[sel], _xi_at_trigger(orbit, ts[sel], kind), ls="none", marker="*", ms=9,
                      color="#ff8c00" if kind == "tau" else "#d62728", label=f"trigger ({kind})")
    ax_x.set_ylabel("Xi")
    ax_x.set_xlabel("time [h]")
    ax_x.set_xlim(0.0, min(hours, float(orbit.t_h[-1]) if orbit.t_h.size else hours))
    ax_x.legend(loc="upper right", fontsize=8)
    ax_x.grid(alpha=0.3)
    return fig


ZERO_XI_KINDS = ("greedy", "safe", "first")
"""Impulse kinds fired by the greedy condition ``Xi <= 0``: their star sits at ``Xi = 0`` exactly."""


def _xi_at_trigger(orbit: OrbitSeries, ts: np.ndarray, kind: str) -> np.ndarray:
    """Height of the trigger stars: 0 for the greedy condition, else ``Xi`` interpolated between samples."""
    if kind in ZERO_XI_KINDS or not orbit.xi.size:
        return np.zeros(ts.shape)
    return np.interp(ts, orbit.xi_t_h, orbit.xi)


def tau_figure(tau: TauSamples) -> Any:
    """Time to trigger per radius: every sample, the medians and the fitted tau_p."""
    fig = new_figure(7.0, 4.0)
    ax = fig.subplots()
    k, n = tau.times_h.shape
    jitter = np.linspace(-0.006, 0.006, n) if n > 1 else np.zeros(1)
    xs = (tau.radii_over_R[:, None] + jitter[None, :]).ravel()
    ys = tau.times_h.ravel()
    censored = ys >= tau.max_hours
    ax.plot(xs[~censored], ys[~censored], ls="none", marker=".", ms=3, color=_GREY, alpha=0.5,
            label=f"samples ({n} per radius)")
    if np.any(censored):
        ax.plot(xs[censored], ys[censored], ls="none", marker="^", ms=4, color="#9467bd", alpha=0.6,
                label=f"no trigger within {tau.max_hours:g} h")
    ax.plot(tau.radii_over_R, tau.medians_h, ls="none", marker="o", ms=6, color="#1f77b4", label="median")
    ax.plot(tau.fit_r_over_R, tau.fit_tau_h, color="#d62728", lw=1.5, label="fitted tau_p")
    ax.set_xlabel("radius of the impulse r / R")
    ax.set_ylabel("time to trigger [h]")
    ax.set_title(tau.label, fontsize=10, loc="left")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return fig
