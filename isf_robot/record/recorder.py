"""The base Rerun recorder: a core :class:`~isf_robot.core.hooks.Observer` that logs a run.

:class:`RerunRecorder` logs what every run has: metadata, the per-step replay columns (the
inputs of :func:`~isf_robot.core.metrics.compute_metrics`), the filter mode, the minimum
barrier value, and each switch or jump event (structured and as a text log). Subclasses
(:class:`~isf_robot.record.arm.ArmRecorder`,
:class:`~isf_robot.record.satellite.SatelliteRecorder`) add their 3-D content by overriding
:meth:`RerunRecorder.start_content`, :meth:`RerunRecorder.step_content` and
:meth:`RerunRecorder.event_content`, and say how to read a step record by overriding
:meth:`RerunRecorder.replay_row`.

Everything per step goes through a :class:`~isf_robot.record.buffer.ColumnBuffer`, so the
cost per step is a few array writes; the stream is closed (file footer written) by
:meth:`RerunRecorder.close`, which ``on_finish`` calls.
"""

from __future__ import annotations

import gc
import json
import weakref
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pyarrow as pa
import rerun as rr

from isf_robot import __version__
from isf_robot.core.hooks import Observer
from isf_robot.support.report import to_jsonable

from . import schema
from .buffer import Channel, ColumnBuffer
from .errors import RecordError, defer_error
from .stream import close_stream

__all__ = ["RerunRecorder", "any_values", "to_jsonable", "finite_scalars", "value_columns"]


_GC_HOLD = [0, False]  # (recorders between on_start and close; whether their first on_start froze the collector)


def hold_collector() -> None:
    """Keep the garbage collector's full passes off what lived before the run (until :func:`release_collector`).

    Importing rerun and pyarrow leaves some 35k long-lived objects on the collector's oldest generation
    and its counters close to a full pass: that pass, during the run, scanned every object of the process
    (60-170 ms on a 2-core machine: a third of a 10 s arm run). While a recorder runs, the objects that
    lived before it started (modules, the scene, the model) are frozen (:func:`gc.freeze`); the run's own
    objects are collected as usual, and :func:`release_collector` hands the frozen ones back
    (:func:`gc.unfreeze`), so nothing is kept past the run. Left alone when the process froze objects of
    its own or disabled the collector.
    """
    if _GC_HOLD[0] == 0:
        _GC_HOLD[1] = gc.isenabled() and gc.get_freeze_count() == 0
        if _GC_HOLD[1]:
            gc.freeze()
    _GC_HOLD[0] += 1


def release_collector() -> None:
    """End one :func:`hold_collector` (the last one unfreezes what the first froze)."""
    if _GC_HOLD[0] == 0:
        return
    _GC_HOLD[0] -= 1
    if _GC_HOLD[0] == 0 and _GC_HOLD[1]:
        _GC_HOLD[1] = False
        gc.unfreeze()


class _CollectorHold:
    """One recorder's :func:`hold_collector`, released once (at close, or when the recorder is dropped unclosed)."""

    def __init__(self) -> None:
        self.held = True
        hold_collector()

    def release(self) -> None:
        if self.held:
            self.held = False
            release_collector()


def value_columns(**fields: np.ndarray | Sequence[str]) -> Any:
    """``rr.AnyValues.columns`` of 1-D numeric or bool arrays (or lists of strings), one value per row.

    The same columns as ``rr.AnyValues.columns(**fields)`` (a list of one value per row), built as
    Arrow list arrays in one go: Rerun's own conversion makes a Python list per value.
    """
    out = {}
    for name, values in fields.items():
        v = pa.array(np.ascontiguousarray(values).reshape(-1) if isinstance(values, np.ndarray) else list(values))
        out[name] = pa.ListArray.from_arrays(pa.array(np.arange(len(v) + 1, dtype=np.int32)), v)
    return rr.AnyValues.columns(**out)



_ARROW_TYPES = ((bool, pa.bool_()), (int, pa.int64()), (float, pa.float64()), (str, pa.string()))


def any_values(**fields: Any) -> rr.AnyValues:
    """``rr.AnyValues(**fields)``, each plain value made an Arrow array of its type here.

    Plain: bool, int, float, a non-empty str, a 1-D numeric array. The same components as Rerun's (the
    types it infers for them); its own inference of a value costs some 0.4 ms the first time in a process
    (about 10 ms for a run's settings). Other values are left to Rerun.
    """
    out: dict[str, Any] = {}
    for name, v in fields.items():
        typ = next((t for kind, t in _ARROW_TYPES if type(v) is kind), None)
        if typ is not None and v != "":  # (an empty text: Rerun drops the field; left to it)
            out[name] = pa.array([v], type=typ)
        elif isinstance(v, np.ndarray) and v.ndim == 1 and v.dtype.kind in "biuf":
            out[name] = pa.array(v)
        else:
            out[name] = v
    return rr.AnyValues(**out)


