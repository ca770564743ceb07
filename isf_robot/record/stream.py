"""Opening explicit Rerun recording streams (no global ``rr.init`` state).

:func:`open_stream` makes a :class:`rerun.RecordingStream` that writes to a ``.rrd`` file,
streams to a freshly spawned viewer (``--spawn``), to a viewer already running at an address
(``--connect [URL]``), and/or serves Rerun's web viewer from this process (``--serve-web``:
a gRPC server plus the web viewer's page, both on 127.0.0.1 unless ``--bind ADDR`` says
otherwise, :mod:`isf_robot.record.serve`; after the run the command keeps serving until
Ctrl-C, :func:`wait_while_serving`, as Rerun's own examples do). :func:`find_viewer` checks
beforehand that a viewer can start, so ``--spawn`` fails with one clear message instead of
hanging or crashing in a headless session.

A recording file is written as ``<name>.partial`` and renamed to ``<name>`` by
:func:`close_stream` once the run has finished (:mod:`isf_robot.support.files`): a bad parameter,
a crash or Ctrl-C leaves an existing recording as it was, and what was recorded before the
interruption under ``<name>.partial``.
"""

from __future__ import annotations

import ipaddress
import os
import sys
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import quote

import rerun as rr

from isf_robot.core.exceptions import ConfigError
from isf_robot.support.files import check_output_path, commit_partial, partial_path

from .errors import RecordError, ViewerUnavailableError
from .serve import (
    DEFAULT_BIND,
    DEFAULT_CONNECT,
    GRPC_PORT,
    WEB_PORT,
    WebViewerServer,
    check_bind,
    check_port_free,
    connect_host,
    rerun_executable,
)

__all__ = ["find_viewer", "open_stream", "close_stream", "stream_path", "wait_while_serving"]

# id(stream) -> the .rrd path its .partial file is renamed to when the stream is closed
_TARGETS: dict[int, Path] = {}
# streams serving the web viewer, kept open after their run until the command ends (see wait_while_serving)
_SERVING: list[tuple[rr.RecordingStream, str, WebViewerServer]] = []


