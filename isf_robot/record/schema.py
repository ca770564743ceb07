"""Entity paths and replay columns shared by the recorders, the blueprints and the replay reader.

Layout of a recording (every time-varying entity is on the ``sim_time`` timeline, seconds):

``/run/info``, ``/run/summary``
    Static: the run's metadata (``on_start``) and summary (``on_finish``) as JSON strings,
    plus ``kind`` (``"arm"`` or ``"satellite"``).
``/replay/steps``
    One row per control step, exactly the inputs of
    :func:`isf_robot.core.metrics.compute_metrics` in float64/bool: ``t``, ``dt``, ``on``,
    ``intervention_rate`` (``|u - u_nom|^2``), ``qp_solved``, and ``min_barrier`` (the
    true-geometry minimum of that step). Replay recomputes the metrics from these alone.
``/replay/impulses``
    Impulsive runs only: one row per impulse with ``dv`` (``dv_x``, ``dv_y``, ``dv_z``),
    ``h_after``, ``xi_after``, ``interval_s``.
``/replay/terminal``
    Arm runs only, at most one row: ``min_barrier`` of the state after the last step (the
    loop checks it without a step record), logged only when it is the run's minimum.
``/replay/events``
    One row per switch or jump event: ``t``, ``kind``, ``index``, ``xi`` (``Xi`` at the
    event), ``duration_s`` (NaN when undefined).
``/replay/arms/<name>``
    Team runs only (several arms): each arm's replay columns, as :data:`STEPS` with the arm's own
    mode, ``|u_i - u_nom,i|^2`` and QP, and ``min_barrier`` the smallest barrier of the arm's collision
    pairs at the control tick (:mod:`isf_robot.record.team`).
``/arms/<name>/...``
    Team runs only: each arm's time series (mode, ``|u_i - u_nom,i|``, smallest barrier of its pairs).
``/events``
    The same events as a text log.
``/plots/...``
    Time series for the viewer (barrier values, trigger values, mode, commands).
``/world/...``
    3-D content (geometry, poses, witness segments, goals; the satellite's body, band,
    trajectory and impulses).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import rerun as rr

__all__ = [
    "INFO", "SUMMARY", "STEPS", "EVENTS", "EVENT_LOG", "STEP_FIELDS", "EVENT_FIELDS",
    "PLOTS", "WORLD", "IMPULSES", "IMPULSE_FIELDS", "TERMINAL", "ARMS", "ARM_STEPS",
    "arm_path", "run_level", "command_unit",
]

INFO = "/run/info"
SUMMARY = "/run/summary"
STEPS = "/replay/steps"
EVENTS = "/replay/events"
IMPULSES = "/replay/impulses"
TERMINAL = "/replay/terminal"
EVENT_LOG = "/events"
PLOTS = "/plots"
WORLD = "/world"
ARMS = "/arms"
ARM_STEPS = "/replay/arms"

STEP_FIELDS: tuple[str, ...] = ("t", "dt", "on", "intervention_rate", "qp_solved", "min_barrier")
"""Columns of :data:`STEPS`, in order."""

EVENT_FIELDS: tuple[str, ...] = ("t", "kind", "index", "xi", "duration_s")
"""Columns of :data:`EVENTS`, in order."""

IMPULSE_FIELDS: tuple[str, ...] = (
    "t", "kind", "index", "dv_x", "dv_y", "dv_z", "h_after", "xi_after", "interval_s",
)
"""Columns of :data:`IMPULSES` (impulsive runs), in order."""


def arm_path(root: str, name: str) -> str:
    """``<root>/<name>`` with an arm's name escaped as one entity path part (a team's per-arm entities)."""
    return f"{root}/{rr.escape_entity_path_part(str(name))}"


def run_level(info: Mapping[str, Any]) -> str:
    """What an arm run's filter commanded, from its run info: ``velocity`` or ``torque`` (the info's ``level``)."""
    return str(info.get("level") or "velocity")


def command_unit(info: Mapping[str, Any]) -> str:
    """The unit of an arm run's commands, from its run info: ``N m`` at the torque level, else ``rad/s``."""
    return "N m" if run_level(info) == "torque" else "rad/s"
