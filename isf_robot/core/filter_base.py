"""What both safety filters share: the QP machinery (rows, screening, re-solve); the step result is in :mod:`.step`.

The filters' semantics (when they are on, which rows they solve) are in
:mod:`isf_robot.core.filters`; this module holds the parts they have in common: evaluating the
Lie data, building and solving the QP with row screening and the re-solve check, and the
infeasibility policy.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from .barrier import Barrier, evaluate_barriers
from .class_k import ClassK, as_class_k
from .exceptions import ConfigError, InfeasibleFilterError, IsfWarning, NonFiniteError, ShapeError, SolverError
from .fast import NO_SCREEN, screen_array, step_kernels, xi_kernel, xi_pass
from .filter_short import ShortWays
from .qp import FilterQP, QPResult
from .qp_small import FEW_ROWS
from .qp_solver import QPSolver
from .step import FilterStep
from .switches import SwitchCounter
from .system import ControlAffineSystem, LieData, lie_data
from .triggers import xi_on
from .validation import as_vector, check_finite_scalar, check_nonnegative

__all__ = ["FilterStep", "FallbackFn"]  # (FilterStep: from .step, where it lives)

_F64 = np.dtype(np.float64)
_BOOL = np.dtype(bool)
_NONE_B = np.zeros(0, bool)  # the selection kernel's "no promoted rows"

FallbackFn = Callable[[float, "np.ndarray | None", LieData, QPResult], np.ndarray]

_KINDS = ("robust", "promote")  # a row's kind by its promotion flag
_tuple_new = tuple.__new__  # (builds a _Xi without its generated __new__: 0.8 against 1.5 us)


class _Xi(NamedTuple):
    """A step's checked ``Xi_on`` (:meth:`_FilterBase._xi`)."""

    u_nom: np.ndarray
    xi: np.ndarray
    xi_min: float
    av: np.ndarray | None  # alpha(h) per row (None: a linear alpha, gain h_i where needed)
    argmin: int  # first row of least Xi_on (-1: not computed)
    kept: int  # rows with Xi_on below their screening threshold (-1: not counted)
    first: int  # the first of them (-1: none, or not counted)
    rows: np.ndarray | None  # when counted: those rows, ascending (the first ``kept``; the filter's buffer, one step)


