"""Default viewer layouts: the 3-D view beside the time series of h, Xi and the filter mode.

Each builder returns a :class:`rerun.blueprint.Blueprint`; :func:`blueprint_for` picks one by
recording kind. Recorders send it as the recording's default blueprint, so the viewer opens
on this layout (the user's own layout changes are kept by the viewer). Once a run starts, the
arm recorder sends the arm layout again with the camera framed on the arm's workspace (a file
alone gets only that one: :func:`~isf_robot.record.options.open_recorder`)
(:func:`arm_blueprint` with ``eye``), and the satellite recorder sends its layout with the
time axes spanning the whole run (:func:`satellite_blueprint` with ``duration_s``).

:func:`team_blueprint` is the arm layout of a team run (several arms): the team's barrier and ``Xi_on``
plots above a tab per arm (its mode, the smallest barrier of its pairs, its correction).

:func:`compare_blueprint` lays the recordings of one ``compare`` side by side: one column per
strategy (barrier, mode, command correction), for recordings opened together in one viewer.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import rerun.blueprint as rrb

from .errors import RecordError
from .schema import ARMS, EVENT_LOG, PLOTS, WORLD, arm_path

__all__ = ["arm_blueprint", "team_blueprint", "satellite_blueprint", "generic_blueprint", "blueprint_for",
           "compare_blueprint", "camera_for"]

TIMELINE = "sim_time"


def _time_panel() -> rrb.TimePanel:
    return rrb.TimePanel(timeline=TIMELINE, state="expanded")


def _whole_run(duration_s: float | None) -> dict[str, object]:
    """TimeSeriesView arguments: all data visible, the x axis spanning ``[0, duration_s]``."""
    out: dict[str, object] = {"time_ranges": [rrb.VisibleTimeRange(
        TIMELINE, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())]}
    if duration_s is not None and np.isfinite(duration_s) and duration_s > 0:
        out["axis_x"] = rrb.TimeAxis(view_range=rrb.components.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seconds=0.0),
            end=rrb.TimeRangeBoundary.absolute(seconds=float(duration_s))))
    return out


def xi_range(c: float | None) -> tuple[float, float] | None:
    """Value range of the ``Xi_on`` plot: ``(-2c, 6c)`` for a finite ``c > 0``, else ``None`` (automatic)."""
    if c is None or not np.isfinite(c) or c <= 0:
        return None
    return (-2.0 * float(c), 6.0 * float(c))


def _xi_axis(c: float | None) -> dict[str, object]:
    r = xi_range(c)
    return {} if r is None else {"axis_y": rrb.ScalarAxis(range=r)}


def camera_for(centre: Sequence[float], radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Eye position and look target framing a sphere (z up): from the front right, above.

    The eye is ``1.5 radius`` from the target, which sits a third of the radius above the centre.
    """
    c = np.asarray(centre, dtype=float).reshape(3)
    target = c + np.array([0.0, 0.0, radius / 3.0])
    direction = np.array([1.0, -0.8, 0.6])
    eye = target + 1.5 * radius * direction / np.linalg.norm(direction)
    return eye, target


def arm_blueprint(eye: Sequence[float] | None = None, target: Sequence[float] | None = None,
                  duration_s: float | None = None, c: float | None = None, unit: str = "rad/s") -> rrb.Blueprint:
    """Arm layout: scene in 3-D (left); h, Xi_on, mode and command correction stacked (right).

    Args:
        eye: Camera position [m] (default: the viewer's own framing of everything).
        target: Point the camera looks at [m].
        duration_s: The run's length: the plots' time axes span it.
        c: The off margin: the ``Xi_on`` plot's value axis starts at ``[-2c, 6c]`` (:func:`xi_range`),
            so its thresholds 0 and ``c`` stay apart however large ``Xi_on`` gets far from obstacles.
        unit: The command's unit (``rad/s``; ``N m`` at the torque level).

    """
    eye_controls = None
    if eye is not None and target is not None:
        eye_controls = rrb.EyeControls3D(position=list(map(float, eye)), look_target=list(map(float, target)),
                                         eye_up=[0.0, 0.0, 1.0])
    span = _whole_run(duration_s)
    right = rrb.Vertical(
        rrb.TimeSeriesView(origin=f"{PLOTS}/barrier", name="barrier h [m] (closest pairs, min)", **span),
        rrb.TimeSeriesView(origin=f"{PLOTS}/xi", name="min Xi_on with 0 and c", **span, **_xi_axis(c)),
        rrb.TimeSeriesView(origin=f"{PLOTS}/mode", name="filter mode (1 = on)", **span),
        rrb.Tabs(
            rrb.TimeSeriesView(origin=f"{PLOTS}/command", name=f"|u - u_nom| [{unit}]", **span),
            rrb.TimeSeriesView(origin=f"{PLOTS}/joints/correction", name=f"u - u_nom per joint [{unit}]", **span),
            rrb.TimeSeriesView(origin=f"{PLOTS}/joints/command", name=f"u and u_nom per joint [{unit}]", **span),
        ),
        row_shares=[3, 2, 1, 2],
    )
    left = rrb.Vertical(
        rrb.Spatial3DView(origin=WORLD, name="scene (robot orange while the filter is on)",
                          eye_controls=eye_controls),
        rrb.TextLogView(origin=EVENT_LOG, name="switch events"),
        row_shares=[4, 1],
    )
    return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[3, 2]), _time_panel(), collapse_panels=False)