def find_viewer() -> Path:
    """Locate the Rerun viewer executable and check that a display is available.

    Returns:
        The path of the ``rerun`` executable.

    Raises:
        ViewerUnavailableError: No executable on ``PATH`` (or beside the Python interpreter),
            or, on Linux, neither ``DISPLAY`` nor ``WAYLAND_DISPLAY`` is set.

    """
    exe = rerun_executable()
    if exe is None:
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
    connect: str | None = None,
    serve_web: bool = False,
    grpc_port: int = GRPC_PORT,
    web_port: int = WEB_PORT,
    bind: str = DEFAULT_BIND,
) -> rr.RecordingStream:
    """Create an explicit recording stream with its sinks.

    Args:
        application_id: Rerun application id, e.g. ``"isf_robot_arm"`` (letters, digits, ``_`` and ``-`` only).
        rrd_path: Write the recording to this ``.rrd`` file (parent folders are created); it is
            written as ``<rrd_path>.partial`` until :func:`close_stream` completes it.
        spawn: Also stream to a newly spawned viewer (checked by :func:`find_viewer`).
        recording_id: Recording id (default: a fresh UUID).
        recording_name: Human-readable name shown by the viewer.
        blueprint: Default blueprint sent with the recording.
        connect: Also stream to the viewer listening at this URL (``rerun+http://HOST:PORT/proxy``).
        serve_web: Also serve the recording over gRPC (port ``grpc_port``) with Rerun's web
            viewer (port ``web_port``, :class:`~isf_robot.record.serve.WebViewerServer`), both
            listening on ``bind``; the page's address is printed on stderr.
        grpc_port: See ``serve_web`` (default :data:`GRPC_PORT`).
        web_port: See ``serve_web`` (default :data:`WEB_PORT`).
        bind: See ``serve_web`` (default :data:`~isf_robot.record.serve.DEFAULT_BIND`, this machine only).

    Returns:
        The stream. Close it with :func:`close_stream` so the file gets its footer.

    Raises:
        RecordError: Neither a path nor ``spawn`` was given, or the file cannot be created.
        ViewerUnavailableError: ``spawn`` was asked for and no viewer can start.

    """
    if rrd_path is None and not spawn and not connect and not serve_web:
        raise RecordError("a recording needs a destination: an .rrd path, spawn, connect or serve_web")
    if connect is not None and not str(connect).startswith(("rerun://", "rerun+http://", "rerun+https://")):
        raise RecordError(f"--connect {connect!r}: not a viewer address; valid: rerun+http://HOST:PORT/proxy "
                          f"(default {DEFAULT_CONNECT})")
    exe = find_viewer() if spawn else None
    rec = rr.RecordingStream(application_id, recording_id=recording_id or str(uuid.uuid4()))
    sinks: list[Any] = []
    if rrd_path is not None:
        try:
            path = check_output_path(rrd_path, "recording file")
        except ConfigError as exc:
            raise RecordError(str(exc)) from None
        tmp = partial_path(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(tmp, "wb"):
                pass
        except OSError as exc:
            raise RecordError(f"cannot write the recording file {str(path)!r}: {exc.strerror or exc}") from exc
        sinks.append(rr.FileSink(str(tmp)))
        _TARGETS[id(rec)] = path
    if exe is not None:
        try:
            rr.spawn(connect=False, executable_path=str(exe), recording=rec)
        except Exception as exc:  # the viewer binary failed to start
            raise ViewerUnavailableError(f"--spawn could not start the Rerun viewer ({exe}): {exc}") from exc
        sinks.append(rr.GrpcSink())
    if connect:
        sinks.append(rr.GrpcSink(url=str(connect)))
    if serve_web:
        if _SERVING:
            raise RecordError("--serve-web serves one recording per process; use --connect for several runs")
        bind = check_bind(bind)
        check_port_free(bind, int(grpc_port), "the recording (gRPC)")
        try:
            sinks.append(rr.GrpcServerSink(bind_ip=bind, port=int(grpc_port)))
        except Exception as exc:  # the port is taken
            raise RecordError(f"--serve-web cannot serve on {bind} port {grpc_port}: "
                              f"{' '.join(str(exc).split())}") from None
    rec.set_sinks(*sinks, default_blueprint=blueprint)
    if serve_web:
        host = connect_host(bind)
        url = f"rerun+http://{host}:{int(grpc_port)}/proxy"
        try:
            web = WebViewerServer(bind, int(web_port), url)
        except RecordError:
            rec.disconnect()  # the gRPC server stops with its sinks
            raise
        page = f"http://{host}:{int(web_port)}/?url={quote(url, safe='')}"
        _SERVING.append((rec, page, web))
        where = ("every interface: from another machine put this machine's address in place of 127.0.0.1"
                 if ipaddress.ip_address(bind).is_unspecified else f"{bind} only")
        print(f"Rerun web viewer: {page} (listening on {where})", file=sys.stderr, flush=True)
    if recording_name:
        rec.send_recording_name(recording_name)
    return rec


def stream_path(rec: rr.RecordingStream) -> Path | None:
    """The ``.rrd`` file a stream will complete when closed (``None``: no file or already closed)."""
    return _TARGETS.get(id(rec))


def close_stream(rec: rr.RecordingStream, *, complete: bool = True) -> Path | None:
    """Flush everything and close the sinks (writes the ``.rrd`` footer).

    Args:
        rec: The stream.
        complete: The run finished: rename ``<name>.partial`` to ``<name>``. ``False`` (a failed
            or interrupted run) leaves the data under ``<name>.partial`` and ``<name>`` untouched.

    Returns:
        The completed recording file (``None`` without a file or when not ``complete``).

    Raises:
        RecordError: The file writer failed (e.g. the disk is full; Rerun reports it only at the
            flush): nothing is renamed, so ``<name>.partial`` keeps what was written.

    """
    path = _TARGETS.pop(id(rec), None)
    serving = any(r is rec for r, _, _ in _SERVING)
    try:
        rec.flush()
        if not serving:  # a served stream stays up for the web viewer until wait_while_serving ends
            rec.disconnect()
    except RuntimeError as exc:  # the file writer died: disk full, file removed, ... (or a viewer's link)
        why = " ".join(str(exc).split())
        if path is None:
            raise RecordError(f"the recording stream failed: {why}") from exc
        if "grpc" in why.lower():  # the viewer of --connect went away: the file is fine, complete it
            try:
                rec.disconnect()
            except RuntimeError:
                pass
            if complete:
                commit_partial(path)
            raise RecordError(f"the connection to the Rerun viewer failed ({why}); the recording file "
                              f"{str(path if complete else partial_path(path))!r} is written") from exc
        raise RecordError(
            f"the recording could not be written ({why}; disk full?): what was written stays in "
            f"{str(partial_path(path))!r} and {str(path)!r} was not touched") from exc
    if path is None or not complete:
        return None
    try:
        return commit_partial(path)
    except OSError as exc:
        raise RecordError(f"cannot complete the recording file {str(path)!r}: {exc.strerror or exc}") from exc


def wait_while_serving(sleep: Callable[[float], None] = time.sleep) -> bool:
    """Keep serving the web viewer after the run until Ctrl-C, then close the served streams.

    Called by the command line when a command has finished (nothing happens when no stream
    serves). Returns ``True`` when something was served.
    """
    if not _SERVING:
        return False
    pages = ", ".join(page for _, page, _ in _SERVING)
    print(f"serving the recording to the web viewer at {pages}; press Ctrl-C to stop", file=sys.stderr, flush=True)
    try:
        while True:
            sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        while _SERVING:
            rec, _, web = _SERVING.pop()
            web.stop()
            try:
                rec.flush()
                rec.disconnect()
            except RuntimeError:
                pass
    return True
