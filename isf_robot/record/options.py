"""Command-line glue: ``--rrd PATH`` / ``--spawn`` options and the observer they ask for.

Command modules owned by the arm and satellite layers call two functions and nothing else::

    add_recording_args(parser)                      # or per_run=True for `compare`
    observer = make_observer(args, "arm", name="panda_pole-isf-seed0")   # None if not asked

Recording layout:

* ``isf-robot run --rrd PATH`` and ``isf-satellite run --rrd PATH``: one file, one recording.
* ``isf-robot compare --rrd DIR``: one recording per strategy and episode, each in its own
  file ``DIR/<scene>-<strategy>-seed<seed>.rrd`` (names that cannot collide across scenes),
  so that ``isf-robot replay DIR`` (or ``DIR/*.rrd``) puts them side by side. With
  ``--spawn`` every recording also streams to the one viewer, as distinct recordings. The observer is a picklable
  :class:`PerRunRecorder`, so it can travel to worker processes inside the run parameters.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from isf_robot.core.hooks import Observer

from .errors import RecordError
from .serve import DEFAULT_BIND, DEFAULT_CONNECT, GRPC_PORT, WEB_PORT, check_bind

__all__ = [
    "add_recording_args", "make_observer", "open_recorder", "recording_path", "run_name", "PerRunRecorder",
    "APPLICATION_IDS",
]

APPLICATION_IDS = {"arm": "isf_robot_arm", "satellite": "isf_robot_satellite", "generic": "isf_robot"}
"""Rerun application id per recording kind."""


def add_recording_args(parser: argparse.ArgumentParser, *, per_run: bool = False) -> None:
    """Add ``--rrd`` and ``--spawn`` to a subcommand's parser.

    Args:
        parser: The subcommand parser.
        per_run: The command makes several runs (``compare``): ``--rrd`` names a directory
            receiving one ``.rrd`` file per run.

    """
    group = parser.add_argument_group("Rerun recording")
    if per_run:
        group.add_argument(
            "--rrd", metavar="DIR", type=Path, default=None,
            help="save one Rerun recording per episode as DIR/<scene>-<strategy>-seed<seed>.rrd (DIR is "
                 "created if missing; each file appears when its episode finishes, an interrupted one stays "
                 "*.rrd.partial; replay them with 'isf-robot replay DIR')",
        )
    else:
        group.add_argument("--rrd", metavar="PATH", type=Path, default=None,
                           help="save the run as a Rerun recording (.rrd) for the viewer and 'isf-robot replay'; "
                                "written as PATH.partial and renamed when the run finishes, so an existing PATH "
                                "survives a failed or interrupted run (missing folders are created)")
    group.add_argument("--spawn", action="store_true",
                       help="stream the run to a newly spawned Rerun viewer (needs a display)")
    group.add_argument("--connect", nargs="?", const=DEFAULT_CONNECT, default=None, metavar="URL",
                       help=f"stream to a Rerun viewer already running (default URL {DEFAULT_CONNECT}, the "
                            "viewer started with 'rerun' on this machine)")
    if not per_run:
        group.add_argument("--serve-web", action="store_true",
                           help=f"serve Rerun's web viewer from this process (page on port {WEB_PORT}, data on "
                                f"{GRPC_PORT}, on 127.0.0.1 unless --bind; the address is printed); after the run "
                                "it keeps serving until Ctrl-C")
        group.add_argument("--bind", metavar="ADDR", default=None,
                           help="--serve-web: the address to listen on (default 127.0.0.1, this machine only; "
                                "0.0.0.0 exposes the run to every machine that can reach this one)")
        group.add_argument("--web-port", metavar="PORT", type=int, default=None,
                           help=f"--serve-web: port of the web viewer's page (default {WEB_PORT})")
        group.add_argument("--grpc-port", metavar="PORT", type=int, default=None,
                           help=f"--serve-web: port of the recording's gRPC server (default {GRPC_PORT})")
    parser.set_defaults(rrd_per_run=per_run)


_SAFE = re.compile(r"[^A-Za-z0-9_.=+-]+")


def recording_path(base: Path, name: str) -> Path:
    """File of one run in a per-run recording directory: ``base/<name>.rrd`` (name sanitised)."""
    if base.suffix == ".rrd" and not base.is_dir():
        raise RecordError(
            f"--rrd {str(base)!r}: this command writes one recording per strategy and episode; "
            "pass a directory (it is created if missing)"
        )
    clean = _SAFE.sub("_", name).strip("_") or "run"
    return base / f"{clean}.rrd"


def make_observer(args: argparse.Namespace, kind: str, *, name: str | None = None, **context: Any) -> Observer | None:
    """Create the recorder asked for by ``--rrd`` / ``--spawn``, or ``None`` when neither was given.

    Args:
        args: Parsed arguments (from a parser prepared by :func:`add_recording_args`).
        kind: ``"arm"``, ``"satellite"`` or ``"generic"``.
        name: Recording name shown by the viewer (single-run commands).
        **context: Passed to the recorder: for ``"arm"`` optionally ``closest=``; for
            ``"satellite"`` optionally ``mesh_path=``, ``radius_m=``; anything else is ignored.
            The geometry comes from the run's start info.

    Returns:
        An :class:`~isf_robot.core.hooks.Observer` to pass to the simulation loop, or ``None``.
        With per-run recording (``compare``) a picklable :class:`PerRunRecorder` that opens
        ``DIR/<strategy>-seed<seed>.rrd`` at each run's start.

    Raises:
        RecordError: Bad destination; ViewerUnavailableError: ``--spawn`` without a viewer.

    """
    rrd = getattr(args, "rrd", None)
    spawn = bool(getattr(args, "spawn", False))
    connect = getattr(args, "connect", None)
    serve_web = bool(getattr(args, "serve_web", False))
    serving = _serve_options(args, serve_web)
    if rrd is None and not spawn and connect is None and not serve_web:
        return None
    if kind not in APPLICATION_IDS:
        raise RecordError(f"unknown recording kind {kind!r}; valid kinds: {', '.join(sorted(APPLICATION_IDS))}")
    if spawn:
        from .stream import find_viewer  # (imports rerun: see open_recorder)

        find_viewer()  # fail before simulating
    if getattr(args, "rrd_per_run", False):
        if rrd is not None:
            recording_path(Path(rrd), "check")  # a directory, not a .rrd file
        return PerRunRecorder(None if rrd is None else Path(rrd), kind, spawn=spawn, connect=connect)
    return open_recorder(kind, None if rrd is None else Path(rrd), spawn=spawn, name=name, connect=connect,
                         serve_web=serve_web, serving=serving, **context)


def _serve_options(args: argparse.Namespace, serve_web: bool) -> dict[str, Any]:
    """``bind``, ``web_port``, ``grpc_port`` of ``--serve-web``, checked; they need ``--serve-web``."""
    given = {k: getattr(args, k, None) for k in ("bind", "web_port", "grpc_port")}
    named = [f"--{k.replace('_', '-')}" for k, v in given.items() if v is not None]
    if named and not serve_web:
        raise RecordError(f"{', '.join(named)}: only for --serve-web (where it listens); add --serve-web")
    for key in ("web_port", "grpc_port"):
        v = given[key]
        if v is not None and not 1 <= int(v) <= 65535:
            raise RecordError(f"--{key.replace('_', '-')} must be a TCP port, 1..65535, got {v}")
    web = WEB_PORT if given["web_port"] is None else int(given["web_port"])
    grpc = GRPC_PORT if given["grpc_port"] is None else int(given["grpc_port"])
    if serve_web and web == grpc:
        raise RecordError(f"--web-port and --grpc-port must differ, both are {web}")
    return {"bind": check_bind(DEFAULT_BIND if given["bind"] is None else given["bind"]), "web_port": web,
            "grpc_port": grpc}


def open_recorder(kind: str, path: Path | None, *, spawn: bool = False, name: str | None = None,
                  connect: str | None = None, serve_web: bool = False, serving: dict[str, Any] | None = None,
                  **context: Any) -> Observer:
    """Open a stream (file and/or viewer) and the recorder of ``kind`` on it.

    Args:
        kind: ``"arm"``, ``"satellite"`` or ``"generic"``.
        path: ``.rrd`` file, or ``None`` (viewer only).
        spawn: Stream to a spawned viewer too.
        name: Recording name shown by the viewer.
        connect: Stream to the viewer at this URL too.
        serve_web: Serve the web viewer from this process too (see :func:`~isf_robot.record.stream.open_stream`).
        serving: ``bind``, ``web_port``, ``grpc_port`` of ``serve_web`` (default: 127.0.0.1, 9090, 9876).
        **context: Recorder arguments (see :func:`make_observer`).

    """
    # (the stream and the recorders import rerun, and the arm's mujoco: loaded when a recording opens, not when
    # a command adds its options)
    from .blueprints import blueprint_for
    from .stream import open_stream

    live = spawn or connect is not None or serve_web
    # (the arm recorder sends its layout, framed on the arm, when the run starts: a file alone needs no other, 8 ms;
    # a viewer gets the kind's layout at once)
    blueprint = blueprint_for(kind) if live or kind != "arm" else None
    stream = open_stream(APPLICATION_IDS[kind], rrd_path=path, spawn=spawn, recording_name=name,
                         blueprint=blueprint, connect=connect, serve_web=serve_web, **(serving or {}))
    if kind == "arm":
        from .arm import ArmRecorder

        arm = _pick(context, ArmRecorder.CONTEXT_KEYS)
        if "capacity" not in arm:  # (a file alone: long blocks, fewer sends; a live viewer: an update every ~1 s)
            arm["capacity"] = ArmRecorder.LIVE_CAPACITY if live else ArmRecorder.FILE_CAPACITY
        return ArmRecorder(stream, **arm)
    if kind == "satellite":
        from .satellite import SatelliteRecorder

        return SatelliteRecorder(stream, **_pick(context, SatelliteRecorder.CONTEXT_KEYS))
    from .recorder import RerunRecorder

    return RerunRecorder(stream)


def _pick(context: dict[str, Any], keys: tuple[str, ...]) -> dict[str, Any]:
    return {k: v for k, v in context.items() if k in keys}


def run_name(info: Mapping[str, Any]) -> str:
    """Name of a run from its ``on_start`` info: ``[<scene>-]<strategy or trigger>[-<coordination>]-seed<seed>``."""
    head = str(info.get("strategy") or info.get("trigger") or "run")
    if info.get("scene"):
        head = f"{info['scene']}-{head}"
    if info.get("coordination"):  # a team run: central and decentral runs of one seed get files of their own
        head = f"{head}-{info['coordination']}"
    seed = info.get("seed")
    return f"{head}-seed{seed}" if seed is not None else str(head)


class PerRunRecorder(Observer):
    """One recording per run: each ``on_start`` opens ``<directory>/<run_name(info)>.rrd``.

    Holds only paths and flags until a run starts, so it can be pickled into worker processes
    (``compare --jobs K``) and reused for consecutive runs. For arm runs the scene is loaded
    from the run info (``model_path``/``config_path`` or ``scene``).

    Args:
        directory: Folder receiving the files (created if missing), or ``None`` (viewer only).
        kind: Recording kind (``"arm"``, ``"satellite"``, ``"generic"``).
        spawn: Also stream each run to the viewer (one viewer, distinct recordings).
        connect: Also stream each run to the viewer at this URL.

    """

    def __init__(self, directory: Path | None, kind: str, *, spawn: bool = False, connect: str | None = None) -> None:
        self.directory = directory
        self.kind = kind
        self.spawn = spawn
        self.connect = connect
        self.paths: list[Path] = []
        self._current: Observer | None = None

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state["_current"] = None
        return state

    def on_start(self, info: Mapping[str, Any]) -> None:
        """Open this run's recording and start it."""
        name = run_name(info)
        path = None if self.directory is None else recording_path(self.directory, name)
        self._current = open_recorder(self.kind, path, spawn=self.spawn, name=name,
                                      connect=getattr(self, "connect", None))
        if path is not None:
            self.paths.append(path)
        self._current.on_start(info)

    def on_step(self, record: Any) -> None:
        """Forward to the current run's recorder."""
        if self._current is not None:
            self._current.on_step(record)

    def on_steps(self, block: Any) -> None:
        """Forward to the current run's recorder."""
        if self._current is not None:
            self._current.on_steps(block)

    def on_event(self, event: Any) -> None:
        """Forward to the current run's recorder."""
        if self._current is not None:
            self._current.on_event(event)

    def on_finish(self, summary: Mapping[str, Any]) -> None:
        """Finish and close the current run's recording."""
        if self._current is not None:
            current, self._current = self._current, None
            current.on_finish(summary)
            error = getattr(current, "error", None)
            if error is not None:  # one file of many failed (e.g. disk full): stop the batch with it
                raise error

    def on_abort(self, reason: BaseException) -> None:
        """The run stopped early: its recording stays ``<name>.rrd.partial``."""
        if self._current is not None:
            self._current.on_abort(reason)
            self._current = None