def team_blueprint(arms: Sequence[str], eye: Sequence[float] | None = None, target: Sequence[float] | None = None,
                   duration_s: float | None = None, c: float | None = None) -> rrb.Blueprint:
    """Team layout (several arms): the scene in 3-D (left); the team's h and Xi_on, then a tab per arm (right).

    Each arm's tab stacks its filter mode, the smallest barrier of its collision pairs and ``|u_i - u_nom,i|``
    (``/arms/<name>/...``, :mod:`isf_robot.record.team`). Arguments as :func:`arm_blueprint`.
    """
    if not arms:
        raise RecordError("team_blueprint needs at least one arm")
    eye_controls = None
    if eye is not None and target is not None:
        eye_controls = rrb.EyeControls3D(position=list(map(float, eye)), look_target=list(map(float, target)),
                                         eye_up=[0.0, 0.0, 1.0])
    span = _whole_run(duration_s)
    tabs = []
    for name in arms:
        base = arm_path(ARMS, name)
        tabs.append(rrb.Vertical(
            rrb.TimeSeriesView(origin=f"{base}/mode", name=f"{name}: filter mode (1 = on)", **span),
            rrb.TimeSeriesView(origin=f"{base}/barrier_min", name=f"{name}: min h of its pairs [m]", **span),
            rrb.TimeSeriesView(origin=f"{base}/correction_norm", name=f"{name}: |u - u_nom| [rad/s]", **span),
            row_shares=[1, 2, 2], name=str(name),
        ))
    right = rrb.Vertical(
        rrb.TimeSeriesView(origin=f"{PLOTS}/barrier", name="team: barrier h [m] (closest pairs, min)", **span),
        rrb.TimeSeriesView(origin=f"{PLOTS}/xi", name="team: min Xi_on with 0 and c", **span, **_xi_axis(c)),
        rrb.Tabs(*tabs, name="per arm"),
        row_shares=[2, 1, 4],
    )
    left = rrb.Vertical(
        rrb.Spatial3DView(origin=WORLD, name="scene (robots orange while a filter is on)", eye_controls=eye_controls),
        rrb.TextLogView(origin=EVENT_LOG, name="switch events"),
        row_shares=[4, 1],
    )
    return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[3, 2]), _time_panel(), collapse_panels=False)


def satellite_blueprint(duration_s: float | None = None) -> rrb.Blueprint:
    """Satellite layout: body, band and trajectory in 3-D (left); r/R, h, Xi, impulses (right).

    Args:
        duration_s: The run's length [s]: every plot's time axis spans ``[0, duration_s]``.

    """
    span = _whole_run(duration_s)
    right = rrb.Vertical(
        rrb.TimeSeriesView(origin=f"{PLOTS}/radius", name="r / R with the band 1.6 .. 2.4", **span),
        rrb.TimeSeriesView(origin=f"{PLOTS}/barrier", name="barrier h", **span),
        rrb.TimeSeriesView(origin=f"{PLOTS}/xi", name="Xi and Xi_tau", **span),
        rrb.TimeSeriesView(origin=f"{PLOTS}/impulses", name="impulses |dv| [m/s] and maneuver phase", **span),
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


def compare_blueprint(strategies: Sequence[str], *, root: str = "/compare", unit: str = "rad/s") -> rrb.Blueprint:
    """Strategies of one seed side by side: a column per strategy (barrier, mode, correction in ``unit``).

    The views read ``<root>/<strategy>/plots/...``: :func:`isf_robot.record.compare.merge_runs`
    copies each per-run recording's plots there, in one recording.
    """
    if not strategies:
        raise RecordError("compare_blueprint needs at least one strategy")
    cols = []
    for s in strategies:
        base = f"{root}/{s}{PLOTS}"
        cols.append(rrb.Vertical(
            rrb.TimeSeriesView(origin=f"{base}/barrier", name=f"{s}: barrier h [m]"),
            rrb.TimeSeriesView(origin=f"{base}/mode", name=f"{s}: filter mode"),
            rrb.TimeSeriesView(origin=f"{base}/command", name=f"{s}: |u - u_nom| [{unit}]"),
            row_shares=[3, 1, 2], name=s,
        ))
    return rrb.Blueprint(rrb.Horizontal(*cols), _time_panel(), collapse_panels=False)


def blueprint_for(kind: str) -> rrb.Blueprint:
    """The default blueprint of a recording kind (``"arm"``, ``"satellite"``, ``"generic"``)."""
    builders = {"arm": arm_blueprint, "satellite": satellite_blueprint, "generic": generic_blueprint}
    try:
        return builders[kind]()
    except KeyError:
        raise RecordError(f"unknown recording kind {kind!r}; valid kinds: {', '.join(sorted(builders))}") from None
