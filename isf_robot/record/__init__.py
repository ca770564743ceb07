"""The Rerun layer: recorders that subscribe to runs, blueprints, and replay of ``.rrd`` files.

This is the only package that imports ``rerun``. The core never logs: simulation loops call
the :class:`~isf_robot.core.hooks.Observer` hooks, and the recorders here turn them into
buffered ``send_columns`` calls on an explicit :class:`rerun.RecordingStream`.

Public API:

* :func:`open_stream` / :func:`close_stream`: a recording stream to a file and/or a viewer.
* :class:`RerunRecorder`: replay columns, mode, min barrier, events (base of the others).
* :class:`ArmRecorder` (MuJoCo geometry and poses, barriers, commands, witness segments) and
  :class:`SatelliteRecorder` (body, band, trajectory, triggers, impulses).
* :class:`PerRunRecorder`: one recording file per run (picklable; for ``compare``).
* :func:`arm_blueprint`, :func:`team_blueprint`, :func:`satellite_blueprint`, :func:`blueprint_for`.
* :func:`read_rrd`, :func:`read_many`, :func:`replay_metrics`, :func:`arm_metrics` (each arm of a team
  recording), :func:`format_table`, :class:`RunLog`.
* :func:`add_recording_args`, :func:`make_observer`: the ``--rrd`` / ``--spawn`` glue.

Names load on first use, so importing this package (as the CLI does to register
``replay``) does not import rerun or mujoco.
"""

from __future__ import annotations

from isf_robot._exports import lazy_exports

_EXPORTS: dict[str, str] = {
    "TIMELINE": "buffer", "Channel": "buffer", "ColumnBuffer": "buffer", "RaggedChannel": "buffer",
    "RecordError": "errors", "RecordingReadError": "errors", "ViewerUnavailableError": "errors",
    "add_recording_args": "options", "make_observer": "options", "recording_path": "options",
    "PerRunRecorder": "options",
    "RerunRecorder": "recorder", "SatelliteRecorder": "satellite", "ArmRecorder": "arm",
    "arm_blueprint": "blueprints", "satellite_blueprint": "blueprints", "generic_blueprint": "blueprints",
    "blueprint_for": "blueprints", "team_blueprint": "blueprints",
    "METRIC_KEYS": "replay", "arm_metrics": "replay", "RunLog": "replay", "format_table": "replay",
    "impulse_metrics": "replay",
    "read_many": "replay", "read_rrd": "replay", "read_columns": "replay", "replay_metrics": "replay",
    "close_stream": "stream", "find_viewer": "stream", "open_stream": "stream",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