def finite_scalars(t: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, Any] | None:
    """``(t, Scalars columns)`` of the rows whose value is finite (``None`` if there is none)."""
    ok = np.isfinite(values)
    if not ok.any():
        return None
    if ok.all():
        return t, rr.Scalars.columns(scalars=values)
    return t[ok], rr.Scalars.columns(scalars=values[ok])


def _event_columns(rows: list[tuple[float, str, int, float, float]]) -> Any:
    t, kind, index, xi, dur = zip(*rows)
    return value_columns(
        t=np.asarray(t, dtype=np.float64),
        kind=kind,
        index=np.asarray(index, dtype=np.int64),
        xi=np.asarray(xi, dtype=np.float64),
        duration_s=np.asarray(dur, dtype=np.float64),
    )


def _text_columns(rows: list[tuple[str, str]]) -> Any:
    text, level = zip(*rows)
    return rr.TextLog.columns(text=list(text), level=list(level))


class RerunRecorder(Observer):
    """Log a run to an explicit Rerun recording stream.

    Args:
        stream: The recording stream (see :func:`~isf_robot.record.stream.open_stream`).
        kind: Recording kind stored in ``/run/info`` (``"arm"``, ``"satellite"``, ...).
        capacity: Rows buffered per channel before a ``send_columns`` call.
        close_on_finish: Close the stream in ``on_finish`` (writes the file footer).

    """

    kind = "generic"
    INFO_OBJECTS: tuple[str, ...] = ()
    """Start-info keys holding live objects (e.g. the MuJoCo model): used, not stored in ``/run/info``."""

    def __init__(
        self,
        stream: rr.RecordingStream,
        *,
        kind: str | None = None,
        capacity: int = 2048,
        close_on_finish: bool = True,
    ) -> None:
        self.stream = stream
        if kind is not None:
            self.kind = kind
        self.buffer = ColumnBuffer(stream, capacity)
        self.close_on_finish = close_on_finish
        self.closed = False
        self._hold: _CollectorHold | None = None  # (between on_start and close: see hold_collector)
        self.error: RecordError | None = None  # a file that could not be written (see on_finish)
        self.steps = 0
        self.events = 0
        self._steps = self.make_step_channel()
        self._events = self.buffer.ragged(schema.EVENTS, _event_columns)
        self._log = self.buffer.ragged(schema.EVENT_LOG, _text_columns)

    def make_step_channel(self) -> Channel | None:
        """The per-step channel: the replay columns, plus the mode and minimum-barrier plots.

        Subclasses may return ``None`` and build a wider channel whose flush derives the same
        entities (see :class:`~isf_robot.record.arm.ArmRecorder`), with :meth:`on_step`
        overridden.
        """
        fields = {
            "t": ((), np.float64), "dt": ((), np.float64), "on": ((), np.bool_),
            "intervention_rate": ((), np.float64), "qp_solved": ((), np.bool_),
            "min_barrier": ((), np.float64),
        }
        return self.buffer.channel(schema.STEPS, fields, value_columns,
                                   derived=self.step_plots())

    @staticmethod
    def step_plots() -> tuple[tuple[str, Any], ...]:
        """Derived entities of the replay columns: ``/plots/mode`` and ``/plots/barrier/min``."""
        return (
            (f"{schema.PLOTS}/mode", lambda t, a: (t, rr.Scalars.columns(scalars=a["on"].astype(np.float64)))),
            (f"{schema.PLOTS}/barrier/min", lambda t, a: finite_scalars(t, a["min_barrier"])),
        )

    # -- observer hooks ------------------------------------------------------------------
    def versions(self) -> dict[str, str]:
        """Versions stored with the recording: isf_robot and rerun (subclasses add their engine)."""
        return {"isf_robot": __version__, "rerun": str(rr.__version__)}

    def on_start(self, info: Mapping[str, Any]) -> None:
        """Log the run's metadata (static) and the subclass's static content.

        ``/run/info`` holds every start-info entry but the live objects (:attr:`INFO_OBJECTS`)
        plus ``versions`` (:meth:`versions`); the versions and the scalar settings are also
        recording properties, which the viewer shows beside the recording.
        """
        if self._hold is None or not self._hold.held:  # (a recorder of several runs: held again for each)
            self._hold = _CollectorHold()
            weakref.finalize(self, self._hold.release)  # (a recorder dropped without close: released all the same)
        try:
            self._log_start(info)
        except BaseException:
            self._release()
            raise

    def _log_start(self, info: Mapping[str, Any]) -> None:
        meta = to_jsonable({k: v for k, v in info.items() if k not in self.INFO_OBJECTS})
        meta.setdefault("versions", self.versions())
        self.stream.log(schema.INFO, any_values(kind=self.kind, info_json=json.dumps(meta)), static=True)
        self.stream.send_property("versions", any_values(**meta["versions"]))
        # As text, under names of their own: Rerun fixes the type of an AnyValues field name at its
        # first use in a process (runs differ, 5 vs 5.0; and /replay/steps has a float "dt").
        settings = {f"setting_{k}": str(v) for k, v in meta.items()
                    if isinstance(v, (str, int, float, bool)) and k != "kind"}
        if settings:
            self.stream.send_property("run", any_values(**settings))
        self.stream.log(f"{schema.PLOTS}/mode", rr.SeriesLines(names="filter on"), static=True)
        self.stream.log(f"{schema.PLOTS}/barrier/min", rr.SeriesLines(names="min h", colors=[220, 40, 40]),
                        static=True)
        self.start_content(info)

    def on_step(self, record: Any) -> None:
        """Buffer the step's replay row, mode, minimum barrier and the subclass's content."""
        t, dt, on, rate, solved, h_min = self.replay_row(record)
        assert self._steps is not None  # the base class always has its step channel
        self._steps.push(t, t, dt, on, rate, solved, h_min)
        self.step_content(t, record)
        self.steps += 1

    def on_event(self, event: Any) -> None:
        """Buffer a switch or jump event (structured row and text line)."""
        t = float(event.t)
        kind = str(getattr(event, "kind", "event"))
        index = int(getattr(event, "index", self.events + 1))
        xi = getattr(event, "xi_min", getattr(event, "xi_before", float("nan")))
        dur = getattr(event, "duration_s", getattr(event, "interval_s", None))
        xi = float("nan") if xi is None else float(xi)
        dur_f = float("nan") if dur is None else float(dur)
        self._events.push(t, (t, kind, index, xi, dur_f))
        self._log.push(t, (self.describe_event(event), "INFO"))  # every kind at one level: all shown alike
        self.event_content(t, event)
        self.events += 1

    def on_finish(self, summary: Mapping[str, Any]) -> None:
        """Flush the buffers, log the summary (static) and close the stream if configured."""
        self.stream.log(schema.SUMMARY, any_values(summary_json=json.dumps(to_jsonable(summary)),
                                                     steps=self.steps, events=self.events), static=True)
        self.buffer.flush()
        self.finish_content(summary)
        self.buffer.flush()
        self._release()
        if self.close_on_finish:
            try:
                self.close()
            except RecordError as exc:  # the run's results are not lost for it: reported after them
                self.error = exc
                defer_error(exc)

    def close(self, *, complete: bool = True) -> None:
        """Flush whatever is buffered and close the stream (idempotent).

        ``complete=False`` (the run failed or was interrupted): the file keeps its
        ``.partial`` name and an existing recording under the target name is left as it was.
        """
        self._release()
        if self.closed:
            return
        self.closed = True
        try:
            self.buffer.flush()
        finally:
            close_stream(self.stream, complete=complete)

    def _release(self) -> None:
        if self._hold is not None:
            self._hold.release()

    def on_abort(self, reason: BaseException) -> None:
        """The run stopped early: close without completing (the data stays in ``<name>.partial``)."""
        self.close(complete=False)

    # -- what subclasses give --------------------------------------------------------------
    def replay_row(self, record: Any) -> tuple[float, float, bool, float, bool, float]:
        """Extract ``(t, dt, on, |u - u_nom|^2, qp_solved, min_barrier)`` from a step record.

        The default reads attributes ``t``, ``dt``, ``on``, then ``intervention_rate`` or
        ``u``/``u_nom``, then ``qp_solved`` (or ``solved_qp``), then ``min_barrier`` (or
        ``h_min``).
        """
        rate = getattr(record, "intervention_rate", None)
        if rate is None:
            d = np.asarray(record.u, dtype=float) - np.asarray(record.u_nom, dtype=float)
            rate = float(d @ d)
        solved = getattr(record, "qp_solved", getattr(record, "solved_qp", False))
        h_min = getattr(record, "min_barrier", getattr(record, "h_min", float("nan")))
        return (float(record.t), float(record.dt), bool(record.on), float(rate), bool(solved), float(h_min))

    def describe_event(self, event: Any) -> str:
        """One text line for the event log."""
        kind = getattr(event, "kind", "event")
        t = float(event.t)
        dur = getattr(event, "duration_s", None)
        extra = "" if dur is None else f" after {float(dur):.4g} s"
        return f"t = {t:.6g} s: {kind} #{getattr(event, 'index', '?')}{extra}"

    def start_content(self, info: Mapping[str, Any]) -> None:
        """Log static content (geometry, ...); default: nothing."""

    def step_content(self, t: float, record: Any) -> None:
        """Buffer per-step content; default: nothing."""

    def event_content(self, t: float, event: Any) -> None:
        """Log per-event content (arrows, ...); default: nothing."""

    def finish_content(self, summary: Mapping[str, Any]) -> None:
        """Log end-of-run content; default: nothing."""
