"""Event location that cannot miss a crossing between integrator steps.

``solve_ivp`` finds an event only when the event function changes sign between two step points:
a trigger that dips below zero and recovers within one step (up to ``max_step``) is missed. Here
every step's dense output is scanned with a **rate bound**: if ``|dg/dt| <= L`` on ``[a, b]``
and ``g(a), g(b)`` have the same strict sign, then ``g`` keeps that sign on the whole interval
whenever

    |g(a)| + |g(b)| > L (b - a),

because a zero at ``t*`` needs ``|g(a)| <= L (t* - a)`` and ``|g(b)| <= L (b - t*)`` (the bound is
used only up to the first zero and from the last one, so it need only hold where the trajectory
is still inside the region the bound was derived for). Intervals that are not certified are
halved, left half first, down to ``min_dt``; an interval whose end values show the event's sign
change is a bracket, solved by Brent's method on the step's interpolant (the same equation and
tolerance ``solve_ivp`` uses, so a crossing it finds is located identically).

Guarantee and its limits: with a valid rate bound, no sign change of ``g`` along the step's
interpolant longer than ``min_dt`` goes unseen; the interpolant itself agrees with the solution
to the integrator's tolerance. A bracket with a sign change is taken to hold one crossing of its
sign (as ``solve_ivp`` does); for the triggers here the first falling crossing is what matters and
the scan is left to right, so none precedes it unseen. Without a rate bound an event falls back
to ``solve_ivp``'s rule (step points only).

:func:`integrate` is the integration loop (DOP853 steps, ``solve_ivp``'s conventions for
``t``, ``y``, ``t_events``, ``y_events``, ``status``, ``sol``), :func:`event` declares an event.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["EventFn", "RateBound", "BatchFn", "Event", "event", "ArcSolution", "integrate", "brackets"]

EventFn = Callable[[float, NDArray[np.float64]], float]
"""An event function ``g(t, y)``."""

RateBound = Callable[[NDArray[np.float64], NDArray[np.float64], Any], Any]
"""``L(y_a, y_b, dt)``: an upper bound on ``|dg/dt|`` over an interval of length ``dt`` [s] whose
end states are ``y_a`` and ``y_b``."""

BatchFn = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]
"""``g`` at many points: ``(t (k,), y (6, k)) -> (k,)``."""

_EPS = float(np.finfo(float).eps)
_MAX_GRID = 256


@dataclass(frozen=True)
class Event:
    """An event: the function, whether it stops the arc, its direction and its rate bound.

    Attributes:
        fn: ``g(t, y)``.
        terminal: Stop the arc at the first crossing.
        direction: ``-1`` falling (``g`` from >= 0 to <= 0), ``+1`` rising, ``0`` both.
        rate: Rate bound of ``g`` (certified scan), or ``None`` (step points only). Called with
            states of shape (6,) or (6, k) and ``dt`` a float or shape (k,).
        batch: ``g`` at many points, ``(t (k,), y (6, k)) -> (k,)``, or ``None`` (a loop over
            ``fn``); must agree with ``fn``.
        code: The compiled form of ``fn`` and ``rate`` for :mod:`satellite.orbit.fast_arcs`,
            ``(kind, parameter, extra)``, or ``None`` (the arcs that watch it run in Python).

    """

    fn: EventFn
    terminal: bool
    direction: float
    rate: RateBound | None = None
    batch: BatchFn | None = None
    code: tuple[int, float, Any] | None = None

    def __call__(self, t: float, y: NDArray[np.float64]) -> float:
        """``g(t, y)``."""
        return self.fn(t, y)


def event(
    fn: EventFn, terminal: bool, direction: float, rate: RateBound | None = None, batch: BatchFn | None = None,
    code: tuple[int, float, Any] | None = None,
) -> Event:
    """Declare an event (see :class:`Event`)."""
    return Event(fn, bool(terminal), float(direction), rate, batch, code)


def _active(ga: float, gb: float, direction: float) -> bool:
    """Whether ``g`` crosses zero from ``ga`` to ``gb`` in the event's direction (``solve_ivp``'s rule)."""
    up = ga <= 0.0 <= gb
    down = ga >= 0.0 >= gb
    return (up and direction > 0) or (down and direction < 0) or ((up or down) and direction == 0)


def brackets(
    ev: Event, interp: Callable[[Any], NDArray[np.float64]], a: float, b: float,
    ga: float, gb: float, ya: NDArray[np.float64], yb: NDArray[np.float64], *,
    min_dt: float, first_only: bool,
) -> tuple[list[tuple[float, float]], int]:
    """Sub-intervals of ``[a, b]`` that hold a crossing of ``ev``, in time order.

    Args:
        ev: The event (its rate bound drives the scan; without one only ``[a, b]`` is tested).
        interp: The step's dense output, ``t -> y``.
        a: Start [s].
        b: End [s], > ``a``.
        ga: ``g`` at ``a``.
        gb: ``g`` at ``b``.
        ya: State at ``a``.
        yb: State at ``b``.
        min_dt: Shortest interval that is split [s].
        first_only: Stop at the first bracket (terminal events).

    Returns:
        ``(brackets, evaluations)``: the brackets ``(a_k, b_k)`` and the number of interior
        points evaluated.

    """
    out: list[tuple[float, float]] = []
    if _active(ga, gb, ev.direction):
        return [(a, b)], 0
    if ev.rate is None or _certified(ev, ga, gb, ya, yb, b - a):
        return out, 0
    # a grid fine enough that most of its cells are certified at once, evaluated in one call
    need = float(ev.rate(ya, yb, b - a)) * (b - a) / max(abs(ga) + abs(gb), 1e-300)
    n = int(min(_MAX_GRID, max(2, math.ceil(need))))
    ts = np.linspace(a, b, n + 1)
    ys = np.empty((len(ya), n + 1))
    ys[:, 0], ys[:, -1] = ya, yb
    ys[:, 1:-1] = interp(ts[1:-1])
    gs = np.empty(n + 1)
    gs[0], gs[-1] = ga, gb
    if ev.batch is not None:
        gs[1:-1] = ev.batch(ts[1:-1], ys[:, 1:-1])
    else:
        gs[1:-1] = [ev.fn(float(t), ys[:, k + 1]) for k, t in enumerate(ts[1:-1])]
    evals = n - 1
    ok = (gs[:-1] * gs[1:] > 0.0) & (
        np.abs(gs[:-1]) + np.abs(gs[1:]) > np.asarray(ev.rate(ys[:, :-1], ys[:, 1:], np.diff(ts))) * np.diff(ts))
    stack = [(float(ts[k]), float(ts[k + 1]), float(gs[k]), float(gs[k + 1]), ys[:, k], ys[:, k + 1])
             for k in range(n - 1, -1, -1) if not ok[k]]
    while stack:
        a0, b0, g0, g1, y0, y1 = stack.pop()
        if _active(g0, g1, ev.direction):
            out.append((a0, b0))
            if first_only:
                break
            continue
        if b0 - a0 <= min_dt or _certified(ev, g0, g1, y0, y1, b0 - a0):
            continue
        m = 0.5 * (a0 + b0)
        ym = interp(m)
        gm = float(ev.fn(m, ym))
        evals += 1
        stack.append((m, b0, gm, g1, ym, y1))
        stack.append((a0, m, g0, gm, y0, ym))
    return out, evals


def _certified(ev: Event, ga: float, gb: float, ya: NDArray[np.float64], yb: NDArray[np.float64], dt: float) -> bool:
    """Whether ``g`` has no zero on an interval of length ``dt``: ``|g_a| + |g_b| > L dt``, same sign."""
    return ga * gb > 0.0 and abs(ga) + abs(gb) > float(ev.rate(ya, yb, dt)) * dt  # type: ignore[misc]


@dataclass
class ArcSolution:
    """Result of :func:`integrate`, with ``solve_ivp``'s attribute names.

    Attributes:
        t: Step points [s], shape (n,) (the last one the stop time).
        y: States at ``t``, shape (6, n).
        t_events: Per event, the crossing times [s], shape (k_i,).
        y_events: Per event, the states at the crossings, shape (k_i, 6).
        status: 0 reached the end time, 1 a terminal event stopped the arc.
        nfev: Right-hand-side evaluations (steps and dense outputs).
        sol: Dense output over the arc (an ``OdeSolution``), or ``None`` when not kept.
        scan_points: Interior points evaluated by the certified scan.

    """

    t: NDArray[np.float64]
    y: NDArray[np.float64]
    t_events: list[NDArray[np.float64]]
    y_events: list[NDArray[np.float64]]
    status: int
    nfev: int
    sol: Any = None
    scan_points: int = 0
    message: str = field(default="")


class IntegrationFailed(RuntimeError):
    """The step-size control failed (carries the time and the solver's message)."""

    def __init__(self, t: float, message: str) -> None:
        super().__init__(message)
        self.t = t


def integrate(
    rhs: Callable[[float, NDArray[np.float64]], NDArray[np.float64]], t0: float, t1: float,
    y0: NDArray[np.float64], events: Sequence[Event], *, rtol: float, atol: float, max_step: float,
    dense: bool = False, min_dt: float = 1e-2,
) -> ArcSolution:
    """Integrate ``y' = rhs(t, y)`` from ``t0`` to ``t1`` (DOP853), locating events without misses.

    Same steps, same interpolants and, for crossings ``solve_ivp`` sees, the same event times as
    ``solve_ivp(rhs, (t0, t1), y0, method="DOP853", ...)``; in addition every event with a rate
    bound is scanned inside each step (see the module docstring).

    Raises:
        IntegrationFailed: The integrator failed (e.g. step size underflow).

    """
    from scipy.integrate import DOP853, OdeSolution  # here: importing scipy.integrate costs ~0.5 s at start

    solver = DOP853(rhs, float(t0), np.asarray(y0, dtype=float), float(t1), rtol=rtol, atol=atol,
                    max_step=max_step)
    ts, ys, interps = [solver.t], [solver.y.copy()], []
    g = [float(e(solver.t, solver.y)) for e in events]
    t_events: list[list[float]] = [[] for _ in events]
    y_events: list[list[NDArray[np.float64]]] = [[] for _ in events]
    status = None
    scan = 0
    while status is None:
        msg = solver.step()
        if solver.status == "failed":
            raise IntegrationFailed(float(solver.t), str(msg))
        if solver.status == "finished":
            status = 0
        t_old, t, y = float(solver.t_old), float(solver.t), solver.y
        step = _LazyDense(solver)
        g_new = [float(e(t, y)) for e in events]
        found: list[tuple[float, int]] = []
        if t > t_old:
            for i, e in enumerate(events):
                brs, n = brackets(e, step, t_old, t, g[i], g_new[i], ys[-1], y, min_dt=min_dt,
                                  first_only=e.terminal)
                scan += n
                whole = _root(e, step, t_old, t) if brs and _active(g[i], g_new[i], e.direction) else None
                for a, b in brs:
                    root = whole if whole is not None and a <= whole <= b else _root(e, step, a, b)
                    found.append((root, i))
        found.sort()
        stop = next((k for k, (_, i) in enumerate(found) if events[i].terminal), None)
        if stop is not None:
            found = found[: stop + 1]
        for root, i in found:
            t_events[i].append(root)
            y_events[i].append(step(root))
        if stop is not None:
            status = 1
            t = found[-1][0]
            y = step(t)
        g = g_new
        if len(ts) > 1 and ts[-1] == t:
            continue  # a terminal event at the step's start (as solve_ivp: no empty segment)
        if dense:
            interps.append(step.get())
        ts.append(t)
        ys.append(np.array(y, dtype=float))
    dense_sol = OdeSolution(np.array(ts), interps) if dense and interps else None
    return ArcSolution(
        t=np.array(ts), y=np.vstack(ys).T,
        t_events=[np.asarray(x) for x in t_events],
        y_events=[np.asarray(x, dtype=float).reshape(len(x), len(ys[0])) for x in y_events],
        status=status, nfev=int(solver.nfev), sol=dense_sol, scan_points=scan,
    )


class _LazyDense:
    """The current step's dense output, computed on first use (it costs 3 extra evaluations)."""

    def __init__(self, solver: Any) -> None:
        self.solver = solver
        self.sol: Any = None

    def get(self) -> Any:
        """The step's ``DenseOutput``."""
        if self.sol is None:
            self.sol = self.solver.dense_output()
        return self.sol

    def __call__(self, t: Any) -> NDArray[np.float64]:
        sol = self.get()
        if isinstance(t, float) and hasattr(sol, "F"):  # DOP853's interpolant, one point (scipy's formula)
            x = (t - sol.t_old) / sol.h
            y = np.zeros_like(sol.y_old)
            for i, f in enumerate(sol.F[::-1]):
                y += f
                y *= x if i % 2 == 0 else 1.0 - x
            return y + sol.y_old  # type: ignore[no-any-return]
        return sol(t)  # type: ignore[no-any-return]


def _root(ev: Event, sol: Callable[[float], NDArray[np.float64]], a: float, b: float) -> float:
    """The crossing in ``[a, b]``: ``solve_ivp``'s equation and tolerance (Brent, 4 eps)."""
    from scipy.optimize import brentq

    return float(brentq(lambda t: ev.fn(t, sol(t)), a, b, xtol=4 * _EPS, rtol=4 * _EPS))
