"""Compiled arcs (numba, a dependency; ``ISF_ROBOT_JIT=0`` runs Python): the same integration, ~20x cheaper.

:func:`satellite.orbit.events.integrate` drives scipy's ``DOP853`` step by step from Python and scans
each step for events; at ~1 ms a step (about 13 right-hand-side calls of ~15 us, the step's
numpy glue, the scan's Python bisection) a 2400 h run took ~35 s. :class:`FastArcs` runs the
same algorithm in one compiled call per arc (:mod:`satellite.orbit.arc_kernel`): scipy's DOP853 step-size
control and interpolant, the certified scan with its bisection and Brent's method, the truth
right-hand side of a tabulated field (the shell B-spline, the fine boxes, Kepler, the spin), and
the band, apsis, contact and maneuver event functions with their rate bounds. The formulas are the
Python path's own functions, compiled (:mod:`satellite.orbit.kernel_parts` lists them), so the right-hand
side and the event values agree with the Python path's to a relative 1e-12 (in practice exactly: the Python
path calls the same compiled functions); scipy's DOP853 adds its stages by BLAS (``np.dot``) and the kernel
by loops, so step decisions, and event times, agree to the integrator's tolerance (a chaotic orbit's
long-run trajectory diverges from it as from any other rounding).

It is used when every event of an arc has a compiled form (:attr:`satellite.orbit.events.Event.code`)
and the field is a :class:`~satellite.gravity.table.GravityTable` whose near-surface correction is
its fine boxes (or none); otherwise the arc is integrated in Python. Outside the table's radii
(DOP853's stage and trial points of a step near the band's edges, an orbit past a band exit) both
paths use the table's radial continuation, one function compiled here
(:func:`satellite.gravity.table.shell_continued`), so an arc never leaves the compiled call for the
exact field. Without numba, or with ``ISF_ROBOT_JIT=0`` in the environment, everything runs in Python.

Ctrl-C and SIGTERM are held while numba compiles or runs (:func:`signals_deferred`) and act as soon as
the call returns: a ``KeyboardInterrupt`` raised inside numba (its compiler's ctypes callbacks, the
boxing of a compiled call's results, which calls Python) is swallowed there or comes out as a
``SystemError`` traceback, not as the command's one-line "interrupted".
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from isf_robot.core.jit import jit_enabled as core_jit_enabled
from satellite.control.tau import TauFit
from satellite.control.triggers import XI, XITAU
from satellite.gravity.fine import NO_BOXES
from satellite.gravity.table import GravityTable, table_acceleration
from satellite.orbit.events import ArcSolution, Event, IntegrationFailed

__all__ = ["FastArcs", "FastDense", "jit_enabled", "signals_deferred"]

_JIT: dict[str, Any] = {}


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM (their Python handlers) for the body; the held ones act when it ends.

    The handlers are swapped for one that only notes the signal, so no exception is raised inside
    numba's machinery (module docstring); on exit the original handlers are back and called for the
    noted signals, in order, which raises their ``KeyboardInterrupt``/``Terminated`` here. Signals
    with no Python handler (ignored, default) and threads other than the main one are left alone.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    saved: dict[int, Any] = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        if callable(signal.getsignal(sig)):
            saved[sig] = signal.signal(sig, lambda signum, _frame: held.append(signum))
    try:
        yield
    finally:
        for num, handler in saved.items():
            signal.signal(num, handler)
        for num in dict.fromkeys(held):
            saved[num](num, None)


def jit_enabled() -> bool:
    """Whether compiled arcs can be used (numba importable, ``ISF_ROBOT_JIT`` not ``0``, the formulas compiled)."""
    if not core_jit_enabled() or not hasattr(table_acceleration, "py_func"):
        return False
    if "arc" not in _JIT:
        try:
            from satellite.orbit import arc_kernel, kernel_parts  # (deferred: numba compiles or loads the kernels)
        except ImportError:
            _JIT["arc"] = None
        else:
            _JIT["arc"] = arc_kernel.arc
            _JIT["interp_many"] = kernel_parts.interp_many
    return _JIT["arc"] is not None


def _dop853_coefficients() -> Any:
    """The DOP853 coefficient module of scipy, read without importing ``scipy.integrate`` (~0.5 s at start).

    The module holds the published Dormand-Prince 8(5,3) tables and imports numpy only; when the file is
    not where scipy keeps it, the ordinary import.
    """
    if "coef" not in _JIT:
        import importlib.util
        from pathlib import Path

        spec = importlib.util.find_spec("scipy")
        path = Path(spec.origin).parent / "integrate" / "_ivp" / "dop853_coefficients.py" if spec and spec.origin \
            else None
        if path is not None and path.is_file():
            mspec = importlib.util.spec_from_file_location("_isf_dop853_coefficients", path)
            assert mspec is not None and mspec.loader is not None
            mod = importlib.util.module_from_spec(mspec)
            mspec.loader.exec_module(mod)
        else:  # pragma: no cover (another scipy layout)
            from scipy.integrate._ivp import dop853_coefficients as mod
        _JIT["coef"] = mod
    return _JIT["coef"]


def _pack_field(field: Any) -> tuple[Any, ...] | None:
    """The table's arrays for the kernel, or ``None`` when it has no compiled form."""
    if not isinstance(field, GravityTable) or (field.fine is None and field.near is not None):
        return None
    box_o, box_n, coef = field.fine.packed() if field.fine is not None else NO_BOXES
    return field.geom, field._ext, box_o, box_n, coef


