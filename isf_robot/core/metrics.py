"""Duty-cycle and intervention metrics of a filtered run.

Conventions (the same code computes a live run's figures and a replayed log's):

* Step k holds over ``[t_k, t_k + dt_k)`` with mode ``on_k``.
* ``duty_cycle = sum(dt_k on_k) / sum(dt_k)``: fraction of time the filter is on.
* ``on_switches``: off-to-on transitions (a run that starts on counts one).
* Off periods are the *complete* ones: from an off-switch to the next on-switch. The stretch
  before the first on-switch and one cut by the end of the run are not inter-event times in
  the sense of the paper's MIET, so ``mean_off_s``/``min_off_s`` exclude them (``None`` when
  there is no complete off period). On periods likewise.
* ``intervention = sum_k |u_k - u_nom,k|^2 dt_k``.
* ``short_offs``: complete off periods shorter than :data:`CHATTER_OFF_S` (chatter).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .exceptions import ShapeError
from .sums import row_sq_sums, sq_sum

__all__ = ["CHATTER_OFF_S", "DutyCycleMetrics", "FilterStats", "compute_metrics", "MetricsAccumulator"]

CHATTER_OFF_S = 0.25
"""Shortest off period [s] that is not chatter: an intermittent filter whose complete off periods fall
under it is switching faster than an arm's motion changes (``short_offs`` counts them)."""

_F64 = np.dtype(np.float64)
_CHUNK = 1 << 16  # steps kept as tuples before they are packed into arrays
_BATCH = 256  # steps whose intervention and jump are made together (MetricsAccumulator.add_step)
_COLUMNS = (("t", float), ("dt", float), ("on", bool), ("intervention_rate", float), ("qp_solved", bool))


@dataclass(frozen=True)
class DutyCycleMetrics:
    """Summary of a run's filter activity (see the module docstring for definitions)."""

    duration_s: float
    control_steps: int
    duty_cycle: float
    on_switches: int
    off_switches: int
    mean_on_s: float | None
    min_on_s: float | None
    mean_off_s: float | None
    min_off_s: float | None
    max_off_s: float | None
    intervention: float
    qp_solves: int
    short_offs: int = 0

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready)."""
        return asdict(self)


@dataclass(frozen=True)
class FilterStats:
    """What the filter's solver did over a run (live runs only; a replayed log has no QPs).

    Attributes:
        fallbacks: Steps whose command came from the infeasibility fallback.
        relaxations: Steps where promotions were relaxed to the robust condition.
        resolves: Steps where a screened-out row was needed, so the QP was solved again with
            every row (screening never changes a command).
        qp_closed_form: QP solves answered by the one-row closed form (within the input bounds, if any).
        qp_time_median_us: Median wall time of a step's QP work [us] (every solve of the step,
            polish and checks included), ``None`` without QPs.
        solver_time_median_us: The same over the steps that went to the QP backend (not the
            closed form) [us].
        switch_jump_max: Largest step in the command at a mode switch, ``|u_k - u_{k-1}|`` over
            the steps with a switch event (``None`` without switches) [command units].
        jump_max: Largest ``|u_k - u_{k-1}|`` over every step (the nominal's own changes included).
        off_bound_min_s: Smallest designed off-period bound reported at an off switch
            (:attr:`~isf_robot.core.filters.FilterStep.off_bound_s`; ``None``: none reported,
            ``inf``: no fall of ``Xi_on`` measured yet) [s]; compare with ``min_off_s``.

    """

    fallbacks: int = 0
    relaxations: int = 0
    resolves: int = 0
    qp_closed_form: int = 0
    qp_time_median_us: float | None = None
    solver_time_median_us: float | None = None
    switch_jump_max: float | None = None
    jump_max: float | None = None
    off_bound_min_s: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready)."""
        return asdict(self)


def _periods(t_end: np.ndarray, on: np.ndarray, t_start: np.ndarray, want_on: bool) -> np.ndarray:
    """Lengths of complete runs of ``on == want_on`` bounded by switches on both sides."""
    n = on.shape[0]
    if n == 0:
        return np.zeros(0)
    change = np.flatnonzero(on[1:] != on[:-1]) + 1  # indices where a new run starts
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [n]])  # exclusive
    out = []
    for s, e in zip(starts, ends):
        if bool(on[s]) != want_on or s == 0 or e == n:
            continue  # wrong mode, or cut by the start / end of the run
        out.append(t_end[e - 1] - t_start[s])
    return np.asarray(out, dtype=float)


