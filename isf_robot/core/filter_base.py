"""What both safety filters share: ``Xi_on`` of every row, the filter QP with screening, its solve paths, the policy.

The filters' semantics (when they are on, which rows they promote) are in
:mod:`isf_robot.core.filters`. A filter step here:

1. ``Xi_on`` of every row (:func:`~isf_robot.core.robust.xi_pass`), checked finite;
2. the rows kept by screening (:mod:`isf_robot.core.screening`) and their bounds
   (:func:`~isf_robot.core.robust.row_bounds`: robust, promoted or ramped);
3. one of three solve paths: the closed form for one row or for a few rows without input bounds
   (:mod:`isf_robot.core.projection`, with the bounds and step 4 in one call:
   :mod:`isf_robot.core.closed_step`; the standard filter runs steps 1 to 4 in that one call, the
   intermittent filter's on step the choice of its promoted rows and steps 2 to 4), else
   the QP (:class:`~isf_robot.core.qp_solver.QPSolver`); promotions relaxed to the robust condition
   when the promoted QP is infeasible;
4. the rows screened out checked at the answer (solved again with every row when one binds);
5. the infeasibility policy.

Each pass is one plain function, compiled by numba where it runs
(:func:`~isf_robot.core.jit.compiled`; ``ISF_ROBOT_JIT=0`` runs it as written, read when the
filter is built); for float64 C-contiguous inputs and a linear class-K function its compiled code is
called without numba's per-call dispatch (:mod:`isf_robot.core.passes`).
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import replace
from operator import itemgetter
from typing import NamedTuple

import numpy as np

from . import projection, qp_check
from .barrier import Barrier, evaluate_barriers
from .class_k import ClassK, Linear, as_class_k
from .exceptions import ConfigError, InfeasibleFilterError, IsfWarning, NonFiniteError, ShapeError, SolverError
from .jit import compiled
from .passes import DirectPasses, Passes
from .projection import FEW_ROWS
from .qp import FilterQP, QPResult
from .qp_solver import QPSolver
from .spec import FilterSpec
from .step import FilterStep
from .switches import SwitchCounter
from .system import ControlAffineSystem, LieData, lie_data
from .validation import as_vector, check_finite_scalar

__all__ = ["FilterStep", "FallbackFn"]  # (FilterStep: from .step, where it lives)

FallbackFn = Callable[[float, "np.ndarray | None", LieData, QPResult], np.ndarray]

_F64 = np.dtype(np.float64)
_NONE_B = np.zeros(0, bool)  # "no promoted rows"
_NONE_F = np.zeros(0)  # "no thresholds" / "every ramp weight 1"
_KINDS = ("robust", "promote")  # a row's kind by its promotion flag
_ACTIVE: dict[int, tuple[np.ndarray, ...]] = {}  # n rows' activity masks by their bits, shared (read-only)
_tuple_new = tuple.__new__  # (builds a _Xi without its generated __new__)
_NO_CLOSED = (None, False, False)  # "no closed-form answer" (see _FilterBase._solve_rows)


def _masks(n: int) -> tuple[np.ndarray, ...]:
    """Every activity mask of ``n`` rows, read-only, indexed by its bits (bit ``i``: row ``i`` active)."""
    out = []
    for bits in range(1 << n):
        mask = np.array([bool(bits >> i & 1) for i in range(n)])
        mask.flags.writeable = False
        out.append(mask)
    return tuple(out)


class _Xi(NamedTuple):
    """A step's checked ``Xi_on`` (:meth:`_FilterBase._xi`)."""

    u_nom: np.ndarray
    xi: np.ndarray
    xi_min: float
    av: np.ndarray  # alpha(h) per row
    argmin: int  # first row of least Xi_on
    passes: Passes  # the passes these inputs take (compiled, or as written)
    closed: tuple[QPResult, bool, bool] | None  # the robust rows' closed form (_closed_result) with Xi_on, if answered