class FastDense:
    """Dense output of a compiled arc (``OdeSolution``'s segment rule and the kernel's DOP853 interpolant).

    Args:
        ts: Step points [s], shape (n,).
        hs: Each segment's full step length [s], shape (n - 1,) (the last segment may end early,
            at a terminal event, inside its step).
        y_old: State at each segment's start, shape (n - 1, 6).
        F: Interpolant coefficients per segment, shape (n - 1, 7, 6).

    """

    def __init__(self, ts: NDArray[np.float64], hs: NDArray[np.float64], y_old: NDArray[np.float64],
                 F: NDArray[np.float64]) -> None:
        self.ts, self.hs, self.y_old, self.F = ts, hs, y_old, F

    def __call__(self, t: Any) -> NDArray[np.float64]:
        """States at ``t`` (float: shape (6,); array (k,): shape (6, k))."""
        tq = np.asarray(t, dtype=np.float64)
        scalar = tq.ndim == 0
        tt = np.atleast_1d(tq)
        seg = np.clip(np.searchsorted(self.ts, tt, side="left") - 1, 0, len(self.hs) - 1)
        y = np.empty((len(tt), 6))
        _JIT["interp_many"](tt, seg, self.ts, self.hs, self.y_old, self.F, y)
        return y[0] if scalar else y.T