def compute_metrics(
    t: np.ndarray,
    dt: np.ndarray | float,
    on: np.ndarray,
    intervention_rate: np.ndarray,
    qp_solved: np.ndarray | int,
) -> DutyCycleMetrics:
    """Compute :class:`DutyCycleMetrics` from per-step arrays.

    Args:
        t: Step times [s], shape (N,), non-decreasing.
        dt: Step lengths [s], shape (N,) or a scalar.
        on: Filter mode per step, shape (N,) bool.
        intervention_rate: ``|u - u_nom|^2`` per step, shape (N,).
        qp_solved: Per-step bool array of QP solves, shape (N,), or a total count.

    """
    t = np.asarray(t, dtype=float)
    n = t.shape[0]
    on = np.asarray(on, dtype=bool)
    dt_arr = np.full(n, float(dt)) if np.ndim(dt) == 0 else np.asarray(dt, dtype=float)
    rate = np.asarray(intervention_rate, dtype=float)
    if on.shape != (n,) or dt_arr.shape != (n,) or rate.shape != (n,):
        raise ShapeError(f"t, dt, on and intervention_rate must all have shape ({n},)")
    solves = int(qp_solved) if np.ndim(qp_solved) == 0 else int(np.count_nonzero(qp_solved))
    total = float(np.sum(dt_arr))
    t_end = t + dt_arr
    off_p = _periods(t_end, on, t, want_on=False)
    on_p = _periods(t_end, on, t, want_on=True)
    starts_on = int(np.count_nonzero(on[1:] & ~on[:-1])) + (1 if n and on[0] else 0)
    ends_on = int(np.count_nonzero(~on[1:] & on[:-1])) if n else 0

    def stat(arr: np.ndarray, fn: Any) -> float | None:
        return float(fn(arr)) if arr.size else None

    return DutyCycleMetrics(
        duration_s=total,
        control_steps=n,
        duty_cycle=float(np.sum(dt_arr[on]) / total) if total > 0 else 0.0,
        on_switches=starts_on,
        off_switches=ends_on,
        mean_on_s=stat(on_p, np.mean),
        min_on_s=stat(on_p, np.min),
        mean_off_s=stat(off_p, np.mean),
        min_off_s=stat(off_p, np.min),
        max_off_s=stat(off_p, np.max),
        intervention=float(np.sum(rate * dt_arr)),
        qp_solves=solves,
        short_offs=int(np.count_nonzero(off_p < CHATTER_OFF_S)),
    )


