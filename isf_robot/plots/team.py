"""Figures of arms sharing a workspace: one team run per arm, and each arm's figures per way of filtering.

* :func:`team_run_figure`: the team's ``min h`` (true geometry) with its on-intervals shaded, then a row
  per arm: the smallest barrier of the arm's pairs with the arm's own on-intervals shaded, and
  ``|u_i - u_nom,i|`` over its own joints.
* :func:`team_compare_figure`: per way of filtering (``cbf/central``, ``isf/decentral``, ...), grouped bars
  of each arm's duty cycle, on switches, intervention and shortest off period (the chatter line
  :data:`CHATTER_S` drawn), the mean over episodes as the bar and the range as whiskers.

They take :class:`~isf_robot.plots.data.RunSeries` (one per arm, and the team's) and :class:`TeamBars`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from isf_robot.core import ConfigError
from isf_robot.core.metrics import CHATTER_OFF_S

from .data import RunSeries
from .figures import _h_axis, _shade_on, strategy_color
from .output import new_figure

__all__ = ["TeamBars", "team_run_figure", "team_compare_figure", "CHATTER_S"]

CHATTER_S = CHATTER_OFF_S
"""An off period shorter than this counts as chatter (the issue's target: each arm's shortest off >= 0.25 s)."""

ARM_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#17becf")


@dataclass(frozen=True)
class TeamBars:
    """Each arm's figures over episodes for one way of filtering a team.

    Attributes:
        group: Its name, ``<strategy>/<coordination>`` (or ``nominal``).
        arms: The arms' names, length a.
        duty_cycle: Each episode's duty cycle per arm, shape (k, a).
        on_switches: Off -> on switches, shape (k, a).
        intervention: ``sum |u_i - u_nom,i|^2 dt`` over the arm's joints [rad^2/s], shape (k, a).
        min_off_s: Shortest off period [s], shape (k, a) (NaN: no off period ended).

    """

    group: str
    arms: tuple[str, ...]
    duty_cycle: np.ndarray
    on_switches: np.ndarray
    intervention: np.ndarray
    min_off_s: np.ndarray

    FIELDS = ("duty_cycle", "on_switches", "intervention", "min_off_s")

    def __post_init__(self) -> None:
        arms = tuple(str(a) for a in self.arms)
        if not arms:
            raise ConfigError(f"{self.group!r}: a team needs at least one arm")
        object.__setattr__(self, "arms", arms)
        shape: tuple[int, ...] | None = None
        for name in self.FIELDS:
            v = np.asarray(getattr(self, name), dtype=float)
            v = v.reshape(1, -1) if v.ndim == 1 and v.size == len(arms) else v  # (one episode)
            if v.ndim != 2 or v.shape[1] != len(arms) or v.shape[0] == 0:
                raise ConfigError(f"{self.group!r}: {name} must have shape (episodes, {len(arms)}), got {v.shape}")
            if shape is not None and v.shape != shape:
                raise ConfigError(f"{self.group!r}: {name} has shape {v.shape}, duty_cycle {shape}")
            shape = v.shape
            object.__setattr__(self, name, v)

    @property
    def strategy(self) -> str:
        """The strategy of the group (before the ``/``)."""
        return self.group.split("/", 1)[0]


def _arm_title(name: str, run: RunSeries) -> str:
    return f"{name}: duty cycle {np.mean(run.on):.2f}, {len(run.intervals)} on-interval(s)"


def team_run_figure(team: RunSeries, arms: Sequence[RunSeries], names: Sequence[str]) -> Any:
    """The team's ``min h`` above a row per arm (its pairs' ``min h``; ``|u_i - u_nom,i|``), on-intervals shaded.

    Args:
        team: The team's series (``h`` the true-geometry minimum over every pair, ``on`` any filter on).
        arms: Each arm's series (``h`` the smallest barrier of its pairs, ``on`` its own filter's mode,
            ``correction`` over its own joints).
        names: The arms' names.

    """
    if not arms or len(arms) != len(names):
        raise ConfigError(f"a team figure needs one series per arm, got {len(arms)} for {len(names)} arm(s)")
    n = len(arms)
    fig = new_figure(10.0, 1.9 * (n + 1) + 0.4)
    grid = fig.add_gridspec(n + 1, 2, width_ratios=[3, 2])
    top = fig.add_subplot(grid[0, :])
    _h_axis(top, team, f"{team.label}: team duty cycle {np.mean(team.on):.2f} (a filter on)")
    top.legend(loc="upper right", fontsize=8)
    first_c: Any = None
    for i, (name, run) in enumerate(zip(names, arms)):
        color = ARM_COLORS[i % len(ARM_COLORS)]
        ax = fig.add_subplot(grid[i + 1, 0], sharex=top)
        _shade_on(ax, run, label=False)
        ax.plot(run.t, run.h, color=color, lw=1.2)
        ax.axhline(0.0, color="k", lw=0.8, ls="--")
        ax.set_ylabel(f"{name}\nmin h [m]")
        ax.set_title(_arm_title(name, run), fontsize=9, loc="left")
        ax.grid(alpha=0.3)
        axc = fig.add_subplot(grid[i + 1, 1], sharex=top, sharey=first_c)
        first_c = first_c or axc
        _shade_on(axc, run, label=False)
        axc.plot(run.t, run.correction, color=color, lw=1.0)
        axc.set_ylabel("|u - u_nom| [rad/s]")
        axc.grid(alpha=0.3)
        if i == n - 1:
            ax.set_xlabel("time [s]")
            axc.set_xlabel("time [s]")
    fig.suptitle("each arm: the smallest barrier of its pairs at the control ticks (left) and its correction "
                 "(right), shaded while its own filter is on", fontsize=9)
    return fig


def team_compare_figure(bars: Sequence[TeamBars], title: str = "") -> Any:
    """Grouped bars per way of filtering: each arm's duty cycle, on switches, intervention, shortest off.

    Bars are means over episodes with the range as whiskers, except the shortest off period: the
    smallest over the episodes (the chatter target), with a line at :data:`CHATTER_S`.
    """
    if not bars:
        raise ConfigError("a team comparison needs at least one way of filtering")
    arms = bars[0].arms
    if any(b.arms != arms for b in bars):
        raise ConfigError("a team comparison draws one team: the recordings' arms differ ("
                          + "; ".join(sorted({", ".join(b.arms) for b in bars})) + ")")
    fig = new_figure(11.0, 6.2)
    axes = fig.subplots(2, 2).ravel()
    spec = (("duty_cycle", "duty cycle"), ("on_switches", "on switches"),
            ("intervention", "intervention \u222b|u \u2212 u_nom|\u00b2 dt [rad\u00b2/s]"),
            ("min_off_s", f"shortest off period [s] (chatter below {CHATTER_S:g} s; none: no off period ended)"))
    x = np.arange(len(bars))
    width = 0.8 / len(arms)
    for ax, (name, label) in zip(axes, spec):
        for j, arm in enumerate(arms):
            vals = [np.asarray(getattr(b, name), dtype=float)[:, j] for b in bars]
            if name == "min_off_s":
                mean = np.array([float(np.nanmin(v)) if np.isfinite(v).any() else math.nan for v in vals])
                err = None
            else:
                mean = np.array([float(np.mean(v)) for v in vals])
                lo = np.array([float(np.min(v)) for v in vals])
                hi = np.array([float(np.max(v)) for v in vals])
                err = np.vstack((mean - lo, hi - mean))
                err = err if np.any(err) else None
            xs = x - 0.4 + width * (j + 0.5)
            ax.bar(xs, np.nan_to_num(mean), width=width * 0.9, yerr=err, capsize=3,
                   color=ARM_COLORS[j % len(ARM_COLORS)], label=arm)
            for xv, m in zip(xs, mean):
                ax.annotate("none" if not math.isfinite(m) else f"{m:.3g}", (xv, 0 if not math.isfinite(m) else m),
                            ha="center", va="bottom", fontsize=7, xytext=(0, 2), textcoords="offset points")
        if name == "min_off_s":
            ax.axhline(CHATTER_S, color="#d62728", lw=0.9, ls="--", label=f"{CHATTER_S:g} s")
        ax.set_xticks(x, [b.group for b in bars], fontsize=8)
        for tick, b in zip(ax.get_xticklabels(), bars):
            tick.set_color(strategy_color(b.strategy))
        ax.set_title(label, fontsize=9)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.grid(axis="y", alpha=0.3)
        top = ax.get_ylim()[1]
        ax.set_ylim(top=top * 1.15 if top > 0 else 1.0)
    axes[0].legend(fontsize=8, title="arm", title_fontsize=8)
    axes[3].legend(fontsize=8, loc="upper right")
    k = max(b.duty_cycle.shape[0] for b in bars)
    if title:
        fig.suptitle(f"{title} ({k} episode(s) per way{', whiskers: range' if k > 1 else ''})", fontsize=11)
    return fig
