"""Chatter of an intermittent filter: off periods under :data:`~isf_robot.core.metrics.CHATTER_OFF_S`, and the fix.

An intermittent filter that turns off and is needed again within a fraction of a second gains
nothing over the standard filter and adds a hand-over at every switch. :func:`chatter_risk` says,
from the parameters alone, when a filter has no means against it; :func:`chatter_advice` says, after
a run, how much it chattered and which parameter change would stop it. Both answer with one line
that names the scene-file key and the flag.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from .metrics import CHATTER_OFF_S
from .spec import FilterSpec

__all__ = ["chatter_advice", "chatter_risk", "horizon_for"]


def horizon_for(predict_every: int, period: float) -> float:
    """The shortest predictive horizon [s] that keeps off periods above the chatter threshold.

    ``CHATTER_OFF_S + predict_every * period``: the filter turns off only when the nominal, rolled
    forward this long, keeps every ``Xi_on > 0``; the horizon covers the shortest off period that is
    not chatter and the control steps between two rollouts (``period`` [s] each).

    Not longer: while the prediction holds the filter on, the rows it finds failing are promoted
    even when they are far, and a pair pushed out to the broad phase's cut-off leaves the filter's
    rows and comes back, so the command alternates between the promoted one and the nominal. The
    longer the horizon, the more often that happens (``RESULTS.md``, "designed, not tuned").
    """
    return CHATTER_OFF_S + predict_every * period


def _up(x: float) -> float:
    """``x`` rounded up to 0.05 (a value a user types)."""
    return math.ceil(x / 0.05 - 1e-9) * 0.05


def _fix(spec: FilterSpec, need: float) -> str:
    """The change that would stop chatter, given the rule's horizon ``need`` [s]."""
    h = spec.horizon or 0.0
    if h < need:
        what = "turn on the predictive off trigger" if h == 0 else f"lengthen the predictive horizon (now {h:g} s)"
        v = _up(need)
        return f"{what}: horizon = {v:g} (--horizon {v:g})"
    v = _up(max(1.5 * h, need))
    return (f"design the off margin: min_off = {CHATTER_OFF_S:g} (--min-off {CHATTER_OFF_S:g}), or lengthen the "
            f"predictive horizon (now {h:g} s; a longer one costs tracking error): horizon = {v:g} (--horizon {v:g})")


def chatter_risk(spec: FilterSpec, period: float) -> str | None:
    """Why an intermittent filter with ``spec`` at control period ``period`` [s] may chatter, or ``None``.

    ``None`` when a predictive horizon of at least :func:`horizon_for` or a designed off margin
    (``min_off >= CHATTER_OFF_S``) guards against it.
    """
    need = horizon_for(spec.predict_every, period)
    if (spec.horizon or 0.0) >= need - 1e-12 or spec.min_off >= CHATTER_OFF_S:
        return None
    return (f"nothing keeps the intermittent filter's off periods above {CHATTER_OFF_S:g} s, so it may chatter; "
            + _fix(spec, need))


def chatter_advice(metrics: Mapping[str, Any], spec: FilterSpec, period: float) -> str | None:
    """One line on a run's chatter (its ``short_offs`` and ``min_off_s``) with the fix, or ``None`` when it had none."""
    n = metrics.get("short_offs") or 0
    if not n:
        return None
    shortest = metrics.get("min_off_s")
    at = f" (shortest {shortest:.3f} s)" if shortest is not None else ""
    return (f"chatter: {n:g} off period{'s' if n != 1 else ''} under {CHATTER_OFF_S:g} s{at}; "
            + _fix(spec, horizon_for(spec.predict_every, period)))