class MetricsAccumulator:
    """Collects per-step data during a run and computes :class:`DutyCycleMetrics` at the end.

    Memory is about 26 bytes per step (26 MB per million steps): the steps are appended as tuples
    (the cheapest per step) and packed into arrays every ``_CHUNK`` steps.

    :meth:`add_step` keeps the commands of up to ``_BATCH`` steps (and their nominal commands where
    they differ) as their bytes (``tobytes``: a copy of the values, cheaper than writing an array's row) and
    makes their figures -- ``|u - u_nom|^2`` and the jump ``|u_k - u_{k-1}|^2`` -- when the batch is full or
    read, in step order: the same products on the same numbers as step by step (a row of the batch's
    difference is the difference of the two commands, and its ``dot`` numpy's), but in one warm pass instead
    of five numpy calls inside every control step.
    """

    def __init__(self) -> None:
        self._steps: list[tuple[float, float, bool, bool]] = []  # (t, dt, on, solved)
        self._rates: list[float] = []  # |u - u_nom|^2 of those steps (a batch's: added when it is made)
        self._packed: list[dict[str, np.ndarray]] = []  # earlier steps, as arrays
        self._n_packed = 0
        self._qp_times: list[float] = []
        self._solver_times: list[float] = []
        self._fallbacks = self._relaxations = self._resolves = self._closed_form = 0
        self._u_prev: np.ndarray | None = None
        self._jump2: float | None = None  # largest |u_k - u_{k-1}|^2 (its root is the largest jump: sqrt is monotone)
        self._switch_jump2: float | None = None
        self._off_bound: float | None = None
        self._ub: list[bytes] | None = None  # the batch's commands (bytes of float64 vectors); None: no batch
        self._nb: list[bytes] = []  # the nominal commands of the batch's steps with u not u_nom, in step order
        self._u0 = b""  # the command before the batch
        self._shape: tuple[int, ...] = ()  # the batch's command shape
        self._rix: list[int] = []  # batch rows of the steps with u not u_nom
        self._ev: list[int] = []  # batch rows of the steps with a switch event

    def add(self, t: float, dt: float, on: bool, u: np.ndarray, u_nom: np.ndarray, solved: bool) -> None:
        """Record one step."""
        self._flush()  # (the batch's steps first: their figures go to the columns in step order)
        rate = sq_sum(u - u_nom)  # (sums' written order: the same figure on every machine)
        self._steps.append((t, dt, bool(on), bool(solved)))
        self._rates.append(rate)
        if len(self._steps) >= _CHUNK:
            self._pack()

    def add_step(self, step: Any, dt: float) -> None:
        """Record a :class:`~isf_robot.core.filters.FilterStep` (and its solver figures).

        The same figures as :meth:`add` and the bookkeeping below it, in one call (it runs every
        control step; a command that is ``u_nom`` itself has intervention 0 without a product).
        """
        qp, u, u_nom = step.qp, step.u, step.u_nom
        if type(u) is not np.ndarray or u.dtype != _F64:
            u = np.asarray(u, dtype=float)
        same = u is u_nom
        ub = self._ub
        if ub is not None and u.shape == self._shape and (
                same or type(u_nom) is np.ndarray and u_nom.dtype == _F64 and u_nom.shape == u.shape):
            ub.append(u.tobytes())  # (into the batch: the figures when it is made)
            n = len(ub)
            if not same:
                self._nb.append(u_nom.tobytes())
                self._rix.append(n)
            if step.event is not None:
                self._ev.append(n)
            self._steps.append((step.t, dt, bool(step.on), qp is not None))
            if n == _BATCH:
                self._flush()
                if len(self._steps) >= _CHUNK:
                    self._pack()
        else:  # (the first step, or a command of another shape: step by step)
            self._flush()
            rate = 0.0
            if not same:
                rate = sq_sum(u - u_nom)
            self._steps.append((step.t, dt, bool(step.on), qp is not None))
            self._rates.append(rate)
            prev = self._u_prev
            self._u_prev = u.copy()
            if prev is not None:
                self._jump(sq_sum(u - prev), step.event is not None)
            if u.ndim == 1:  # (a new batch after this step)
                self._ub, self._shape, self._u0 = [], u.shape, u.tobytes()
            else:
                self._ub = None
            if len(self._steps) >= _CHUNK:
                self._pack()
        if qp is not None:
            self._qp_times.append(qp.solve_time_s)
            if qp.status == "closed_form":
                self._closed_form += 1
            else:
                self._solver_times.append(qp.solve_time_s)
        if step.fallback:
            self._fallbacks += 1
        if step.relaxed:
            self._relaxations += 1
        if getattr(step, "resolved", False):
            self._resolves += 1
        bound = getattr(step, "off_bound_s", None)
        if bound is not None:
            self._off_bound = bound if self._off_bound is None else min(self._off_bound, bound)

    def _jump(self, jump2: float, switch: bool) -> None:
        """Account one step's jump ``|u_k - u_{k-1}|^2`` (``switch``: the step has a switch event)."""
        if self._jump2 is None or jump2 > self._jump2:
            self._jump2 = jump2
        if switch and (self._switch_jump2 is None or jump2 > self._switch_jump2):
            self._switch_jump2 = jump2

    def _flush(self) -> None:
        """Make the batch's figures, in step order, and start the next batch after its last command."""
        ub = self._ub
        if not ub:
            return
        n, width = len(ub), self._shape[0]
        U = np.frombuffer(b"".join((self._u0, *ub)), dtype=_F64).reshape(n + 1, width)  # row 0: the one before
        d = U[1:] - U[:n]  # row j: command j + 1 minus command j (elementwise, exact)
        jumps = row_sq_sums(d).tolist()  # (each row's sq_sum, in one pass)
        top = self._jump2
        for v in jumps:  # (as _jump, step by step)
            if top is None or v > top:
                top = v
        self._jump2 = top
        top = self._switch_jump2
        for row in self._ev:
            v = jumps[row - 1]
            if top is None or v > top:
                top = v
        self._switch_jump2 = top
        rix, rates = self._rix, [0.0] * n  # (the batch's steps' rates, in step order: 0 where u is u_nom)
        if rix:
            N = np.frombuffer(b"".join(self._nb), dtype=_F64).reshape(len(rix), width)
            r = U[rix] - N  # (the steps with u not u_nom: u - u_nom)
            for row, v in zip(rix, row_sq_sums(r).tolist()):
                rates[row - 1] = v
            rix.clear()
            self._nb.clear()
        self._rates += rates
        self._ev.clear()
        self._u0 = ub[-1]
        self._u_prev = U[n].copy()
        ub.clear()

    def stats(self) -> FilterStats:
        """The solver figures of the steps recorded with :meth:`add_step`."""
        self._flush()
        def med(v: list[float]) -> float | None:
            return float(np.median(v)) * 1e6 if v else None

        def root(v: float | None) -> float | None:
            return None if v is None else math.sqrt(v)

        return FilterStats(self._fallbacks, self._relaxations, self._resolves, self._closed_form,
                           med(self._qp_times), med(self._solver_times), root(self._switch_jump2),
                           root(self._jump2), self._off_bound)

    def __len__(self) -> int:
        return self._n_packed + len(self._steps)

    def _columns(self) -> dict[str, np.ndarray]:
        """The steps not packed yet, as arrays (the batch's figures made)."""
        self._flush()
        t, dt, on, solved = tuple(zip(*self._steps)) if self._steps else ((),) * 4
        cols = (t, dt, on, self._rates, solved)
        return {name: np.asarray(col, dtype=dtype) for (name, dtype), col in zip(_COLUMNS, cols)}

    def _pack(self) -> None:
        self._packed.append(self._columns())
        self._n_packed += len(self._steps)
        self._steps.clear()
        self._rates.clear()

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded per-step arrays: t, dt, on, intervention_rate, qp_solved."""
        parts = [*self._packed, self._columns()]
        return {name: np.concatenate([p[name] for p in parts]) for name, _ in _COLUMNS}

    def result(self) -> DutyCycleMetrics:
        """Compute the metrics of everything recorded so far."""
        a = self.arrays()
        return compute_metrics(a["t"], a["dt"], a["on"], a["intervention_rate"], a["qp_solved"])
