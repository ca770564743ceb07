"""The strategies of one seed side by side: one recording per (scene, seed) built from ``compare``'s files.

``isf-robot compare --rrd DIR`` writes one recording per strategy and episode,
``DIR/<scene>-<strategy>-seed<seed>.rrd``. Rerun's viewer shows one recording at a time, so
:func:`write_side_by_side` reads them back (with Rerun's reader) and writes, for each scene and
seed, ``DIR/side_by_side/<scene>-seed<seed>.rrd``: the barrier, filter mode and command
correction of every strategy under ``/compare/<strategy>/plots/...`` with
:func:`~isf_robot.record.blueprints.compare_blueprint` as its default layout (a column per
strategy, in the order given). The per-run files stay as they are (``isf-robot replay DIR``
reads those; the ``side_by_side`` folder is not among them).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import rerun as rr

from .blueprints import compare_blueprint
from .columns import read_columns
from .errors import RecordingReadError
from .replay import RunLog, read_rrd
from .schema import command_unit
from .stream import close_stream, open_stream

__all__ = ["write_side_by_side", "SERIES", "SUBDIR"]

SUBDIR = "side_by_side"
SERIES: tuple[tuple[str, str], ...] = (
    ("/plots/barrier/min", "min h (true geometry)"),
    ("/plots/barrier/zero", "h = 0"),
    ("/plots/mode", "filter on"),
    ("/plots/command/correction_norm", "|u - u_nom|"),
)
"""Entities copied per strategy, with their series names."""


def _key(log: RunLog) -> tuple[str, str]:
    return str(log.info.get("scene") or "run"), str(log.info.get("seed"))


def write_side_by_side(directory: str | Path, order: Sequence[str] = ()) -> list[Path]:
    """Write one side-by-side recording per (scene, seed) of the arm recordings in ``directory``.

    Args:
        directory: A folder of per-run recordings (``compare --rrd DIR``).
        order: Strategy order of the columns (others follow, sorted).

    Returns:
        The files written, sorted.

    Raises:
        RecordingReadError: A recording cannot be read.

    """
    d = Path(directory)
    groups: dict[tuple[str, str], list[tuple[Path, RunLog]]] = {}
    for f in sorted(d.glob("*.rrd")):
        for log in read_rrd(f):
            if log.kind == "arm" and log.info.get("strategy"):
                groups.setdefault(_key(log), []).append((f, log))
    rank = {s: i for i, s in enumerate(order)}
    written = []
    for (scene, seed), runs in sorted(groups.items()):
        runs.sort(key=lambda r: (rank.get(str(r[1].info["strategy"]), len(rank)), str(r[1].info["strategy"])))
        strategies = [str(log.info["strategy"]) for _, log in runs]
        if len(set(strategies)) != len(strategies):
            raise RecordingReadError(d, f"several recordings of {scene} seed {seed} with the same strategy")
        name = f"{scene}-seed{seed}"
        path = d / SUBDIR / f"{name}.rrd"
        units = {command_unit(log.info) for _, log in runs}
        if len(units) > 1:
            raise RecordingReadError(d, f"recordings of {scene} seed {seed} at both levels: compare one level at a "
                                        "time")
        stream = open_stream("isf_robot_compare", rrd_path=path, recording_name=f"{name}: {' vs '.join(strategies)}",
                             blueprint=compare_blueprint(strategies, unit=units.pop()))
        ok = False
        try:
            stream.log("/run/info", rr.AnyValues(scene=scene, seed_label=seed, strategies=",".join(strategies),
                                                 files=",".join(str(f.name) for f, _ in runs)), static=True)
            for (f, _), strategy in zip(runs, strategies):
                for entity, label in SERIES:
                    try:
                        col = read_columns(f, entity, ["Scalars:scalars"])
                    except RecordingReadError:
                        continue  # e.g. no correction plot in an older recording
                    target = f"/compare/{strategy}{entity}"
                    stream.log(target, rr.SeriesLines(names=f"{strategy}: {label}"), static=True)
                    stream.send_columns(target, indexes=[rr.TimeColumn("sim_time", duration=col["sim_time"])],
                                        columns=rr.Scalars.columns(scalars=col["Scalars:scalars"]))
            ok = True
        finally:
            close_stream(stream, complete=ok)  # a failure leaves <name>.rrd.partial, not a half file
        written.append(path)
    return written