class _FilterBase:
    uses_rows = True
    intermittent = False

    def __init__(
        self,
        alpha: ClassK | float | Callable[[float], float],
        d_bar: float = 0.0,
        *,
        system: ControlAffineSystem | None = None,
        barriers: Sequence[Barrier] | None = None,
        u_min: Sequence[float] | np.ndarray | None = None,
        u_max: Sequence[float] | np.ndarray | None = None,
        solver: QPSolver | None = None,
        on_infeasible: str = "raise",
        fallback: FallbackFn | None = None,
        validate: bool = True,
        screen: float | np.ndarray | None = None,
    ) -> None:
        self.validate = bool(validate)
        self.alpha = as_class_k(alpha)
        self.spec = FilterSpec(alpha=self.alpha, d_bar=d_bar)  # (the intermittent filter's holds its options too)
        self.d_bar = self.spec.d_bar
        self.system = system
        self.barriers = list(barriers) if barriers is not None else None
        if self.barriers is not None and len(self.barriers) == 0:
            raise ConfigError("barriers must hold at least one barrier (or be None for step_lie)")
        self.u_min = None if u_min is None else as_vector(u_min, "u_min")
        self.u_max = None if u_max is None else as_vector(u_max, "u_max")
        if self.u_min is not None and self.u_max is not None:
            if self.u_min.shape != self.u_max.shape:
                raise ShapeError(f"u_min {self.u_min.shape} and u_max {self.u_max.shape} differ in shape")
            if np.any(self.u_min > self.u_max):
                raise ConfigError(f"u_min must be <= u_max elementwise, got {self.u_min} and {self.u_max}")
        if system is not None:
            for name, bd in (("u_min", self.u_min), ("u_max", self.u_max)):
                if bd is not None and bd.shape != (system.m,):
                    raise ShapeError(f"{name} must have shape ({system.m},), got {bd.shape}")
        self.solver = solver if solver is not None else QPSolver()
        if on_infeasible not in ("raise", "fallback"):
            raise ConfigError(f"on_infeasible must be 'raise' or 'fallback', got {on_infeasible!r}")
        self.on_infeasible = on_infeasible
        if fallback is not None and not callable(fallback):
            raise ConfigError("fallback must be callable fallback(t, x, lie, qp_result) -> u")
        self.fallback = fallback
        self.screen = self._check_screen(screen)
        self._passes = Passes.build()  # (ISF_ROBOT_JIT is read when the filter is built)
        self._plain = Passes.build(False)  # (inputs the compiled passes do not take: other dtypes, no inputs)
        self._direct = DirectPasses(self._passes)  # (the compiled passes for inputs of fixed types: _passes_for)
        self._closed = self._closed_forms()  # (the solver's options and the bounds are read when the filter is built)
        self._lo = qp_check.NO_BOUND if self.u_min is None else self.u_min  # (the closed steps' bounds: length 0 none)
        self._hi = qp_check.NO_BOUND if self.u_max is None else self.u_max
        self._within = compiled(projection.within_bounds)  # (ISF_ROBOT_JIT is read here)
        self._rows_buf = np.empty(256, np.intp)
        self._res_buf = np.empty(FEW_ROWS)
        self._screens: dict[float, np.ndarray] = {}
        self._all: dict[int, np.ndarray] = {}
        self.qp_solves = 0
        self._switches = SwitchCounter()

    def _check_screen(self, screen: float | np.ndarray | None) -> float | np.ndarray | None:
        if screen is None:
            return None
        arr = np.asarray(screen, dtype=float)
        if arr.ndim > 1 or np.any(~(arr > self.solver.active_tol)):
            raise ConfigError(f"screen thresholds must be one number or one per row, each > the solver's "
                              f"active_tol ({self.solver.active_tol:g}) (or inf), got {screen}")
        return float(arr) if arr.ndim == 0 else arr

    def _screen_array(self, screen: float | np.ndarray, k: int) -> np.ndarray:
        """Thresholds as the passes take them: one for every row, or one per row of ``k``."""
        if type(screen) is np.ndarray and screen.dtype is _F64 and screen.ndim == 1 and screen.flags.c_contiguous:
            sa = screen
        elif type(screen) is float:
            sa = self._screens.get(screen)
            if sa is None:
                sa = self._screens[screen] = np.full(1, screen)
        else:  # (C-contiguous float64, as the passes take them: passes.DirectPasses)
            sa = np.ascontiguousarray(screen, dtype=float).reshape(-1)
        if sa.shape[0] != k and sa.shape[0] != 1:
            raise ShapeError(f"screen thresholds: one, or one per row ({k}); got {sa.shape[0]}")
        return sa

    # -- inputs --------------------------------------------------------------------------
    def lie(self, t: float, x: np.ndarray) -> LieData:
        """Evaluate the configured barriers and system at ``(t, x)``."""
        if self.system is None or self.barriers is None:
            raise ConfigError("step(t, x, u_nom) needs system= and barriers=; otherwise call step_lie()")
        x = as_vector(x, "state x", self.system.n)
        ev = evaluate_barriers(self.barriers, x, t)
        return lie_data(ev, self.system.f0(x, t), self.system.g(x, t))

    def step(self, t: float, x: np.ndarray, u_nom: np.ndarray) -> FilterStep:
        """Filter ``u_nom`` at state ``x`` and time ``t`` [s]."""
        t = check_finite_scalar(t, "t")
        x = as_vector(x, "state x", self.system.n if self.system else None)
        return self.step_lie(t, self.lie(t, x), u_nom, x=x)

    def step_lie(self, t: float, lie: LieData, u_nom: np.ndarray, x: np.ndarray | None = None, *,
                 screen: float | np.ndarray | None = None) -> FilterStep:
        """Filter ``u_nom`` given precomputed barrier data (see the subclasses)."""
        raise NotImplementedError

    def _within_bounds(self, u: np.ndarray) -> bool:
        """``u`` satisfies the input bounds the filter was given (true without bounds; a NaN entry: false).

        :func:`~isf_robot.core.projection.within_bounds`, compiled for float64 commands.
        """
        lo, hi = self._lo, self._hi
        if (lo.shape[0] and lo.shape != u.shape) or (hi.shape[0] and hi.shape != u.shape):
            raise ShapeError(f"a command of shape {u.shape} against input bounds of shape {lo.shape}, {hi.shape}")
        if u.dtype == np.float64 and u.shape[0]:
            return bool(self._within(u, lo, hi))
        return bool(projection.within_bounds(u, lo, hi))

    def _closed_forms(self) -> bool:
        """Whether the closed steps serve: the solver's closed forms, and its ``few_rows`` when there are input bounds.

        With bounds a closed step's answer is kept only when it satisfies them (no bound active: the bounded optimum
        too); the solver's own closed forms follow the same rule (:class:`~isf_robot.core.qp_solver.QPSolver`).
        Read once, when the filter is built (``_closed``): not in every step.
        """
        solver = self.solver
        return solver.closed_form and (solver.few_rows or (self.u_min is None and self.u_max is None))

    def _passes_for(self, lie: LieData, u_nom: np.ndarray) -> Passes:
        """The compiled passes for float64 data with inputs; the plain ones otherwise (numpy decides).

        Called without numba's dispatch (:class:`DirectPasses`) where every array is C-contiguous and of one
        dimension (``Lg h`` two) and the class-K function linear: the types those calls were resolved for.
        """
        lg, h, lf, gn = lie.lg, lie.h, lie.lf, lie.grad_norm
        f64 = _F64
        if (lg.dtype is f64 and u_nom.dtype is f64 and h.dtype is f64 and lf.dtype is f64
                and gn.dtype is f64 and lg.ndim == 2 and u_nom.shape[0] and lg.flags.c_contiguous):
            if (type(self.alpha) is Linear and h.ndim == 1 and lf.ndim == 1 and gn.ndim == 1 and u_nom.ndim == 1
                    and h.flags.c_contiguous and lf.flags.c_contiguous and gn.flags.c_contiguous
                    and u_nom.flags.c_contiguous):
                return self._direct  # type: ignore[return-value]
            return self._passes
        return self._plain

    def _xi(self, t: float, lie: LieData, u_nom: np.ndarray, screen: float | np.ndarray | None = None,
            closed: bool = False) -> _Xi:
        """Checked inputs, ``Xi_on`` per row, its minimum and ``alpha(h)``.

        ``closed``: also the robust rows' closed form (of the rows :meth:`_solve_rows` keeps without
        promotions, ``screen`` their thresholds) in the same compiled call
        (:func:`~isf_robot.core.closed_step.xi_closed_step`) where the closed forms serve
        (:meth:`_closed_forms`; with input bounds, an answer within them): the field ``closed`` when it
        answered (else ``None``). A non-finite input raises NonFiniteError (a finite ``Xi_on`` also means
        finite ``Lg h`` and ``u_nom``).
        """
        if self.validate:
            lie.validate()
            u_nom = as_vector(u_nom, "nominal command u_nom", lie.m)
        h = lie.h
        k = h.shape[0]
        if k == 0:
            return _tuple_new(_Xi, (u_nom, np.zeros(0), math.inf, np.zeros(0), -1, self._plain, None))
        alpha = self.alpha
        gain = alpha.gain if type(alpha) is Linear else 0.0
        av = np.empty(k) if gain > 0.0 else np.asarray(alpha.vector(h), dtype=float)
        rows = self._rows_buf
        if rows.shape[0] < k:
            rows = self._rows_buf = np.empty(2 * k, np.intp)
        xi = np.empty(k)
        passes = self._passes_for(lie, u_nom)
        solver = self.solver
        if closed and self._closed:
            sa = _NONE_F if screen is None or k < 2 else self._screen_array(screen, k)
            u = np.empty(u_nom.shape[0])
            t0 = time.perf_counter()
            total, low, arg, kept, n, code, slack, held, bits = passes.xi_closed_step(
                lie.lf, lie.lg, u_nom, lie.grad_norm, self.d_bar, h, gain, av, sa, xi, rows, _NONE_B, _NONE_F,
                solver.feas_tol, solver.active_tol, solver.few_rows, self._lo, self._hi, u, self._res_buf)
            short = self._closed_result(u_nom, u, code, slack, held, n, bits, t0) if code >= 0 else None
        else:  # (no thresholds: _solve_rows finds the rows it keeps)
            total, low, arg, _ = passes.xi_pass(lie.lf, lie.lg, u_nom, lie.grad_norm, self.d_bar, h, gain, av, _NONE_F,
                                                xi, rows)
            short = None
        if not math.isfinite(total):
            raise NonFiniteError(f"barrier data or nominal command not finite at t={t:.6g}: "
                                 f"Xi_on = {xi}, u_nom = {u_nom}")
        return _tuple_new(_Xi, (u_nom, xi, float(low), av, int(arg), passes, short))

    # -- the QP's rows -------------------------------------------------------------------
    def qp_lower(self, lie: LieData, promote: np.ndarray | None = None, b: float = 0.0,
                 ramp: float | np.ndarray = 1.0) -> np.ndarray:
        """The QP's lower bounds ``lb`` (rows ``Lg h u >= lb``): robust, or promoting where ``promote`` is True.

        ``ramp`` in [0, 1) (a number, or one per row) lowers the promotion level to ``max(-alpha(h), ramp b + (1 - ramp)
        (-alpha(h)))`` (the hand-over after an on switch; never below the robust condition).
        """
        k = lie.h.shape[0]
        ramp_arr = _NONE_F if np.all(np.asarray(ramp) >= 1.0) else np.broadcast_to(
            np.asarray(ramp, dtype=float), (k,)).copy()
        return self._plain.row_bounds(self._all_rows(k), lie.lf, lie.grad_norm, self.d_bar,
                                      np.asarray(self.alpha.vector(lie.h), dtype=float),
                                      _NONE_B if promote is None else promote, ramp_arr, b)

    def build_qp(self, lie: LieData, u_nom: np.ndarray, promote: np.ndarray | None = None, b: float = 0.0,
                 ramp: float | np.ndarray = 1.0) -> FilterQP:
        """Build the filter QP: robust rows, or promoting rows where ``promote`` is True (see :meth:`qp_lower`)."""
        kinds: tuple[str, ...] = ()
        if promote is not None and promote.any():
            kinds = tuple(map(_KINDS.__getitem__, promote.tolist()))
        return FilterQP._of(u_nom, lie.lg, self.qp_lower(lie, promote, b, ramp), self.u_min, self.u_max,
                            kinds, lie.names)

    def _all_rows(self, k: int) -> np.ndarray:
        rows = self._all.get(k)
        if rows is None:
            rows = self._all[k] = np.arange(k, dtype=np.intp)
        return rows

    # -- solving -------------------------------------------------------------------------
    def _solve(self, qp: FilterQP) -> QPResult:
        """Solve; under the fallback policy a failing solver counts as an infeasible problem."""
        self.qp_solves += 1
        try:
            return self.solver.solve(qp)
        except SolverError:
            if self.on_infeasible != "fallback":
                raise
            try:
                viol, u = self.solver.least_violation(qp)
            except SolverError:
                u, viol = qp.u_nom.copy(), qp.max_violation(qp.u_nom)
            return QPResult(u, "solver_failed", np.ones(qp.k, bool), 0.0, 0, viol)

    def _solve_rows(
        self, t: float, x: np.ndarray | None, lie: LieData, u_nom: np.ndarray, xi: np.ndarray, av: np.ndarray,
        promote: np.ndarray | None, ramp: np.ndarray, b: float, floor: float,
        screen: float | np.ndarray | None = None, xs: _Xi | None = None,
    ) -> tuple[QPResult, tuple[str, ...], bool, bool]:
        """Solve with screening; return ``(result, relaxed names, fallback, resolved)``.

        ``xi``: each row's robust slack at ``u_nom`` (``Xi_on``, or the slack at a blended target);
        ``xs``: the step's :meth:`_xi` when ``xi`` is its ``Xi_on`` (its closed form then serves, if it
        made one); ``floor``: the thresholds are at least this (the off margin); promoted rows are
        always kept. The rows (:func:`~isf_robot.core.screening.screened_rows`) and their closed form are
        one compiled call (:func:`~isf_robot.core.closed_step.screened_closed_step`) where the closed
        forms serve.
        """
        k = xi.shape[0]
        passes = xs.passes if xs is not None else self._passes_for(lie, u_nom)
        short: tuple[QPResult | None, bool, bool]
        if xs is not None and xs.closed is not None and promote is None and not floor > 0.0:
            short, rows = xs.closed, None  # (made with Xi_on for the same rows, and answered: no rows needed below)
        else:
            if screen is None:
                screen = self.screen
            sa = _NONE_F if screen is None or k < 2 else self._screen_array(screen, k)
            prom, arg = _NONE_B if promote is None else promote, -1 if xs is None else xs.argmin
            buf, solver = self._rows_buf, self.solver
            if self._closed:
                u = np.empty(u_nom.shape[0])
                t0 = time.perf_counter()
                n, code, low, held, bits = passes.screened_closed_step(
                    xi, sa, floor, prom, arg, buf, lie.lf, lie.grad_norm, self.d_bar, av, ramp, b, lie.lg, u_nom,
                    solver.feas_tol, solver.active_tol, solver.few_rows, self._lo, self._hi, u, self._res_buf)
                short = self._closed_result(u_nom, u, code, low, held, n, bits, t0) if code >= 0 else _NO_CLOSED
            else:
                n, short = passes.screened_rows(xi, sa, floor, prom, arg, buf), _NO_CLOSED
            rows = None if n == k else buf[:n]
        return self._rows_solved(t, x, lie, u_nom, xi, av, promote, ramp, b, passes, rows, short)

    def _rows_solved(self, t: float, x: np.ndarray | None, lie: LieData, u_nom: np.ndarray, xi: np.ndarray,
                     av: np.ndarray, promote: np.ndarray | None, ramp: np.ndarray, b: float, passes: Passes,
                     rows: np.ndarray | None,
                     short: tuple[QPResult | None, bool, bool]) -> tuple[QPResult, tuple[str, ...], bool, bool]:
        """:meth:`_solve_rows` after the screening: ``rows`` kept (``None``: every row), ``short`` their closed form.

        The closed form's answer when every other row holds at it; else the rows' QP (when the closed form gave
        none), checked on the rows screened out; every row solved when one of those binds.
        """
        first = short[0]
        if first is not None and short[1]:
            return first, (), False, False
        if first is None:
            first, relaxed, fb = self._solve_block(t, x, lie, u_nom, av, promote, ramp, b, rows, passes)
            if rows is None or fb or passes.others_hold(xi, lie.lg, first.u - u_nom, rows, self.solver.active_tol):
                return first, relaxed, fb, False
        # a screened row binds at the answer: every row
        res, relaxed, fb = self._solve_block(t, x, lie, u_nom, av, promote, ramp, b, None, passes)
        return replace(res, solve_time_s=res.solve_time_s + first.solve_time_s), relaxed, fb, True

    def _closed_result(self, u_nom: np.ndarray, u: np.ndarray, code: int, low: float, held: bool, n: int, bits: int,
                       t0: float) -> tuple[QPResult, bool, bool]:
        """``(result, every other row holds, a row is active)`` of a closed-form answer (``code`` >= 0) on ``n`` rows.

        ``t0``: when its solve began.

        ``bits``: the active rows (:func:`~isf_robot.core.closed_step.active_bits`); the result's ``active``
        is a shared read-only mask.
        """
        spent = time.perf_counter() - t0
        self.qp_solves += 1
        masks = _ACTIVE.get(n)
        if masks is None:
            masks = _ACTIVE[n] = _masks(n)
        if n == 1:
            return QPResult._of(u_nom if code == 0 else u, "closed_form", masks[bits], spent), bool(held), bits != 0
        return QPResult._of(u, "optimal", masks[bits], spent, 0, max(0.0, -float(low))), bool(held), bits != 0

    def _solve_block(
        self, t: float, x: np.ndarray | None, lie: LieData, u_nom: np.ndarray, av: np.ndarray,
        promote: np.ndarray | None, ramp: np.ndarray, b: float, rows: np.ndarray | None, passes: Passes,
    ) -> tuple[QPResult, tuple[str, ...], bool]:
        """The rows ``rows`` of ``lie`` (``None``: all), promoting where asked; relaxed to robust if infeasible.

        The closed forms first (one row; a few rows with the solver's ``few_rows``), then the QP; the
        infeasibility policy when the robust QP is infeasible too.
        """
        k = lie.h.shape[0]
        idx = self._all_rows(k) if rows is None else rows
        prom = _NONE_B if promote is None else promote
        lb = passes.row_bounds(idx, lie.lf, lie.grad_norm, self.d_bar, av, prom, ramp, b)
        A = lie.lg if rows is None else lie.lg.take(rows, 0)
        names = lie.names
        if rows is not None and names:
            picked, nn = rows.tolist(), len(names)
            if len(picked) > 1 and max(picked) < nn:  # (every row named: one call)
                names = itemgetter(*picked)(names)
            else:
                names = tuple(names[i] if i < nn else str(i) for i in picked)
        marks = prom[idx] if promote is not None and prom.any() else None  # (the rows' promotion flags, if any)
        promoted = marks is not None and bool(marks.any())
        kinds = tuple(map(_KINDS.__getitem__, marks.tolist())) if promoted else ()  # type: ignore[union-attr]
        qp = FilterQP._of(u_nom, A, lb, self.u_min, self.u_max, kinds, names)
        res = self._solve(qp)
        relaxed: tuple[str, ...] = ()
        if not res.ok and promoted:
            local = np.flatnonzero(prom[idx])
            relaxed_idx = tuple(int(i) for i in idx[local])
            nn = len(lie.names)
            relaxed = tuple(lie.names[i] if i < nn else str(i) for i in relaxed_idx)
            lb = passes.row_bounds(idx, lie.lf, lie.grad_norm, self.d_bar, av, _NONE_B, _NONE_F, b)
            qp = FilterQP._of(u_nom, A, lb, self.u_min, self.u_max, (), names)
            spent = res.solve_time_s
            res = self._solve(qp)
            res = replace(res, solve_time_s=res.solve_time_s + spent, relaxed=relaxed_idx)
        if res.ok:
            return res, relaxed, False
        return self._infeasible(t, x, lie, qp, res), relaxed, True

    def _infeasible(self, t: float, x: np.ndarray | None, lie: LieData, qp: FilterQP, res: QPResult) -> QPResult:
        if self.on_infeasible == "raise":
            raise InfeasibleFilterError(
                f"safety filter infeasible at t={t:.6g}: no command satisfies the robust barrier "
                f"condition{' and the input bounds' if qp.has_bounds else ''} "
                f"(least violation {res.max_violation:.3g}; min h = {float(np.min(lie.h)):.4g})",
                qp=qp, state=x, barrier_values=lie.h.copy(), t=t,
            )
        u = res.u if self.fallback is None else as_vector(self.fallback(t, x, lie, res), "fallback command", lie.m)
        warnings.warn(
            f"safety filter infeasible at t={t:.6g}; applied the fallback command "
            f"(violation {qp.max_violation(u):.3g})", IsfWarning, stacklevel=5,
        )
        return QPResult(u, "fallback", res.active, res.solve_time_s, res.iterations, qp.max_violation(u), res.relaxed)

