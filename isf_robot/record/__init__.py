"""The Rerun layer: recorders that subscribe to runs, blueprints, and replay of ``.rrd`` files.

This is the only package that imports ``rerun``. The core never logs: simulation loops call
the :class:`~isf_robot.core.hooks.Observer` hooks, and the recorders here turn them into
buffered ``send_columns`` calls on an explicit :class:`rerun.RecordingStream`.

Public API:

* :func:`open_stream` / :func:`close_stream`: a recording stream to a file and/or a viewer.
* :class:`RerunRecorder`: replay columns, mode, min barrier, events (base of the others).
* :class:`ArmRecorder` (MuJoCo geometry and poses, barriers, commands, witness segments) and
  :class:`SatelliteRecorder` (body, band, trajectory, triggers, impulses).
* :func:`arm_blueprint`, :func:`satellite_blueprint`, :func:`blueprint_for`.
* :func:`read_rrd`, :func:`read_many`, :func:`replay_metrics`, :func:`format_table`,
  :class:`RunLog`.
* :func:`add_recording_args`, :func:`make_observer`: the ``--rrd`` / ``--spawn`` glue.

``ArmRecorder`` imports mujoco, so it is loaded on first use.
"""

from __future__ import annotations

from typing import Any

from .blueprints import arm_blueprint, blueprint_for, generic_blueprint, satellite_blueprint
from .buffer import TIMELINE, Channel, ColumnBuffer, RaggedChannel
from .errors import RecordError, RecordingReadError, ViewerUnavailableError
from .options import add_recording_args, make_observer, recording_path
from .recorder import RerunRecorder
from .replay import METRIC_KEYS, RunLog, format_table, impulse_metrics, read_many, read_rrd, replay_metrics
from .satellite import SatelliteRecorder
from .stream import close_stream, find_viewer, open_stream

__all__ = [
    "TIMELINE", "Channel", "ColumnBuffer", "RaggedChannel",
    "RecordError", "RecordingReadError", "ViewerUnavailableError",
    "add_recording_args", "make_observer", "recording_path",
    "RerunRecorder", "SatelliteRecorder", "ArmRecorder",
    "arm_blueprint", "satellite_blueprint", "generic_blueprint", "blueprint_for",
    "METRIC_KEYS", "RunLog", "format_table", "impulse_metrics", "read_many", "read_rrd", "replay_metrics",
    "close_stream", "find_viewer", "open_stream",
]


def __getattr__(name: str) -> Any:
    if name == "ArmRecorder":
        from .arm import ArmRecorder

        return ArmRecorder
    raise AttributeError(f"module 'isf_robot.record' has no attribute {name!r}")
