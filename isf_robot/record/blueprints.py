"""Default viewer layouts: the 3-D view beside the time series of h, Xi and the filter mode.

Each builder returns a :class:`rerun.blueprint.Blueprint`; :func:`blueprint_for` picks one by
recording kind. Recorders send it as the recording's default blueprint, so the viewer opens
on this layout (the user's own layout changes are kept by the viewer).
"""

from __future__ import annotations

import rerun.blueprint as rrb

from .errors import RecordError
from .schema import EVENT_LOG, PLOTS, WORLD

__all__ = ["arm_blueprint", "satellite_blueprint", "generic_blueprint", "blueprint_for"]


def _time_panel() -> rrb.TimePanel:
    return rrb.TimePanel(timeline="sim_time", state="expanded")


def arm_blueprint() -> rrb.Blueprint:
    """Arm layout: scene in 3-D (left); h, Xi_on, mode and commands stacked (right); events below."""
    right = rrb.Vertical(
        rrb.TimeSeriesView(origin=f"{PLOTS}/barrier", name="barrier h [m]"),
        rrb.TimeSeriesView(origin=f"{PLOTS}/xi", name="Xi_on"),
        rrb.TimeSeriesView(origin=f"{PLOTS}/mode", name="filter mode (1 = on)"),
        rrb.TimeSeriesView(origin=f"{PLOTS}/command", name="joint command: nominal vs filtered [rad/s]"),
        row_shares=[3, 2, 1, 3],
    )
    left = rrb.Vertical(
        rrb.Spatial3DView(origin=WORLD, name="scene"),
        rrb.TextLogView(origin=EVENT_LOG, name="switch events"),
        row_shares=[4, 1],
    )
    return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[3, 2]), _time_panel(), collapse_panels=False)


def satellite_blueprint() -> rrb.Blueprint:
    """Satellite layout: body, band and trajectory in 3-D (left); r/R, h, Xi, Xi_tau (right)."""
    right = rrb.Vertical(
        rrb.TimeSeriesView(origin=f"{PLOTS}/radius", name="r / R"),
        rrb.TimeSeriesView(origin=f"{PLOTS}/barrier", name="barrier h"),
        rrb.TimeSeriesView(origin=f"{PLOTS}/xi", name="Xi and Xi_tau"),
        rrb.TimeSeriesView(origin=f"{PLOTS}/mode", name="maneuver phase / impulses"),
        row_shares=[2, 2, 2, 1],
    )
    left = rrb.Vertical(
        rrb.Spatial3DView(origin=WORLD, name="orbit about Itokawa"),
        rrb.TextLogView(origin=EVENT_LOG, name="impulses"),
        row_shares=[4, 1],
    )
    return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[3, 2]), _time_panel(), collapse_panels=False)


def generic_blueprint() -> rrb.Blueprint:
    """Any run: 3-D view beside the barrier, trigger and mode plots."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin=WORLD, name="world"),
            rrb.Vertical(
                rrb.TimeSeriesView(origin=f"{PLOTS}/barrier", name="barrier h"),
                rrb.TimeSeriesView(origin=f"{PLOTS}/xi", name="Xi"),
                rrb.TimeSeriesView(origin=f"{PLOTS}/mode", name="filter mode"),
            ),
        ),
        _time_panel(),
    )


def blueprint_for(kind: str) -> rrb.Blueprint:
    """The default blueprint of a recording kind (``"arm"``, ``"satellite"``, ``"generic"``)."""
    builders = {"arm": arm_blueprint, "satellite": satellite_blueprint, "generic": generic_blueprint}
    try:
        return builders[kind]()
    except KeyError:
        raise RecordError(f"unknown recording kind {kind!r}; valid kinds: {', '.join(sorted(builders))}") from None
