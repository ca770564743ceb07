"""``isf-robot replay FILE.rrd [FILE.rrd ...] [--json]``: metrics from recordings, no simulation.

Each recording's duty-cycle metrics are recomputed with
:func:`isf_robot.core.metrics.compute_metrics` from its logged per-step columns. One file
prints a list of metrics; several (or a file holding several recordings, or a directory of
``.rrd`` files) print a side-by-side table, and below it the versions and settings each was
recorded with. A team recording (several arms) adds a table of each arm's figures (its own filter's
duty cycle, switches and off periods, its intervention, the smallest barrier of its pairs at the ticks).
``--json`` prints one shape whatever the number of inputs:
``{"schema": "isf-robot-replay/1", "recordings": [{"file", "recording_id", "label", "kind",
"versions", "info", "metrics"}, ...]}`` (``metrics`` holds the same keys as the run's own
``--json`` for those figures).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from isf_robot.support.report import format_value, with_schema

__all__ = ["register", "handle", "add_arguments", "describe_recording"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``replay``."""
    p.add_argument("files", nargs="+", type=Path, metavar="FILE.rrd",
                   help="recordings saved with --rrd (a directory stands for the .rrd files in it)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")


def handle(args: argparse.Namespace) -> int:
    """Read the recordings, recompute and print their metrics."""
    from isf_robot.record.errors import RecordingReadError
    from isf_robot.record.replay import format_table, read_many, replay_metrics

    bad: list[RecordingReadError] = []
    logs = read_many(args.files, errors=bad)
    if not logs and bad:
        raise bad[0] if len(bad) == 1 else RecordingReadError(
            Path(args.files[0]), f"none of the {len(bad)} recordings could be read")
    for exc in bad:  # one line per unreadable file; the others are replayed
        print(f"isf-robot replay: error: {' '.join(str(exc).split())}", file=sys.stderr)
    results = [(log, replay_metrics(log)) for log in logs]
    if args.json:
        out = {"recordings": [
            {"file": str(log.path), "recording_id": log.recording_id, "label": log.label,
             "kind": log.kind, "versions": log.info.get("versions", {}), "info": log.info, "metrics": m}
            for log, m in results
        ]}
        print(json.dumps(with_schema("isf-robot-replay", out)))
        return 2 if bad else 0
    labels = _unique_labels([log.label for log, _ in results], [log.path.stem for log, _ in results])
    print(format_table(list(zip(labels, [m for _, m in results]))))
    for lab, (_, m) in zip(labels, results):  # a team recording: each arm's figures
        if m.get("arms"):
            print(f"\n{lab}, per arm:")
            print(format_table([(a["name"], a) for a in m["arms"]]))
    print("\nrecorded with:")
    for lab, (log, _) in zip(labels, results):
        print(f"  {lab}: {describe_recording(log.info)}")
    if len(results) > 1:
        for lab, (log, _) in zip(labels, results):
            print(f"  {lab}: {log.path}", file=sys.stderr)
    return 2 if bad else 0


RUN_KEYS = ("scene", "strategy", "trigger", "seed", "alpha", "c", "b", "d_bar", "d_bar_source", "dt",
            "control_period", "duration", "hours", "alpha_gain", "spin", "R_m")
"""Settings shown by the text output (the JSON has every start-info entry)."""


def describe_recording(info: dict[str, Any]) -> str:
    """One line: the versions a recording was made with and its main settings."""
    versions = info.get("versions") or {}
    vers = ", ".join(f"{k} {v}" for k, v in versions.items()) or "versions not recorded"
    sets = ", ".join(f"{k}={format_value(info[k])}" for k in RUN_KEYS if info.get(k) is not None)
    return f"{vers}; {sets}"


def _unique_labels(labels: list[str], stems: list[str]) -> list[str]:
    if len(set(labels)) == len(labels):
        return labels
    if len(set(stems)) == len(stems):
        return stems
    return [f"{i + 1}:{lab}" for i, lab in enumerate(labels)]


def register(sub: Any) -> None:
    """Register ``replay`` on the ``isf-robot`` subparsers."""
    p = sub.add_parser(
        "replay",
        help="recompute duty-cycle metrics from saved Rerun recordings (no simulation)",
        description=(
            "Read .rrd recordings saved with --rrd using Rerun's own reader and recompute the "
            "duty-cycle metrics (duty_cycle, on_switches, mean_off_s, min_off_s, min_barrier, "
            "intervention) from the logged per-step columns, without simulating. Several "
            "recordings give a side-by-side table."
        ),
    )
    add_arguments(p)
    p.set_defaults(handler=handle)
