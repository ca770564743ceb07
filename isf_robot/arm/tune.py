"""Choosing an intermittent filter's parameters from a sweep of one scene, and writing them down.

``isf-robot sweep --model ARM.xml --config ARM.toml ... --write-config FILE.toml`` runs the sweep on
the user's arm, then :func:`choose_point` picks one intermittent point and :func:`filter_section`
writes it as a ``[filter]`` table to paste into the scene file, with the evidence beside it (the
sweep as JSON and its Pareto table).

The choice, among the intermittent points on the Pareto front (:func:`isf_robot.arm.sweep.pareto_front`):

1. keep the points that meet the safety and chatter targets: no violation on the true geometry,
   no complete off period under :data:`~isf_robot.core.metrics.CHATTER_OFF_S` in any episode, and
   as many goals as the standard filter (``cbf``, when the sweep ran it) within 0.1;
2. of those, the lowest duty cycle, then the fewest on-switches, then the least intervention.

When no point meets every target, the point that misses fewest of them (then the same order) is
chosen and the section names what it misses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from isf_robot.core.metrics import CHATTER_OFF_S
from isf_robot.core.strategies import strategy_info

__all__ = ["GOALS_SLACK", "choose_point", "filter_section", "missed_targets"]

GOALS_SLACK = 0.1
"""How many fewer goals (mean over episodes) than the standard filter a chosen point may reach."""


def missed_targets(row: Mapping[str, Any], cbf: Mapping[str, Any] | None) -> list[str]:
    """The targets a sweep point (a row of one scene's ``points``) misses, in words; empty when it meets all."""
    out = []
    if row.get("violations"):
        out.append(f"{row['violations']} violation step(s)")
    off = row.get("min_off_all_s")
    if off is not None and off < CHATTER_OFF_S:
        out.append(f"an off period of {off:.3f} s (< {CHATTER_OFF_S:g} s: chatter)")
    if cbf is not None and row.get("goals_reached") is not None and cbf.get("goals_reached") is not None:
        if row["goals_reached"] < cbf["goals_reached"] - GOALS_SLACK:
            out.append(f"{row['goals_reached']:.2f} goals against cbf's {cbf['goals_reached']:.2f}")
    return out


def _order(row: Mapping[str, Any]) -> tuple[float, float, float]:
    def v(key: str) -> float:
        x = row.get(key)
        return math.inf if x is None else float(x)

    return v("duty_cycle"), v("on_switches"), v("intervention")


def choose_point(scene: Mapping[str, Any]) -> tuple[Mapping[str, Any], list[str]]:
    """The chosen intermittent point of one scene of a sweep, and the targets it misses (see the module docstring).

    Raises:
        ValueError: The sweep has no intermittent point with an episode.

    """
    points: Sequence[Mapping[str, Any]] = scene["points"]
    cbf = next((r for r in points if r["strategy"] == "cbf"), None)
    cands = [r for r in points if strategy_info(r["strategy"]).intermittent and r.get("episodes")]
    if not cands:
        raise ValueError(f"scene {scene['scene']}: the sweep has no intermittent point to choose from "
                         "(give --filters with an intermittent strategy, e.g. isf)")
    front = [r for r in cands if r.get("pareto")] or cands
    best = min(front, key=lambda r: (len(missed_targets(r, cbf)), *_order(r)))
    return best, missed_targets(best, cbf)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    return "inf" if v == math.inf else repr(float(v))


def filter_section(scene: Mapping[str, Any], seeds: Sequence[int], evidence: str) -> str:
    """The ``[filter]`` table of the chosen point of ``scene`` (a scene of a sweep), with the figures as comments.

    ``evidence``: where the sweep's JSON and table are (named in the header).
    """
    row, missed = choose_point(scene)
    cbf = next((r for r in scene["points"] if r["strategy"] == "cbf"), None)
    ratio = row.get("vs_cbf") or {}

    def fig(key: str, fmt: str) -> str:
        x = row.get(key)
        return "-" if x is None else format(x, fmt)

    lines = [
        f"# Chosen by `isf-robot sweep --write-config` for scene {scene['scene']}: point {row['label']} of "
        f"{len(scene['points'])}, {len(seeds)} seed(s) ({seeds[0]}..{seeds[-1]}); evidence: {evidence}.",
        f"# duty {fig('duty_cycle', '.3f')}, switches {fig('on_switches', '.1f')}, shortest off period "
        f"{fig('min_off_all_s', '.3f')} s, intervention {fig('intervention', '.3f')}, goals "
        f"{fig('goals_reached', '.2f')}, violations {row.get('violations', 0)}",
    ]
    if cbf is not None:
        lines.append("# against cbf on the same seeds: duty x" + _fmt(ratio.get("duty_cycle"))
                     + ", switches x" + _fmt(ratio.get("on_switches")) + ", intervention x"
                     + _fmt(ratio.get("intervention")) + f", goals {cbf.get('goals_reached', 0):.2f} for cbf")
    lines.append("# meets every target (no violation, no off period under 0.25 s, cbf's goals)" if not missed
                 else "# MISSES: " + "; ".join(missed) + " (no point of the sweep met every target)")
    lines.append("# Keys not named here keep the scene file's values (blend and horizon: designed from [gains]).")
    lines.append("[filter]")
    values = dict(row.get("values", {}))
    if "d_bar" in row and row.get("d_bar") is not None:
        values.setdefault("d_bar", row["d_bar"])
    for k, v in values.items():
        lines.append(f"{k} = {_toml_value(int(v) if k == 'predict_every' else v)}")
    return "\n".join(lines) + "\n"


def _fmt(x: Any) -> str:
    return "-" if x is None else f"{x:.2f}"
