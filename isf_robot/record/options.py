"""Command-line glue: ``--rrd PATH`` / ``--spawn`` options and the observer they ask for.

Command modules owned by the arm and satellite layers call two functions and nothing else::

    add_recording_args(parser)                      # or per_run=True for `compare`
    observer = make_observer(args, "arm", scene=scene, strategy=s, seed=seed)   # None if not asked

Recording layout:

* ``isf-robot run --rrd PATH`` and ``isf-satellite run --rrd PATH``: one file, one recording.
* ``isf-robot compare --rrd DIR``: one recording per strategy and episode, each in its own
  file ``DIR/<name>.rrd`` (``<name>`` given by the caller, e.g. ``isf-seed3``), so that
  ``isf-robot replay DIR`` (or ``DIR/*.rrd``) puts them side by side. With ``--spawn`` every
  recording also streams to the one viewer, as distinct recordings.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import Any

from isf_robot.core.hooks import Observer

from .errors import RecordError

__all__ = ["add_recording_args", "make_observer", "recording_path", "APPLICATION_IDS"]

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
            help="save one Rerun recording per strategy and episode as DIR/<strategy>-<episode>.rrd "
                 "(replay them with 'isf-robot replay DIR')",
        )
    else:
        group.add_argument("--rrd", metavar="PATH", type=Path, default=None,
                           help="save the run as a Rerun recording (.rrd) for the viewer and 'isf-robot replay'")
    group.add_argument("--spawn", action="store_true",
                       help="stream the run to a newly spawned Rerun viewer (needs a display)")
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
        name: Run name; required with per-run recording (``compare``), where it names the file.
        **context: Passed to the recorder: for ``"arm"`` ``scene=`` (an
            :class:`isf_robot.arm.Scene`) and optionally ``closest=``; for ``"satellite"``
            optionally ``mesh_path=``, ``radius_m=``; anything else is ignored.

    Returns:
        An :class:`~isf_robot.core.hooks.Observer` to pass to the simulation loop, or ``None``.

    Raises:
        RecordError: Bad destination; ViewerUnavailableError: ``--spawn`` without a viewer.

    """
    rrd = getattr(args, "rrd", None)
    spawn = bool(getattr(args, "spawn", False))
    if rrd is None and not spawn:
        return None
    if kind not in APPLICATION_IDS:
        raise RecordError(f"unknown recording kind {kind!r}; valid kinds: {', '.join(sorted(APPLICATION_IDS))}")
    path: Path | None = None
    if rrd is not None:
        rrd = Path(rrd)
        if getattr(args, "rrd_per_run", False):
            if not name:
                raise RecordError("per-run recording needs a run name")
            path = recording_path(rrd, name)
        else:
            path = rrd
    from .blueprints import blueprint_for
    from .stream import open_stream

    stream = open_stream(
        APPLICATION_IDS[kind], rrd_path=path, spawn=spawn, recording_name=name,
        blueprint=blueprint_for(kind),
    )
    if kind == "arm":
        from .arm import ArmRecorder

        return ArmRecorder(stream, **_pick(context, ArmRecorder.CONTEXT_KEYS))
    if kind == "satellite":
        from .satellite import SatelliteRecorder

        return SatelliteRecorder(stream, **_pick(context, SatelliteRecorder.CONTEXT_KEYS))
    from .recorder import RerunRecorder

    return RerunRecorder(stream)


def _pick(context: dict[str, Any], keys: tuple[str, ...]) -> dict[str, Any]:
    return {k: v for k, v in context.items() if k in keys}
