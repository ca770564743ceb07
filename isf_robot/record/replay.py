"""Reading recordings back with Rerun's own reader and recomputing the run's metrics.

:func:`read_rrd` opens a ``.rrd`` file with :class:`rerun.chunk.RrdReader` and returns one
:class:`RunLog` per recording in it (a file may hold several). :func:`replay_metrics`
recomputes the duty-cycle metrics with the core's
:func:`~isf_robot.core.metrics.compute_metrics` from the logged per-step columns
(``/replay/steps``), without simulating anything; the columns are float64/bool as logged, so
the figures equal the live run's.

A missing, empty, truncated, corrupt or non-Rerun file, or a recording that lacks the replay
columns, raises :class:`~isf_robot.record.errors.RecordingReadError` naming the file.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader

from isf_robot.core.metrics import compute_metrics
from isf_robot.support.report import format_table as report_table
from isf_robot.support.report import format_value

from . import schema
from .columns import _check_file, _damaged, read_columns
from .errors import RecordingReadError

__all__ = [
    "RunLog",
    "read_rrd",
    "read_many",
    "read_columns",
    "replay_metrics",
    "arm_metrics",
    "impulse_metrics",
    "format_table",
    "METRIC_KEYS",
]

METRIC_KEYS: tuple[str, ...] = (
    "duty_cycle", "on_switches", "mean_off_s", "min_off_s", "min_barrier", "intervention",
)
"""The comparison metrics of the issue, in table order (more keys are returned)."""


@dataclass(frozen=True)
class RunLog:
    """One recording read back from a ``.rrd`` file.

    Attributes:
        path: The file it came from.
        application_id: Rerun application id.
        recording_id: Rerun recording id.
        kind: ``"arm"``, ``"satellite"`` or another recorder kind.
        info: Run metadata logged at start (parsed JSON).
        summary: Run summary logged at the end (parsed JSON), ``None`` if the run did not finish.
        steps: Replay columns (``t``, ``dt``, ``on``, ``intervention_rate``, ``qp_solved``,
            ``min_barrier``), each shape (N,), in step order.
        events: Event columns (``t``, ``kind``, ``index``, ``xi``, ``duration_s``), each
            shape (E,), in time order.
        impulses: Impulse columns of impulsive runs (``t``, ``kind``, ``index``, ``dv_x``,
            ``dv_y``, ``dv_z``, ``h_after``, ``xi_after``, ``interval_s``), in time order.
        terminal: True-geometry barrier of the final state when the loop's last check set
            the run's minimum (arm runs), shape (0,) or (1,).
        arms: Team runs (several arms): each arm's replay columns by name, in the team's order
            (as ``steps``; ``min_barrier`` the smallest barrier of the arm's pairs at the tick); empty otherwise.

    """

    path: Path
    application_id: str
    recording_id: str
    kind: str
    info: dict[str, Any]
    summary: dict[str, Any] | None
    steps: dict[str, np.ndarray]
    events: dict[str, np.ndarray] = field(default_factory=dict)
    impulses: dict[str, np.ndarray] = field(default_factory=dict)
    terminal: np.ndarray = field(default_factory=lambda: np.zeros(0))
    arms: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """Short label for tables: strategy/episode when known, else the file stem."""
        parts = [str(self.info[k]) for k in ("scene", "strategy", "trigger", "coordination")
                 if self.info.get(k) is not None]
        for k in ("episode", "seed"):
            if self.info.get(k) is not None:
                parts.append(f"{k[:2] if k == 'episode' else k}{self.info[k]}")
                break
        return "/".join(parts) if parts else self.path.stem


def _flat(col: pa.ChunkedArray | pa.Array) -> pa.Array:
    """One value per row from a ``list<...>`` component column (first element of each row)."""
    arr = col.combine_chunks() if isinstance(col, pa.ChunkedArray) else col
    if pa.types.is_list(arr.type) or pa.types.is_large_list(arr.type):
        lengths = arr.value_lengths().fill_null(0).to_numpy(zero_copy_only=False)
        if np.any(lengths != 1):
            raise ValueError("a replay column holds rows with other than one value")
        return arr.flatten()
    return arr


def _to_numpy(arr: pa.Array) -> np.ndarray:
    if pa.types.is_string(arr.type) or pa.types.is_large_string(arr.type):
        return np.asarray(arr.to_pylist(), dtype=object)
    return arr.to_numpy(zero_copy_only=False)


def _collect(batches: list[pa.RecordBatch], names: Sequence[str]) -> dict[str, np.ndarray]:
    """Concatenate the named columns of several record batches."""
    cols: dict[str, list[np.ndarray]] = {n: [] for n in names}
    for b in batches:
        for n in names:
            if n not in b.schema.names:
                entity = (b.schema.metadata or {}).get(b"rerun:entity_path", b"?").decode()
                raise ValueError(f"column {n!r} missing from {entity}")
            cols[n].append(_to_numpy(_flat(b.column(n))))
    return {n: (np.concatenate(v) if v else np.zeros(0)) for n, v in cols.items()}


def _static_value(batches: list[pa.RecordBatch], name: str) -> Any:
    for b in reversed(batches):
        if name in b.schema.names and b.num_rows:
            vals = _flat(b.column(name)).to_pylist()
            if vals:
                return vals[-1]
    return None


def _read_store(path: Path, reader: RrdReader, entry: Any) -> RunLog:
    by_entity: dict[str, list[pa.RecordBatch]] = {}
    wanted = {schema.INFO, schema.SUMMARY, schema.STEPS, schema.EVENTS, schema.IMPULSES, schema.TERMINAL}
    arm_prefix = schema.ARM_STEPS + "/"
    for chunk in reader.stream(store=entry):
        ep = chunk.entity_path
        if ep in wanted or ep.startswith(arm_prefix):
            by_entity.setdefault(ep, []).append(chunk.to_record_batch())
    info_batches = by_entity.get(schema.INFO, [])
    if not info_batches or schema.STEPS not in by_entity:
        if path.name.endswith(".partial"):  # (the temporary name a recording has until its run ends)
            raise RecordingReadError(path, "an unfinished recording (its run was interrupted before the recording "
                                           "was complete) holds no run log to replay; finished runs' .rrd files do")
        raise RecordingReadError(
            path, f"recording {entry.recording_id!r} is not an isf_robot run log (no {schema.INFO} / "
            f"{schema.STEPS} entities); record runs with --rrd"
        )
    kind = _static_value(info_batches, "kind") or "generic"
    info = json.loads(_static_value(info_batches, "info_json") or "{}")
    summary_json = _static_value(by_entity.get(schema.SUMMARY, []), "summary_json")
    summary = json.loads(summary_json) if summary_json else None
    expected = _static_value(by_entity.get(schema.SUMMARY, []), "steps")
    try:
        steps = _collect(by_entity[schema.STEPS], schema.STEP_FIELDS)
        events = _collect(by_entity.get(schema.EVENTS, []), schema.EVENT_FIELDS)
        impulses = _collect(by_entity.get(schema.IMPULSES, []), schema.IMPULSE_FIELDS)
        terminal = _collect(by_entity.get(schema.TERMINAL, []), ("min_barrier",))["min_barrier"]
        arms = _arm_steps(by_entity, info.get("arms") or ())
    except (ValueError, pa.ArrowException) as exc:
        raise RecordingReadError(path, f"malformed replay columns: {exc}") from exc
    order = np.argsort(steps["t"], kind="stable")
    steps = {k: v[order] for k, v in steps.items()}
    steps["on"] = steps["on"].astype(bool)
    steps["qp_solved"] = steps["qp_solved"].astype(bool)
    if events["t"].size:
        order = np.argsort(events["t"], kind="stable")
        events = {k: v[order] for k, v in events.items()}
    if impulses["t"].size:
        order = np.argsort(impulses["t"], kind="stable")
        impulses = {k: v[order] for k, v in impulses.items()}
    if summary is None:
        raise RecordingReadError(
            path, f"recording {entry.recording_id!r} is incomplete: the run did not finish or the file "
            f"was cut short (no {schema.SUMMARY}; {steps['t'].size} steps read)"
        )
    if expected is not None and int(expected) != steps["t"].size:
        raise RecordingReadError(
            path, f"recording {entry.recording_id!r} is truncated: {steps['t'].size} of {int(expected)} "
            "logged steps could be read"
        )
    for name, cols in arms.items():
        if cols["t"].size != steps["t"].size:
            raise RecordingReadError(path, f"recording {entry.recording_id!r}: arm {name!r} has "
                                     f"{cols['t'].size} logged steps, the team {steps['t'].size}")
    return RunLog(path, entry.application_id, entry.recording_id, str(kind), info, summary, steps, events,
                  impulses, np.asarray(terminal, dtype=float), arms)


def _arm_steps(by_entity: dict[str, list[pa.RecordBatch]], names: Sequence[str]) -> dict[str, dict[str, np.ndarray]]:
    """Each arm's replay columns (``/replay/arms/<name>``), in time order, by name in the team's order."""
    out: dict[str, dict[str, np.ndarray]] = {}
    for name in names:
        batches = by_entity.get(schema.arm_path(schema.ARM_STEPS, name))
        if not batches:
            continue
        cols = _collect(batches, schema.STEP_FIELDS)
        order = np.argsort(cols["t"], kind="stable")
        cols = {k: v[order] for k, v in cols.items()}
        cols["on"] = cols["on"].astype(bool)
        cols["qp_solved"] = cols["qp_solved"].astype(bool)
        out[str(name)] = cols
    return out


def read_rrd(path: str | Path) -> list[RunLog]:
    """Read every isf_robot recording in a ``.rrd`` file.

    Args:
        path: The file.

    Returns:
        One :class:`RunLog` per recording, in file order.

    Raises:
        RecordingReadError: The file is missing, unreadable, truncated, corrupt, not a Rerun
            file, or holds no isf_robot recording.

    """
    p = Path(path)
    _check_file(p)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "no footer/manifest": we check completeness ourselves
            reader = RrdReader(p)
            entries = reader.recordings()
            if not entries:
                raise RecordingReadError(p, "the file holds no recording")
            return [_read_store(p, reader, e) for e in entries]
    except RecordingReadError:
        raise
    except Exception as exc:  # rerun raises RuntimeError/ValueError for damaged files
        raise _damaged(p, exc) from exc


def read_many(paths: Iterable[str | Path], *, errors: list[RecordingReadError] | None = None) -> list[RunLog]:
    """Read several files (directories are expanded to their ``*.rrd`` files, sorted).

    With ``errors`` (a list), a file that cannot be read is appended there and the others are
    still read; without it the first bad file raises.
    """
    out: list[RunLog] = []
    for p in paths:
        q = Path(p)
        if q.is_dir():
            files = sorted(q.glob("*.rrd"))
            if not files:
                raise RecordingReadError(q, "the directory holds no .rrd file")
        else:
            files = [q]
        for f in files:
            try:
                out.extend(read_rrd(f))
            except RecordingReadError as exc:
                if errors is None:
                    raise
                errors.append(exc)
    return out


def _min_or_none(a: np.ndarray) -> float | None:
    a = np.asarray(a, dtype=float)
    a = a[~np.isnan(a)]
    return float(np.min(a)) if a.size else None


def impulse_metrics(log: RunLog) -> dict[str, Any]:
    """Impulse figures of an impulsive run, from the logged impulses (as the satellite run reports them).

    Returns:
        ``triggers`` (number of impulses), ``kinds`` (count per kind), ``total_dv`` (sum of
        impulse magnitudes [m/s], summed in order), ``min_inter_event_h`` and
        ``mean_inter_event_h`` (intervals between successive impulses [h]; ``None`` with
        fewer than two impulses).

    """
    imp = log.impulses
    n = int(imp["t"].size) if "t" in imp else 0
    kinds: dict[str, int] = {}
    for k in (imp["kind"] if n else []):
        kinds[str(k)] = kinds.get(str(k), 0) + 1
    total = 0.0
    if n:
        dv = np.column_stack([imp["dv_x"], imp["dv_y"], imp["dv_z"]])
        total = float(sum(float(np.linalg.norm(v)) for v in dv))
    iet = np.asarray(imp["interval_s"][1:], dtype=float) / 3600.0 if n else np.zeros(0)
    return {
        "triggers": n,
        "kinds": kinds,
        "total_dv": total,
        "min_inter_event_h": float(iet.min()) if iet.size else None,
        "mean_inter_event_h": float(iet.mean()) if iet.size else None,
    }


RUN_FIGURES: tuple[str, ...] = ("min_h", "r_min_over_R", "r_max_over_R", "simulated_h", "left_band_h",
                                 "band_exits", "miet_bound_h")
"""Exact figures of an impulsive run taken from its logged summary (the samples miss extremes)."""


def replay_metrics(log: RunLog) -> dict[str, Any]:
    """Recompute a run's metrics from its logged columns, without simulating.

    Returns:
        Arm (and other sampled-data) runs: the fields of
        :class:`~isf_robot.core.metrics.DutyCycleMetrics` plus ``min_barrier`` (minimum of the
        logged true-geometry minima); a team run (several arms) adds ``arms``, each arm's figures
        (:func:`arm_metrics`). Impulsive (satellite) runs: only the figures that apply to
        them, :func:`impulse_metrics` (from the logged impulses), ``min_barrier`` and
        :data:`RUN_FIGURES` as the run computed them on its whole trajectory (from the logged
        summary; ``min_barrier_source`` says ``"run"``, or ``"samples"`` when a summary lacks
        ``min_h`` and the minimum over the logged samples is given instead), and ``duration_s``.

    """
    s = log.steps
    if log.kind == "satellite":
        summary = log.summary or {}
        out: dict[str, Any] = dict(impulse_metrics(log))
        exact = summary.get("min_h")
        out["min_barrier"] = float(exact) if exact is not None else _min_or_none(s["min_barrier"])
        out["min_barrier_source"] = "run" if exact is not None else "samples"
        out.update({k: summary[k] for k in RUN_FIGURES if k in summary})
        sim_h = summary.get("simulated_h")
        out["duration_s"] = 3600.0 * float(sim_h) if sim_h is not None else (float(s["t"][-1]) if s["t"].size
                                                                              else 0.0)
        return out
    m = compute_metrics(s["t"], s["dt"], s["on"], s["intervention_rate"], s["qp_solved"])
    out = m.as_dict()
    out["min_barrier"] = _min_or_none(np.concatenate([s["min_barrier"], log.terminal]))
    if log.arms:
        out["arms"] = arm_metrics(log)
    return out


def arm_metrics(log: RunLog) -> list[dict[str, Any]]:
    """Each arm's figures of a team recording, recomputed from its replay columns (empty for one arm).

    Per arm: ``name``, the fields of :class:`~isf_robot.core.metrics.DutyCycleMetrics` (its own filter's
    duty cycle, switches, off periods, and the intervention over its own joints), and ``min_barrier``
    (the smallest barrier of its collision pairs at the control ticks).
    """
    out = []
    for name, a in log.arms.items():
        m = compute_metrics(a["t"], a["dt"], a["on"], a["intervention_rate"], a["qp_solved"])
        out.append({"name": name, **m.as_dict(), "min_barrier": _min_or_none(a["min_barrier"])})
    return out


def format_table(rows: Sequence[tuple[str, Mapping[str, Any]]], keys: Sequence[str] | None = None) -> str:
    """Side-by-side table: one column per recording, one row per metric.

    Args:
        rows: ``(label, metrics)`` per recording.
        keys: Metric keys to show (default: :data:`METRIC_KEYS`, plus impulse figures when present).

    """
    if keys is None:
        keys = list(METRIC_KEYS) + ["qp_solves", "duration_s"]
        if any("triggers" in m for _, m in rows):
            keys = ["triggers", "total_dv", "min_inter_event_h", "mean_inter_event_h", "min_barrier",
                    "duration_s"]
    body = [[k] + [format_value(m.get(k)) for _, m in rows] for k in keys]
    return report_table(["metric"] + [label for label, _ in rows], body, align_first_only=True)
