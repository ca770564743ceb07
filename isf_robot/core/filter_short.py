"""The filters' short ways around the general QP (a mixin of :class:`~isf_robot.core.filter_base._FilterBase`).

* one kept row: its closed form on the row's own floats (:meth:`ShortWays._one_row`);
* two to ``FEW_ROWS`` rows without input bounds: the exact few-row solution
  (:func:`~isf_robot.core.qp_small.project_few`) without building the QP object
  (:meth:`ShortWays._solve_few`);
* the checks that the rows screened out hold at the answer;
* with the compiled kernels (:func:`~isf_robot.core.fast.step_kernels`), the whole screened
  few-row step: the kept rows, their bounds, the few-row solution and the check of the rows
  screened out, each a compiled pass around numpy's own products (:meth:`ShortWays._few_fast`).

Each gives the numbers the general way (``build_qp`` + :meth:`QPSolver.solve`) gives, bit for bit
(``tests/core/test_screening.py``, ``tests/core/test_fast.py``), or ``None`` and the caller
solves the general way.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from .class_k import CustomClassK, Linear
from .fast import StepKernels
from .qp import QPResult
from .qp_small import FEW_ROWS, REL_TOL, project_few
from .qp_solver import QPSolver
from .sums import dot, matvec
from .system import LieData

if TYPE_CHECKING:
    from .filter_base import _Xi

__all__ = ["ShortWays"]

_F64 = np.dtype(np.float64)
_BOOL = np.dtype(bool)
_NONE_B = np.zeros(0, bool)  # the kernels' "no promoted rows"
_NONE_F = np.zeros(0)  # the kernels' "every ramp weight 1" / "alpha(h) made from gain h"
_ACTIVE = (np.zeros(1, bool), np.ones(1, bool))  # one row's activity, shared (read-only)
for _a in _ACTIVE:
    _a.flags.writeable = False


class ShortWays:
    """The short ways; the filter provides ``alpha``, ``d_bar``, ``solver``, ``u_min``/``u_max``, ``qp_solves``."""

    alpha: Any
    d_bar: float
    solver: QPSolver
    u_min: np.ndarray | None
    u_max: np.ndarray | None
    qp_solves: int
    _steps: StepKernels | None
    _few_buf: np.ndarray  # (4, FEW_ROWS): the compiled few-row step's scratch

    def qp_lower(self, lie: LieData, promote: np.ndarray | None = None, b: float = 0.0,
                 ramp: float | np.ndarray = 1.0) -> np.ndarray:
        raise NotImplementedError

    def _solve_few(self, lie: LieData, u_nom: np.ndarray, promote: np.ndarray | None, b: float,
                   ramp: float | np.ndarray) -> QPResult | None:
        """2 to ``FEW_ROWS`` rows, no bounds: :meth:`QPSolver.solve`'s few-row closed form without the QP object.

        The same bounds (:meth:`qp_lower`), the same :func:`~isf_robot.core.qp_small.project_few`
        call and result as ``self._solve(self.build_qp(...))`` on a plain :class:`QPSolver` with
        ``few_rows``; ``None`` when that does not apply or no few-row solution exists (the caller
        then builds the QP and its solver decides).
        """
        solver = self.solver
        k = lie.h.shape[0]
        if not (1 < k <= FEW_ROWS and type(solver) is QPSolver and solver.few_rows and solver.closed_form
                and self.u_min is None and self.u_max is None):
            return None
        lb = self.qp_lower(lie, promote, b, ramp)
        t0 = time.perf_counter()  # (solve_time_s: the solve, as QPSolver.solve times it; not the bounds' building)
        hit = project_few(lie.lg, lb, u_nom, kernels=solver._few)
        if hit is None:
            return None
        self.qp_solves += 1
        u, res, rmin = hit
        return QPResult._of(u, "optimal", res <= solver.active_tol, time.perf_counter() - t0, 0, max(0.0, -rmin))

    def _few_fast(self, lie: LieData, u_nom: np.ndarray, xi: np.ndarray, xs: _Xi | None, promote: np.ndarray | None,
                  rows: np.ndarray, n: int) -> tuple[QPResult, bool] | None:
        """The kept rows ``rows`` (``n``: 2 to ``FEW_ROWS``, ascending) the compiled way: ``(result, others hold)``.

        The numbers of :meth:`_solve_few` on ``lie`` with those rows taken (``lie`` itself when
        every row is kept), and of :meth:`_screened_rows_hold_mask` at its answer, bit for bit, in
        one call of ``_step_jit.few_step``: the same products (``A u_nom``, ``A A^T``, ``A u``,
        ``Lg h (u - u_nom)``, all in :mod:`isf_robot.core.sums`' order) and the same elementwise
        operations in the same order. ``None`` when that way does not apply or finds no few-row
        answer (the caller then goes the general way, which decides). The QP timer covers the
        call, the bounds' building included.
        """
        steps, solver = self._steps, self.solver
        if not (steps is not None and n <= FEW_ROWS and type(solver) is QPSolver and solver.few_rows
                and solver.closed_form and solver._few is not None and self.u_min is None and self.u_max is None):
            return None
        h, lf, gn, lg = lie.h, lie.lf, lie.grad_norm, lie.lg
        k = xi.shape[0]
        if not (h.dtype == _F64 and lf.dtype == _F64 and gn.dtype == _F64 and lg.dtype == _F64
                and u_nom.dtype == _F64 and xi.dtype == _F64 and lg.ndim == 2 and lg.shape[0] == k
                and h.shape == lf.shape == gn.shape == xi.shape and u_nom.shape == lg.shape[1:]):
            return None
        ramp = getattr(self, "_ramp", 1.0)
        if type(ramp) is float:  # (one weight for every row)
            if not ramp >= 1.0:
                return None
            ramp = _NONE_F
        elif not (type(ramp) is np.ndarray and ramp.dtype == _F64 and ramp.shape == xi.shape):
            return None
        if promote is None:
            promote = _NONE_B
        elif not (promote.dtype == _BOOL and promote.shape == xi.shape):
            return None
        alpha = self.alpha
        gain, av, av_rows = 0.0, _NONE_F, False  # (alpha(h) as qp_lower makes it on the rows it is given)
        if type(alpha) is Linear:
            gain = alpha.gain
        else:
            if n == k:
                av = xs.av if xs is not None and xs.av is not None else alpha.vector(h)
            elif type(alpha) is CustomClassK and xs is not None and xs.av is not None:
                av = xs.av  # (the same call of alpha on the same floats)
            else:
                av, av_rows = alpha.vector(h.take(rows)), True
            if not (type(av) is np.ndarray and av.dtype == _F64 and av.shape == ((n,) if av_rows else xi.shape)):
                return None
        m, tol = u_nom.shape[0], solver.active_tol
        if m == 0:
            return None
        buf = self._few_buf  # (lb, r, the rows' tolerances, A u - lb)
        u, active, du = np.empty(m), np.empty(n, bool), np.empty(m)
        t0 = time.perf_counter()
        code, low, held = steps.few_step(rows, h, lf, gn, self.d_bar, gain, av, av_rows, promote, ramp,
                                         getattr(self, "b", 0.0), lg, u_nom, REL_TOL, buf, u, tol, active, du, xi,
                                         n < k)
        if code == 2:  # (G not finite, or the candidate failed its confirmation: the Python enumeration decides)
            hit = project_few(lg if n == k else lg.take(rows, 0), buf[0, :n].copy(), u_nom)
            if hit is None:
                return None
            u, res, low = hit
            active, du = res <= tol, u - u_nom
            held = n == k or steps.hold(xi, matvec(lg, du), rows, n, tol)
        elif code < 0:
            return None
        self.qp_solves += 1
        return QPResult._of(u, "optimal", active, time.perf_counter() - t0, 0, max(0.0, -low)), held

    def _one_row_ok(self, lie: LieData) -> bool:
        """Whether one kept row may go the short way (:meth:`_one_row`).

        No input bounds, the closed form enabled, float64 barrier data (the row's bound is then
        the same in floats).
        """
        return (self.u_min is None and self.u_max is None and self.solver.closed_form
                and lie.h.dtype == _F64 and lie.lf.dtype == _F64 and lie.grad_norm.dtype == _F64)

    def _one_row(self, lie: LieData, u_nom: np.ndarray, i: int, xi: np.ndarray, xs: _Xi | None,
                 promoted: bool = False) -> tuple[QPResult, bool] | None:
        """Row ``i`` alone (robust, or promoted), no bounds: ``(result, every other row holds at it)``.

        The closed form without building the QP, with the same numbers as :meth:`build_qp` and
        :meth:`QPSolver.solve_row` on that row: the bound ``r - Lf h_i + |dh_i/dx| d_bar`` with
        ``r = -alpha(h_i)``, or the promotion level (``b``, or its ramp ``max(r, w b + (1 - w) r)``),
        in the same order of operations (IEEE float64 arithmetic in floats and in numpy agree), the
        same products (:mod:`isf_robot.core.sums`' written order) and the same check; then
        :meth:`_screened_rows_hold`. With the compiled kernels both in one call
        (``_step_jit.one_step``). ``None`` when the closed form fails its check (the caller then
        solves the general way). When the row holds at ``u_nom`` the command is ``u_nom`` itself
        (not a copy).
        """
        t0 = time.perf_counter()
        alpha = self.alpha
        if type(alpha) is Linear:
            av = alpha.gain * lie.h.item(i)  # (= alpha.vector(h)[i]: one IEEE product)
        elif xs is not None and type(alpha) is CustomClassK:
            av = xs.av.item(i)  # (the same call of alpha on the same float)
        else:
            av = float(alpha.vector(lie.h[i:i + 1])[0])
        rhs = -av
        if promoted:  # (build_qp's level for this row)
            b, w = getattr(self, "b", 0.0), getattr(self, "_ramp", 1.0)
            w = w if type(w) is float else float(w[i])
            rhs = b if w >= 1.0 else max(rhs, w * b + (1.0 - w) * rhs)
        lb = (rhs - lie.lf.item(i)) + lie.grad_norm.item(i) * self.d_bar
        solver, steps, lg = self.solver, self._steps, lie.lg
        if (steps is not None and lg.dtype == _F64 and u_nom.dtype == _F64 and xi.dtype == _F64 and lg.ndim == 2
                and lg.shape[1:] == u_nom.shape and xi.shape == lg.shape[:1]):
            u, du = np.empty(u_nom.shape[0]), np.empty(u_nom.shape[0])
            code, slack, held = steps.one_step(i, lb, lg, u_nom, solver.feas_tol, solver.active_tol, xi, u, du)
            if code < 0:
                return None
            self.qp_solves += 1
            return QPResult._of(u_nom if code == 0 else u, "closed_form", _ACTIVE[slack <= solver.active_tol],
                                time.perf_counter() - t0), held
        a = lg[i]
        aa = dot(a, a)
        if not aa > 1e-200:  # (|a|^2 underflows: the backend decides)
            return None
        gap = lb - dot(a, u_nom)
        if gap <= 0.0:  # u = u_nom: slack = au - lb = -gap exactly (IEEE subtraction is antisymmetric)
            u, slack = u_nom, -gap
            if not math.isfinite(dot(u, u)):
                return None
        else:
            u = u_nom + (gap / aa) * a
            slack = dot(a, u) - lb
            if not (slack >= -solver.feas_tol * max(1.0, abs(lb)) and math.isfinite(dot(u, u))):
                return None
        self.qp_solves += 1
        res = QPResult._of(u, "closed_form", _ACTIVE[slack <= solver.active_tol], time.perf_counter() - t0)
        return res, self._screened_rows_hold(lie, xi, None if xs is None else xs.xi_min, u, u_nom, i)

    def _screened_rows_hold(self, lie: LieData, xi: np.ndarray, xi_min: float | None, u: np.ndarray,
                            u_nom: np.ndarray, i: int) -> bool:
        """Whether every row but ``i`` has robust slack >= active_tol at ``u`` (row ``i`` solved alone).

        The slack of row j at u is ``xi_j + Lg h_j (u - u_nom)`` (``xi``: the slacks at ``u_nom``),
        so one product covers every row; at ``u = u_nom`` it is ``xi_j`` itself (``Lg h`` finite:
        its product with zero is zero). ``xi_min``: the minimum of a finite ``xi``, when the caller
        has it.
        """
        tol = self.solver.active_tol
        if u is u_nom and xi_min is not None:
            if xi_min >= tol:
                return True
            slack = xi.copy()
        else:
            slack = xi + matvec(lie.lg, u - u_nom)
            sl = slack.tolist()
            if math.isfinite(sum(sl)):
                sl[i] = math.inf
                return min(sl) >= tol
        slack[i] = math.inf  # (NaN: as the array minimum, never >= tol)
        return bool(slack.min() >= tol)

    def _screened_rows_hold_mask(self, lie: LieData, xi: np.ndarray, du: np.ndarray, keep: np.ndarray) -> bool:
        """Whether every screened-out row's robust condition has slack >= active_tol at ``u_nom + du``.

        The slack of row i at u is ``Xi_on,i + Lg h_i (u - u_nom)`` (the robust condition's
        left side minus its right side), so one product covers every row.
        """
        slack = xi + matvec(lie.lg, du)  # (the few-row step's product: sums' order)
        slack[keep] = np.inf
        return bool(slack.min() >= self.solver.active_tol)