class FastArcs:
    """Compiled arcs of one run (see the module docstring); :meth:`make` returns ``None`` when unusable.

    Args:
        model: The run's :class:`satellite.orbit.model.OrbitModel` (field, spin, body phase).
        trig: The band trigger values (band constants, alpha, rate bounds' ``A``).
        contact: The contact watch, or ``None``.

    """

    def __init__(self, model: Any, trig: Any, contact: Any, packed: tuple[Any, ...]) -> None:
        dc = _dop853_coefficients()
        geom, self.ext, self.box_o, self.box_n, self.coef = packed
        self.fp = np.array([model.body_phase, model.omega, model.disturbance_scale, *geom], dtype=np.float64)
        gain = float(getattr(trig.alpha, "gain", math.nan))
        self.bp = np.array([trig.r_centre, trig.h_max, trig.d_bar, trig.accel_bound or 0.0, trig.r_inner,
                            trig.r_outer, trig.half_width, gain, trig.alpha_slope], dtype=np.float64)
        if contact is not None:
            env = contact.envelope
            self.cp = np.array([contact.body_phase, contact.omega, env.d, env.n_lat, env.n_lon, env.max_radius,
                                env.min_radius, env.slope, contact.accel_bound], dtype=np.float64)
            self.env = np.ascontiguousarray(env.values, dtype=np.float64)
        else:
            self.cp, self.env = np.zeros(9), np.zeros((2, 2))
        self.coefs = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in (dc.A, dc.B, dc.C, dc.E3, dc.E5, dc.D))
        self._tp: dict[int, tuple[Any, NDArray[np.float64]]] = {}
        self._no_tau = np.array([0.0, 0.0, 1.0, 0.0])
        self.calls = 0
        self.fallbacks = 0

    @classmethod
    def make(cls, model: Any, trig: Any, contact: Any) -> FastArcs | None:
        """The compiled arcs of a run, or ``None`` (numba missing or off, or a field without compiled form)."""
        if not jit_enabled():
            return None
        packed = _pack_field(model.field)
        return cls(model, trig, contact, packed) if packed is not None else None

    def _tau(self, fit: Any) -> NDArray[np.float64] | None:
        """``tp`` of a maneuver fit (a polynomial in ``s = h / h_max``), or ``None``."""
        got = self._tp.get(id(fit))
        if got is not None and got[0] is fit:
            return got[1]

        if type(fit) is not TauFit:
            return None
        tp = fit.packed
        self._tp[id(fit)] = (fit, tp)
        return tp

    def integrate(self, t0: float, t1: float, y0: NDArray[np.float64], events: Sequence[Event], *, rtol: float,
                  atol: float, max_step: float, dense: bool, min_dt: float, scan: bool) -> ArcSolution | None:
        """One arc as :func:`satellite.orbit.events.integrate` (``scan``: use the events' rate bounds).

        Returns ``None`` when the arc needs the Python path (an event without compiled form, an
        empty or backward arc, a scan buffer overflow).

        Raises:
            IntegrationFailed: The step size underflowed.

        """
        if not t1 > t0:
            return None
        n = len(events)
        kinds = np.empty(n, dtype=np.int64)
        pars = np.empty(n)
        tp = self._no_tau
        for k, e in enumerate(events):
            code = e.code
            if code is None:
                return None
            kinds[k], pars[k] = code[0], code[1]
            if code[0] == XI and not math.isfinite(self.bp[7]):
                return None
            if code[0] == XITAU:
                got = self._tau(code[2])
                if got is None or (tp is not self._no_tau and got is not tp):
                    return None
                tp = got
        dirs = np.array([e.direction for e in events], dtype=np.float64)
        terms = np.array([e.terminal for e in events], dtype=np.bool_)
        rated = np.array([scan and e.rate is not None for e in events], dtype=np.bool_)
        self.calls += 1
        with signals_deferred():  # the first call compiles (~13 s without numba's cache)
            (status, t_fail, ts, ys, hs, Fs, ev_t, ev_i, ev_y, nfev, scanned) = _JIT["arc"](
                float(t0), float(t1), np.array(y0, dtype=np.float64), float(rtol), float(atol), float(max_step),
                float(min_dt), bool(dense), kinds, pars, dirs, terms, rated, self.fp, self.ext, self.box_o,
                self.box_n, self.coef, self.bp, self.cp, self.env, tp, *self.coefs)
        if status == -1:
            raise IntegrationFailed(float(t_fail), "Required step size is less than spacing between numbers.")
        if status < 0:
            self.fallbacks += 1
            return None
        idx = ev_i.astype(np.intp)
        t_events = [ev_t[idx == k] for k in range(n)]
        y_events = [ev_y[idx == k].reshape(-1, 6) for k in range(n)]
        sol = FastDense(ts, hs, ys[:-1], Fs) if dense and len(ts) > 1 else None
        return ArcSolution(t=ts, y=ys.T, t_events=t_events, y_events=y_events, status=int(status), nfev=int(nfev),
                           sol=sol, scan_points=int(scanned))
