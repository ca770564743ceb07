"""The Pareto figure of a parameter sweep (``isf-robot sweep --plot``, ``isf-robot plot sweep.json``).

One panel per scene: every sweep point at (duty cycle, intervention), coloured by strategy; points
on the sweep's Pareto front (its six objectives, not only these two) are drawn large with a black
edge and labelled; the standard filter (cbf) is the reference, with dotted lines through it. The
shortest off period of the point sets the marker's shape: a circle when every episode's off
periods were >= 0.25 s (not chatter: :data:`~isf_robot.core.metrics.CHATTER_OFF_S`), a cross otherwise.

:func:`sweep_scenes` reads the sweep JSON (schema ``isf-robot-sweep/1``) into plain
:class:`ParetoPoint` lists; :func:`pareto_figure` draws them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from isf_robot.core import ConfigError
from isf_robot.core.metrics import CHATTER_OFF_S

from .figures import strategy_color
from .output import new_figure

__all__ = ["ParetoPoint", "sweep_scenes", "pareto_figure", "POINTS_GID", "MIN_OFF_TARGET_S"]

POINTS_GID = "sweep-points"
"""``gid`` of the scatter artists that hold the sweep points (one offset per point)."""

MIN_OFF_TARGET_S = CHATTER_OFF_S
"""Shortest off period that is not chatter, in every episode [s] (a point below it is drawn as a cross)."""


@dataclass(frozen=True)
class ParetoPoint:
    """One sweep point of one scene, as the figure needs it."""

    label: str
    strategy: str
    duty: float
    intervention: float
    min_off_s: float | None
    pareto: bool


def sweep_scenes(doc: Mapping[str, Any]) -> dict[str, list[ParetoPoint]]:
    """The points per scene of a sweep JSON document; a one-line error for anything else."""
    schema = str(doc.get("schema", ""))
    if not schema.startswith("isf-robot-sweep/"):
        raise ConfigError(f"not a sweep file (schema {schema or 'missing'!r}; valid: isf-robot-sweep/1, "
                          "written by isf-robot sweep --output)")
    out: dict[str, list[ParetoPoint]] = {}
    try:
        for sc in doc["scenes"]:
            pts = []
            for r in sc["points"]:
                if r.get("duty_cycle") is None or r.get("intervention") is None:
                    continue
                pts.append(ParetoPoint(str(r["label"]), str(r["strategy"]), float(r["duty_cycle"]),
                                       float(r["intervention"]), r.get("min_off_all_s"), bool(r.get("pareto"))))
            out[str(sc["scene"])] = pts
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"sweep file is malformed: {exc!r}") from None
    if not any(out.values()):
        raise ConfigError("the sweep file has no finished points to draw")
    return out


def pareto_figure(scenes: Mapping[str, Sequence[ParetoPoint]], title: str | None = None) -> Any:
    """Duty cycle vs intervention per scene (see the module docstring); returns the Figure."""
    names = [n for n, pts in scenes.items() if pts]
    cols = min(3, len(names))
    rows = math.ceil(len(names) / cols)
    fig = new_figure(4.6 * cols, 4.0 * rows)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[len(names):]:
        ax.set_visible(False)
    for ax, name in zip(axes, names):
        pts = scenes[name]
        for strategy in dict.fromkeys(p.strategy for p in pts):
            for front in (False, True):
                for ok in (True, False):
                    sel = [p for p in pts if p.strategy == strategy and p.pareto == front
                           and (p.min_off_s is None or p.min_off_s >= MIN_OFF_TARGET_S) == ok]
                    if not sel:
                        continue
                    ax.scatter([p.duty for p in sel], [p.intervention for p in sel], gid=POINTS_GID,
                               s=70 if front else 28, marker="o" if ok else "X", color=strategy_color(strategy),
                               edgecolors="k" if front else "none", linewidths=1.0, alpha=0.9 if front else 0.5,
                               label=f"{strategy}{' (Pareto front)' if front else ''}"
                                     f"{'' if ok else ', min off < 0.25 s'}", zorder=3 if front else 2)
        for p in pts:
            if p.strategy == "cbf":
                ax.axvline(p.duty, color=strategy_color("cbf"), lw=0.8, ls=":")
                ax.axhline(p.intervention, color=strategy_color("cbf"), lw=0.8, ls=":")
            if p.pareto and p.strategy != "cbf":
                ax.annotate(p.label.removeprefix(p.strategy).strip() or p.strategy, (p.duty, p.intervention),
                            fontsize=6, xytext=(3, 3), textcoords="offset points")
        ax.set_title(name, fontsize=10, loc="left")
        ax.set_xlabel("duty cycle (fraction of time on)")
        ax.set_ylabel(r"intervention $\int |u - u_{nom}|^2$")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or "sweep: duty cycle vs intervention (dotted: cbf; large: Pareto front)", fontsize=10)
    return fig
