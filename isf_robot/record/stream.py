"""Opening explicit Rerun recording streams (no global ``rr.init`` state).

:func:`open_stream` makes a :class:`rerun.RecordingStream` that writes to a ``.rrd`` file,
streams to a freshly spawned viewer, or both. :func:`find_viewer` checks beforehand that a
viewer can start, so ``--spawn`` fails with one clear message instead of hanging or crashing
in a headless session.
"""

from __future__ import annotations

import os
import shutil
import sys
import uuid
from pathlib import Path
from typing import Any

import rerun as rr

from .errors import RecordError, ViewerUnavailableError

__all__ = ["find_viewer", "open_stream", "close_stream"]


def find_viewer() -> Path:
    """Locate the Rerun viewer executable and check that a display is available.

    Returns:
        The path of the ``rerun`` executable.

    Raises:
        ViewerUnavailableError: No executable on ``PATH`` (or beside the Python interpreter),
            or, on Linux, neither ``DISPLAY`` nor ``WAYLAND_DISPLAY`` is set.

    """
    found = shutil.which("rerun")
    exe = Path(found) if found else Path(sys.executable).parent / ("rerun.exe" if os.name == "nt" else "rerun")
    if not exe.is_file():
        raise ViewerUnavailableError(
            "--spawn needs the Rerun viewer, but no 'rerun' executable was found on PATH or beside "
            f"{sys.executable}; install rerun-sdk's viewer, or save with --rrd PATH and open the file later"
        )
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ViewerUnavailableError(
            "--spawn cannot start the Rerun viewer: no display (neither DISPLAY nor WAYLAND_DISPLAY "
            "is set); use --rrd PATH and open the file with 'rerun PATH' on a machine with a display"
        )
    return exe


def open_stream(
    application_id: str,
    *,
    rrd_path: str | Path | None = None,
    spawn: bool = False,
    recording_id: str | None = None,
    recording_name: str | None = None,
    blueprint: Any = None,
) -> rr.RecordingStream:
    """Create an explicit recording stream with its sinks.

    Args:
        application_id: Rerun application id, e.g. ``"isf_robot_arm"`` (letters, digits, ``_`` and ``-`` only).
        rrd_path: Write the recording to this ``.rrd`` file (parent folders are created).
        spawn: Also stream to a newly spawned viewer (checked by :func:`find_viewer`).
        recording_id: Recording id (default: a fresh UUID).
        recording_name: Human-readable name shown by the viewer.
        blueprint: Default blueprint sent with the recording.

    Returns:
        The stream. Close it with :func:`close_stream` so the file gets its footer.

    Raises:
        RecordError: Neither a path nor ``spawn`` was given, or the file cannot be created.
        ViewerUnavailableError: ``spawn`` was asked for and no viewer can start.

    """
    if rrd_path is None and not spawn:
        raise RecordError("a recording needs a destination: an .rrd path, spawn=True, or both")
    exe = find_viewer() if spawn else None
    rec = rr.RecordingStream(application_id, recording_id=recording_id or str(uuid.uuid4()))
    sinks: list[Any] = []
    if rrd_path is not None:
        path = Path(rrd_path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(path, "wb"):
                pass
        except OSError as exc:
            raise RecordError(f"cannot write the recording file {str(path)!r}: {exc.strerror or exc}") from exc
        sinks.append(rr.FileSink(str(path)))
    if exe is not None:
        try:
            rr.spawn(connect=False, executable_path=str(exe), recording=rec)
        except Exception as exc:  # the viewer binary failed to start
            raise ViewerUnavailableError(f"--spawn could not start the Rerun viewer ({exe}): {exc}") from exc
        sinks.append(rr.GrpcSink())
    rec.set_sinks(*sinks, default_blueprint=blueprint)
    if recording_name:
        rec.send_recording_name(recording_name)
    return rec


def close_stream(rec: rr.RecordingStream) -> None:
    """Flush everything and close the sinks (writes the ``.rrd`` footer)."""
    rec.flush()
    rec.disconnect()