class _FilterBase(ShortWays):
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
        self.d_bar = check_nonnegative(d_bar, "d_bar (disturbance bound)")
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
            for name, b in (("u_min", self.u_min), ("u_max", self.u_max)):
                if b is not None and b.shape != (system.m,):
                    raise ShapeError(f"{name} must have shape ({system.m},), got {b.shape}")
        self.solver = solver if solver is not None else QPSolver()
        if on_infeasible not in ("raise", "fallback"):
            raise ConfigError(f"on_infeasible must be 'raise' or 'fallback', got {on_infeasible!r}")
        self.on_infeasible = on_infeasible
        if fallback is not None and not callable(fallback):
            raise ConfigError("fallback must be callable fallback(t, x, lie, qp_result) -> u")
        self.fallback = fallback
        self.screen = self._check_screen(screen)
        self._kernel = xi_kernel()  # (ISF_ROBOT_JIT is read when the filter is built)
        self._steps = step_kernels()
        self._few_buf = np.empty((4, FEW_ROWS))
        self._rows_buf = np.empty(256, np.intp)  # (the xi kernel's kept rows, read within a step; more: a new array)
        self.qp_solves = 0
        self._switches = SwitchCounter()

    def _check_screen(self, screen: float | np.ndarray | None) -> float | np.ndarray | None:
        if screen is None:
            return None
        arr = np.asarray(screen, dtype=float)
        if np.any(~(arr > self.solver.active_tol)):
            raise ConfigError(f"screen thresholds must be > the solver's active_tol "
                              f"({self.solver.active_tol:g}) (or inf), got {screen}")
        return float(arr) if arr.ndim == 0 else arr

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
        """``u`` satisfies the input bounds the filter was given (true without bounds)."""
        return not ((self.u_min is not None and bool(np.any(u < self.u_min)))
                    or (self.u_max is not None and bool(np.any(u > self.u_max))))

    def _xi(self, t: float, lie: LieData, u_nom: np.ndarray, screen: float | np.ndarray | None = None) -> _Xi:
        """Checked inputs, ``Xi_on`` per row, its minimum and ``alpha(h)``; with ``screen``, the screening count.

        A non-finite input raises NonFiniteError (a finite ``Xi_on`` also means finite ``Lg h`` and
        ``u_nom``). The compiled kernel (:mod:`isf_robot.core.fast`) makes the same numbers in one
        pass for float64 vectors of one length; otherwise numpy (check and minimum on a list: a sum
        of NaN or inf is not finite, the minimum of finite floats is exact).
        """
        if self.validate:
            lie.validate()
            u_nom = as_vector(u_nom, "nominal command u_nom", lie.m)
        kernel = self._kernel
        if kernel is not None:
            sa = NO_SCREEN if screen is None else screen_array(screen, lie.h.shape[0])
            got = None if sa is None else xi_pass(kernel, lie, u_nom, self.alpha, self.d_bar, sa, self._rows_buf)
            if got is not None:
                xi, total, low, arg, kept, first, av, rows = got
                if not math.isfinite(total):
                    raise NonFiniteError(f"barrier data or nominal command not finite at t={t:.6g}: "
                                         f"Xi_on = {xi}, u_nom = {u_nom}")
                return _tuple_new(_Xi, (u_nom, xi, low, av, arg, kept, first, rows))
        alpha = self.alpha
        av = alpha.vector(lie.h)
        xi = xi_on(lie, u_nom, self.alpha, self.d_bar, av)
        xl = xi.tolist()
        if not math.isfinite(sum(xl)):
            raise NonFiniteError(f"barrier data or nominal command not finite at t={t:.6g}: "
                                 f"Xi_on = {xi}, u_nom = {u_nom}")
        return _tuple_new(_Xi, (u_nom, xi, min(xl) if xl else math.inf, av, -1, -1, -1, None))

    def build_qp(
        self, lie: LieData, u_nom: np.ndarray, promote: np.ndarray | None = None, b: float = 0.0,
        ramp: float | np.ndarray = 1.0,
    ) -> FilterQP:
        """Build the filter QP: robust rows, or promoting rows where ``promote`` is True (see :meth:`qp_lower`)."""
        kinds: tuple[str, ...] = ()  # empty: every row robust
        if promote is not None and promote.any():
            kinds = tuple(map(_KINDS.__getitem__, promote.tolist()))
        return FilterQP._of(u_nom, lie.lg, self.qp_lower(lie, promote, b, ramp), self.u_min, self.u_max,
                            kinds, lie.names)

    def qp_lower(self, lie: LieData, promote: np.ndarray | None = None, b: float = 0.0,
                 ramp: float | np.ndarray = 1.0) -> np.ndarray:
        """The QP's lower bounds ``lb`` (rows ``Lg h u >= lb``): robust, or promoting where ``promote`` is True.

        ``ramp`` in [0, 1) (a number, or one per row) lowers the promotion level to ``max(-alpha(h), ramp b + (1 - ramp)
        (-alpha(h)))`` (the smooth hand-over after an on switch; never below the robust condition).
        """
        rhs = -self.alpha.vector(lie.h)
        if promote is not None and promote.any():
            level = b if np.all(np.asarray(ramp) >= 1.0) else np.maximum(rhs, ramp * b + (1.0 - ramp) * rhs)
            rhs = np.where(promote, level, rhs)
        return rhs - lie.lf + lie.grad_norm * self.d_bar

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
        self, t: float, x: np.ndarray | None, lie: LieData, u_nom: np.ndarray, xi: np.ndarray,
        promote: np.ndarray | None, floor: float, screen: float | np.ndarray | None = None,
        xs: _Xi | None = None, rows: np.ndarray | None = None,
    ) -> tuple[QPResult, tuple[str, ...], bool, bool]:
        """Solve with screening; return ``(result, relaxed names, fallback, resolved)``.

        ``xi``: each row's robust slack at ``u_nom`` (``Xi_on``, or the slack at a blended
        target); ``xs``: the step's :meth:`_xi` when ``xi`` is its ``Xi_on`` (its minimum, screening
        count and ``alpha(h)`` then save array work); ``rows``: the kept rows when the caller
        selected them (ascending: ``xi < max(screen, floor)`` or promoted).
        """
        screen = self.screen if screen is None else screen
        k = xi.shape[0]
        steps = self._steps
        if screen is not None and k > 1:
            keep = None
            if rows is not None:
                n = rows.size
            elif xs is not None and xs.kept >= 0 and promote is None and not floor > 0:
                n = xs.kept  # counted (and listed) by the kernel, with these thresholds
                if n > 1:
                    rows = xs.rows[:n]  # type: ignore[index]
            else:
                rows = self._select(xi, screen, floor, promote)
                if rows is None:
                    keep = xi < np.maximum(screen, floor) if floor > 0 else xi < screen
                    if promote is not None:
                        keep |= promote  # a promoted row is never screened out
                    rows = keep.nonzero()[0]
                n = rows.size
            if n < k:  # (not keep.all())
                if n <= 1 and self._one_row_ok(lie):
                    if n == 1:
                        i = int(rows[0]) if rows is not None else xs.first  # type: ignore[union-attr]
                    else:
                        i = xs.argmin if xs is not None and xs.argmin >= 0 else int(xi.argmin())
                    one = self._one_row(lie, u_nom, i, xi, xs, promote is not None and bool(promote[i]))
                    if one is not None:
                        if one[1]:
                            return one[0], (), False, False
                        return self._resolve(t, x, lie, u_nom, promote, one[0])
                if n > 1 and steps is not None:
                    if rows is None:  # (the kernel counted: the rows themselves now)
                        rows = self._select(xi, screen, floor, promote)
                    got = None if rows is None else self._few_fast(lie, u_nom, xi, xs, promote, rows, n)
                    if got is not None:
                        if got[1]:
                            return got[0], (), False, False
                        return self._resolve(t, x, lie, u_nom, promote, got[0])
                if keep is None:  # (the rows were counted or selected by a kernel: the mask now)
                    keep = xi < screen if rows is None else np.zeros(k, bool)
                    if rows is None:
                        rows = keep.nonzero()[0]
                    else:
                        keep[rows] = True
                if n == 0:  # the row of least slack alone (views: no copies)
                    i = int(xi.argmin())
                    rows = np.array([i])
                    keep[i] = True
                    one = slice(i, i + 1)
                    sub = LieData._of(lie.h[one], lie.lf[one], lie.lg[one], lie.grad_norm[one])
                else:
                    sub = LieData._of(lie.h.take(rows), lie.lf.take(rows), lie.lg.take(rows, 0),
                                      lie.grad_norm.take(rows))
                res, relaxed, fb = self._solve_block(t, x, sub, u_nom, None if promote is None else promote[rows],
                                                     lie.names, rows)
                if not fb and not self._screened_rows_hold_mask(lie, xi, res.u - u_nom, keep):
                    return self._resolve(t, x, lie, u_nom, promote, res)
                return res, relaxed, fb, False
        if steps is not None and 1 < k <= FEW_ROWS:  # every row kept
            got = self._few_fast(lie, u_nom, xi, xs, promote, np.arange(k), k)
            if got is not None:
                return got[0], (), False, False
        res, relaxed, fb = self._solve_block(t, x, lie, u_nom, promote, lie.names, None)
        return res, relaxed, fb, False

    def _select(self, xi: np.ndarray, screen: float | np.ndarray, floor: float,
                promote: np.ndarray | None) -> np.ndarray | None:
        """The kept rows (``xi < max(screen, floor)``, or promoted), ascending, by the kernel; ``None``: numpy's way."""
        steps = self._steps
        k = xi.shape[0]
        sa = None if steps is None else screen_array(screen, k)
        if sa is None or sa.shape[0] == 0 or xi.dtype != _F64 or xi.ndim != 1 or not (
                promote is None or promote.dtype == _BOOL and promote.shape == xi.shape):
            return None
        rows = np.empty(k, np.intp)
        return rows[:steps.select(xi, sa, floor, _NONE_B if promote is None else promote, rows)]

    def _resolve(self, t: float, x: np.ndarray | None, lie: LieData, u_nom: np.ndarray, promote: np.ndarray | None,
                 first: QPResult) -> tuple[QPResult, tuple[str, ...], bool, bool]:
        """A screened row is needed at ``first``'s answer: solve again with every row (``resolved``)."""
        res, relaxed, fb = self._solve_block(t, x, lie, u_nom, promote, lie.names, None)
        return replace(res, solve_time_s=res.solve_time_s + first.solve_time_s), relaxed, fb, True

    def _solve_block(
        self, t: float, x: np.ndarray | None, lie: LieData, u_nom: np.ndarray, promote: np.ndarray | None,
        names: tuple[str, ...], rows: np.ndarray | None,
    ) -> tuple[QPResult, tuple[str, ...], bool]:
        """One QP (promoting where asked, relaxed to robust if infeasible); the policy if still infeasible.

        ``rows`` maps the rows of ``lie`` to ``names`` (``None``: the same rows).
        """
        b = getattr(self, "b", 0.0)
        ramp = getattr(self, "_ramp", 1.0)
        if rows is not None and type(ramp) is not float and np.ndim(ramp):
            ramp = ramp[rows]
        res = self._solve_few(lie, u_nom, promote, b, ramp)  # (None: the QP the general way)
        if res is not None:
            return res, (), False
        qp = self.build_qp(lie, u_nom, promote, b, ramp)
        res = self._solve(qp)
        relaxed: tuple[str, ...] = ()
        if not res.ok and promote is not None and promote.any():
            local = np.flatnonzero(promote)
            relaxed_idx = tuple(int(i) for i in (local if rows is None else rows[local]))
            relaxed = tuple(names[i] if i < len(names) else str(i) for i in relaxed_idx)
            qp = self.build_qp(lie, u_nom)
            first = res.solve_time_s
            res = self._solve(qp)
            res = replace(res, solve_time_s=res.solve_time_s + first, relaxed=relaxed_idx)
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
            f"(violation {qp.max_violation(u):.3g})", IsfWarning, stacklevel=4,
        )
        return QPResult(u, "fallback", res.active, res.solve_time_s, res.iterations, qp.max_violation(u), res.relaxed)
