"""The solve step of the filter QPs: :class:`QPSolver` (daqp by default, ProxQP selectable).

Every answer is checked before it is returned: the command must be finite and satisfy every row
and bound to ``feas_tol`` (relative to the size of the bounds), otherwise the solver raises
:class:`~isf_robot.core.exceptions.SolverError` or, for an infeasible problem, returns status
``"infeasible"`` with the least-violation command as evidence (never as a safe answer).

Backends (choose by measurement; ``benchmarks/arm_bench.py`` prints both on the arm's QPs):

* ``"daqp"`` (default): the dual active-set solver DAQP, called directly. Exact at the solution
  (an active-set method solves the KKT system of the final active set), about 5 us on the
  arm's few-row problems.
* ``"proxsuite"``: ProxQP through proxsuite with warm-started workspaces per problem size,
  eps_abs 1e-9 and the duality-gap check, then an active-set polish kept only when it
  satisfies the KKT conditions (ProxQP alone can stop about 1e-5 off the optimum on a
  degenerate row); about 40 us.
* ``"qpsolvers"``: ProxQP through ``qpsolvers.solve_problem`` (no workspace reuse), polished.

A problem a backend does not solve goes to an always-feasible phase-1 (slack) problem that
decides infeasibility; an exact active-set step from the unconverged or the phase-1 point
settles badly scaled feasible problems.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from .exceptions import ConfigError, ShapeError, SolverError
from .jit import compiled
from .projection import FEW_ROWS, REL_TOL, project_few_within, project_row
from .qp import FilterQP, QPResult
from .qp_check import NO_BOUND, answer_violation
from .validation import check_positive

__all__ = ["QPSolver", "BACKENDS"]

BACKENDS: tuple[str, ...] = ("daqp", "proxsuite", "qpsolvers")

_LEAST_CUT = 1e-5
"""Normalised violations of the least-violation problem's first stage below this count as none (its
regularisation pulls a feasible problem's rows about 1e-6 off; :meth:`QPSolver.least_violation`)."""
_INF = 1e30  # "no bound" for the solvers

_PROXQP_INNER = 50
"""ProxQP's inner iterations per outer one. Its default (1500) let a filter solve on rows of scale 1e-12 run
4e5 iterations (1.2 s; 5 s at 1e-155) before giving up; well-scaled filter problems need a few per outer
iteration (``tests/core/test_qp.py``). A solve stopped at the limit is "unsolved", as at ``max_iter``."""


def _bound(b: np.ndarray | None) -> np.ndarray:
    """An input bound as :func:`~isf_robot.core.qp_check.answer_violation` takes it (``None``: none)."""
    return NO_BOUND if b is None else b


class _Workspace:
    """A ProxQP dense workspace and whether it has been initialised."""

    __slots__ = ("qp", "initialised", "H", "upper", "free_lo", "free_hi")

    def __init__(self, qp: Any, m: int, k: int) -> None:
        self.qp = qp
        self.initialised = False
        self.H = np.eye(m)
        self.upper = np.full(k, _INF)
        self.free_lo = np.full(m, -_INF)
        self.free_hi = np.full(m, _INF)


class QPSolver:
    """Solves :class:`~isf_robot.core.qp.FilterQP` instances and checks every answer.

    Args:
        eps_abs: Absolute tolerance (ProxQP: primal, dual and duality gap; daqp: primal), > 0.
        feas_tol: Largest constraint violation accepted in the returned command (relative to
            ``max(1, |lb|)``); a larger one is a solver failure, never returned silently.
        active_tol: A row is "active" when its slack is below this.
        max_iter: Iteration limit of a filter solve; a problem still unsolved at the limit goes
            to the phase-1 check, which decides infeasibility.
        closed_form: Use :func:`~isf_robot.core.projection.project_row` for a single row without
            bounds (its answer is checked like any other; a violating one, or a row so small
            that ``|Lg h|^2`` underflows, goes to the backend instead).
        few_rows: With ``closed_form``, solve 2 to ``FEW_ROWS`` rows without bounds exactly
            (:func:`~isf_robot.core.projection.project_few` when one or two rows are active at the
            solution, else the certified active-set iteration
            :func:`~isf_robot.core.projection.project_active`; status ``"optimal"``, every row checked;
            anything else goes to the backend); with bounds, 1 to ``FEW_ROWS`` rows the same way when
            that answer satisfies every bound (then no bound is active:
            :func:`~isf_robot.core.projection.project_few_within`; the torque level's limits), compiled or
            as written alike (the same routing either way, so the two ways give the same commands to
            rounding). The answers equal the backend's to its accuracy (about 1e-12), so off by
            default: a chaotic caller (the satellite's post-jump problem) keeps its runs; the arm
            turns it on.
        backend: One of :data:`BACKENDS` (see the module docstring).
        polish: Active-set polish of the iterative backends' answers (ProxQP).

    """

    def __init__(
        self,
        eps_abs: float = 1e-9,
        feas_tol: float = 1e-7,
        active_tol: float = 1e-6,
        max_iter: int = 300,
        closed_form: bool = True,
        backend: str = "daqp",
        polish: bool = True,
        few_rows: bool = False,
    ) -> None:
        self.eps_abs = check_positive(eps_abs, "eps_abs")
        self.feas_tol = check_positive(feas_tol, "feas_tol")
        self.active_tol = check_positive(active_tol, "active_tol")
        if int(max_iter) < 1:
            raise ConfigError(f"max_iter must be >= 1, got {max_iter}")
        self.max_iter = int(max_iter)
        self.closed_form = bool(closed_form)
        if backend not in BACKENDS:
            raise ConfigError(f"backend must be one of {', '.join(BACKENDS)}; got {backend!r}")
        self.backend = backend
        self.polish = bool(polish)
        self.few_rows = bool(few_rows)
        self.project_row = compiled(project_row)  # (ISF_ROBOT_JIT is read here)
        self._project_few_within = compiled(project_few_within)
        self._check = compiled(answer_violation)
        self._cache: dict[tuple[int, int, bool], _Workspace] = {}
        self._eye: dict[int, np.ndarray] = {}
        self._upper: dict[int, np.ndarray] = {}
        self._bounds: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}  # (daqp's lower, upper with bounds)
        self.solves = 0

    # -- the solve step ----------------------------------------------------------------------
    def solve(self, qp: FilterQP) -> QPResult:
        """Solve ``qp`` and check the answer against its constraints.

        ``solve_time_s`` of the result covers everything done here (backend, polish, checks).

        Returns:
            Status ``"optimal"``/``"closed_form"``/``"unconstrained"`` when the command
            satisfies every row and bound, or ``"infeasible"`` (``u`` is then the
            least-violation command: evidence, not safe).

        Raises:
            SolverError: The backend failed for another reason (iteration limit, numerical
                trouble) or returned a command violating the constraints beyond ``feas_tol``.

        """
        t0 = time.perf_counter()
        k = qp.A.shape[0]  # (qp.k and qp.has_bounds, without the properties' calls)
        box = qp.u_min is not None or qp.u_max is not None
        if box:
            m = qp.u_nom.shape[0]
            for name, bound in (("u_min", qp.u_min), ("u_max", qp.u_max)):
                if bound is not None and bound.shape != (m,):
                    raise ShapeError(f"input bound {name} has shape {bound.shape}; the command has {m} inputs")
        if k == 0 and not box:
            return QPResult(qp.u_nom.copy(), "unconstrained", np.zeros(0, bool), time.perf_counter() - t0)
        if k == 1 and not box and self.closed_form:
            res = self.solve_row(qp.u_nom, qp.A[0], float(qp.lb[0]), t0)
            if res is not None:
                return res
            # an answer that fails the check goes to the backend
        elif self.few_rows and self.closed_form and (1 < k <= FEW_ROWS or (box and k == 1)):
            hit = self.solve_few(qp.A, qp.lb, qp.u_nom, qp.u_min, qp.u_max)
            if hit is not None:  # the exact solution (closed form or certified active set), every row and bound checked
                u, res, rmin = hit  # (one row: "closed_form", as the filters' fused steps report it)
                return QPResult._of(u, "closed_form" if k == 1 else "optimal", res <= self.active_tol,
                                    time.perf_counter() - t0, 0, max(0.0, -rmin))
        self.solves += 1
        if self.backend == "daqp":
            u, iters, status = self._solve_daqp(qp)
        elif self.backend == "qpsolvers":
            u, iters, status = self._solve_qpsolvers(qp)
        else:
            u, iters, status = self._solve_proxsuite(qp)
        if status == "unsolved":
            u, status = self._settle(qp, u, iters)
        if status == "infeasible":
            return QPResult(u, "infeasible", np.ones(k, bool), time.perf_counter() - t0, iters,
                            max_violation=qp.max_violation(u))
        if self.polish and self.backend != "daqp":
            u = self._polish(qp, u)
        res = qp.A.dot(u) - qp.lb  # (dot: the BLAS product of @)
        viol, dist = self._check(qp.A, res, u, qp.u_nom, _bound(qp.u_min), _bound(qp.u_max))
        if not dist <= self.feas_tol:  # (a non-finite command: dist inf)
            what = "a non-finite command" if math.isnan(viol) else f"a command violating the constraints by {viol:.3g}"
            raise SolverError(f"{self.backend} returned {what} ({iters} iterations)", qp=qp)
        return QPResult._of(u, "optimal", res <= self.active_tol, time.perf_counter() - t0, iters, viol)

    def solve_row(self, u_nom: np.ndarray, a: np.ndarray, lb: float, t0: float | None = None) -> QPResult | None:
        """The closed form of one row ``a u >= lb`` without bounds, checked; ``None`` when it fails.

        :func:`~isf_robot.core.projection.project_row`: ``None`` (a row so small that ``|a|^2``
        underflows, or an answer violating the row beyond ``feas_tol``, or not finite) sends the
        problem to the backend. ``t0``: the ``perf_counter`` time the caller's solve began (default: now).
        """
        if t0 is None:
            t0 = time.perf_counter()
        u = np.empty(u_nom.shape[0])
        code, slack = self.project_row(np.ascontiguousarray(a, dtype=float), float(lb), u_nom, self.feas_tol, u)
        if code < 0:
            return None
        return QPResult._of(u_nom.copy() if code == 0 else u, "closed_form", np.array([slack <= self.active_tol]),
                            time.perf_counter() - t0)

    def solve_few(self, A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, u_min: np.ndarray | None = None,
                  u_max: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float] | None:
        """1 to ``FEW_ROWS`` rows by closed form, within the bounds: ``(u, A u - lb, min)``, or ``None``.

        :func:`~isf_robot.core.projection.project_few_within` (``project_few``, else ``project_active``), every
        row checked, kept only when every bound holds (then it is the bounded problem's optimum too). ``None``:
        the backend decides.
        """
        k, m = A.shape
        u, res = np.empty(m), np.empty(k)
        lo, hi = _bound(u_min), _bound(u_max)
        within = self._project_few_within if (A.dtype == np.float64 and lb.dtype == np.float64
                                              and u_nom.dtype == np.float64 and m > 0 and lo.dtype == np.float64
                                              and hi.dtype == np.float64) else project_few_within
        code, low = within(np.ascontiguousarray(A), lb, u_nom, REL_TOL, lo, hi, u, res)
        if code < 0:
            return None
        return u, res, float(low)

    def _distance_violation(self, qp: FilterQP, u: np.ndarray) -> float:
        """How far ``u`` lies outside the feasible set, relative to the size of the problem (inf: not finite).

        :func:`~isf_robot.core.qp_check.answer_violation`'s ``distance``, compiled or as written.
        """
        return self._check(qp.A, qp.A.dot(u) - qp.lb, u, qp.u_nom, _bound(qp.u_min), _bound(qp.u_max))[1]

    # -- backends: each returns (u, iterations, "solved" | "unsolved") -------------------------
    def _identity(self, m: int) -> np.ndarray:
        eye = self._eye.get(m)
        if eye is None:
            eye = self._eye[m] = np.eye(m)
        return eye

    def _solve_daqp(self, qp: FilterQP) -> tuple[np.ndarray, int, str]:
        import daqp

        m, k = qp.u_nom.shape[0], qp.A.shape[0]
        lower = qp.lb
        if qp.u_min is not None or qp.u_max is not None:  # (the bounds first, then the rows: daqp's order)
            bufs = self._bounds.get((m, k))
            if bufs is None:
                bufs = self._bounds[(m, k)] = (np.empty(m + k), np.empty(m + k))
            lower, upper = bufs  # (refilled whole at every solve; daqp only reads them, during the call)
            lower[:m] = -_INF if qp.u_min is None else qp.u_min
            lower[m:] = qp.lb
            upper[:m] = _INF if qp.u_max is None else qp.u_max
            upper[m:] = _INF
        else:
            upper = self._upper.get(k)
            if upper is None:
                upper = self._upper[k] = np.full(k, _INF)
        x, _, flag, info = daqp.solve(self._identity(m), -qp.u_nom, qp.A, upper, lower,
                                      primal_tol=self.eps_abs, iter_limit=self.max_iter)
        return np.asarray(x, dtype=float), int(info["iterations"]), "solved" if flag == 1 else "unsolved"

    def _workspace(self, m: int, k: int, box: bool) -> _Workspace:
        key = (m, k, box)
        qp = self._cache.get(key)
        if qp is None:
            from proxsuite import proxqp

            qp = proxqp.dense.QP(m, 0, k, box)
            s = qp.settings
            s.eps_abs = self.eps_abs
            s.eps_rel = 0.0
            s.check_duality_gap = True
            s.eps_duality_gap_abs = self.eps_abs
            s.eps_duality_gap_rel = 0.0
            s.max_iter = self.max_iter
            s.max_iter_in = _PROXQP_INNER
            s.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            qp = _Workspace(qp, m, k)
            self._cache[key] = qp
        return qp

    def _solve_proxsuite(self, qp: FilterQP) -> tuple[np.ndarray, int, str]:
        from proxsuite import proxqp

        m, k, box = qp.m, qp.k, qp.has_bounds
        wrap = self._workspace(m, k, box)
        ws = wrap.qp
        g = -qp.u_nom
        lbox = qp.u_min if qp.u_min is not None else wrap.free_lo
        ubox = qp.u_max if qp.u_max is not None else wrap.free_hi
        if not wrap.initialised:
            if box:
                ws.init(wrap.H, g, None, None, qp.A, qp.lb, wrap.upper, lbox, ubox)
            else:
                ws.init(wrap.H, g, None, None, qp.A, qp.lb, wrap.upper)
            wrap.initialised = True
        elif box:
            ws.update(g=g, C=qp.A, l=qp.lb, l_box=lbox, u_box=ubox, update_preconditioner=True)
        else:
            ws.update(g=g, C=qp.A, l=qp.lb, update_preconditioner=True)
        ws.solve()
        iters = int(ws.results.info.iter)
        u = np.array(ws.results.x, dtype=float)
        if ws.results.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED:
            return u, iters, "solved"
        del self._cache[(m, k, box)]  # its warm start is now meaningless
        return u, iters, "unsolved"

    def _solve_qpsolvers(self, qp: FilterQP) -> tuple[np.ndarray, int, str]:
        import qpsolvers

        problem = qpsolvers.Problem(
            P=self._identity(qp.m), q=-qp.u_nom, G=-qp.A if qp.k else None, h=-qp.lb if qp.k else None,
            lb=qp.u_min, ub=qp.u_max,
        )
        sol = qpsolvers.solve_problem(problem, solver="proxqp", eps_abs=self.eps_abs, eps_rel=0.0,
                                      check_duality_gap=True, max_iter=self.max_iter)
        if sol.found and sol.x is not None:
            return np.asarray(sol.x, dtype=float), 0, "solved"
        return qp.u_nom.copy(), 0, "unsolved"

    # -- unsolved problems ---------------------------------------------------------------------
    def _settle(self, qp: FilterQP, unconverged: np.ndarray, iters: int) -> tuple[np.ndarray, str]:
        """Decide an unsolved problem: an exact feasible optimum, or certified infeasibility."""
        violation, u_least = self.least_violation(qp)
        for guess in (unconverged, u_least):
            if not np.all(np.isfinite(guess)):
                continue
            exact = self._polish(qp, guess)
            if exact is not guess and self._distance_violation(qp, exact) <= self.feas_tol:
                return exact, "solved"
        if violation > self.feas_tol:
            return u_least, "infeasible"
        raise SolverError(
            f"{self.backend} failed after {iters} iterations on a feasible problem "
            f"(phase-1 violation {violation:.3g})", qp=qp)

    def least_violation(self, qp: FilterQP) -> tuple[float, np.ndarray]:
        """The command of least constraint violation, closest to ``u_nom`` among those (DAQP, two stages).

        1. The least violations: ``min |s|^2 + e |u - u_nom|^2 / U^2`` over ``(u, s)`` subject to
           ``a_i u / |a_i| + s_i >= lb_i / |a_i|``, ``s >= 0`` and the input bounds. Each row's
           violation ``s_i`` is measured in its own normalised units (a distance in command space),
           so rows of any scale weigh alike; ``e = 1e-6`` (``U = max(1, |u_nom|_inf)``) only makes
           the solution unique. Always feasible.
        2. The command closest to ``u_nom`` with those violations: ``min |u - u_nom|^2`` subject to
           ``A u >= lb - |a_i| s_i`` and the input bounds, where violations under ``1e-5`` (normalised;
           the first stage's regularisation leaves about ``1e-6`` on a feasible problem) count as
           none, so a feasible problem gets its own optimum.

        Both are small, well-scaled QPs (one solve each, sub-millisecond on a filter's rows); a
        single weighted problem (``|s|`` weighted 1e12) took ProxQP up to minutes per call on
        torque-scale rows.

        Returns:
            ``(max row violation of the returned u, u)``. A violation above ``feas_tol``
            certifies (to tolerance) that ``qp`` is infeasible.

        Raises:
            SolverError: DAQP did not solve the first stage (it is always feasible).

        """
        import daqp

        m, k = qp.m, qp.k
        lo_u = qp.u_min if qp.u_min is not None else np.full(m, -_INF)
        hi_u = qp.u_max if qp.u_max is not None else np.full(m, _INF)
        if k == 0:
            u = np.clip(qp.u_nom, lo_u, hi_u)
            return qp.max_violation(u), u
        norms = np.linalg.norm(qp.A, axis=1)
        norms = np.where(norms > 0.0, norms, 1.0)
        a_n, lb_n = qp.A / norms[:, None], qp.lb / norms
        reg = 1e-6 / max(1.0, float(np.abs(qp.u_nom).max())) ** 2
        H = np.diag(np.concatenate((np.full(m, reg), np.ones(k))))
        f = np.concatenate((-reg * qp.u_nom, np.zeros(k)))
        C = np.hstack((a_n, np.eye(k)))
        lower = np.concatenate((lo_u, np.zeros(k), lb_n))
        upper = np.concatenate((hi_u, np.full(2 * k, _INF)))
        x, _, flag, _ = daqp.solve(H, f, C, upper, lower, primal_tol=self.eps_abs, iter_limit=20 * self.max_iter)
        if flag != 1:
            raise SolverError(f"least-violation problem not solved (DAQP exit flag {flag})", qp=qp)
        u1 = np.clip(np.asarray(x[:m], dtype=float), lo_u, hi_u)
        viol = np.maximum(lb_n - a_n @ u1, 0.0)
        upper2 = np.concatenate((hi_u, np.full(k, _INF)))
        u = u1
        # the rows violated beyond the regularisation's pull (about e |u - u_nom| / U^2) relaxed by their
        # violation, the others kept; if that is infeasible (a violation below the cut), every row relaxed
        for cut in (_LEAST_CUT, 0.0):
            lower2 = np.concatenate((lo_u, qp.lb - norms * np.where(viol > cut, viol, 0.0)))
            u2, _, flag, _ = daqp.solve(self._identity(m), -qp.u_nom, qp.A, upper2, lower2,
                                        primal_tol=self.eps_abs, iter_limit=20 * self.max_iter)
            if flag == 1:
                u2 = np.clip(np.asarray(u2, dtype=float), lo_u, hi_u)
                if qp.max_violation(u2) <= qp.max_violation(u1) + self.eps_abs:
                    u = u2
                    break
        return qp.max_violation(u), u

    def _polish(self, qp: FilterQP, u: np.ndarray) -> np.ndarray:
        """Active-set refinement of an approximate optimum ``u`` (see ``polish``)."""
        A, b = qp.A, qp.lb
        if qp.has_bounds:
            rows_A, rows_b = [A], [b]
            if qp.u_min is not None:
                rows_A.append(np.eye(qp.m))
                rows_b.append(qp.u_min)
            if qp.u_max is not None:
                rows_A.append(-np.eye(qp.m))
                rows_b.append(-qp.u_max)
            A, b = np.vstack(rows_A), np.concatenate(rows_b)
        scale = max(1.0, float(np.abs(b).max()))
        slack = A @ u - b
        u_nom = qp.u_nom
        cand: np.ndarray | None
        for tau in (1e-7 * scale, 1e-4 * scale):
            idx = np.flatnonzero(slack <= tau)
            # primal active-set steps: drop the row with the most negative multiplier
            for _ in range(idx.size + 1):
                if idx.size == 0:
                    cand = u_nom
                    break
                Aa = A[idx]
                rhs = b[idx] - Aa @ u_nom
                if idx.size == 1:
                    nrm = float(Aa[0] @ Aa[0])
                    if nrm <= 1e-200:  # lam would overflow: keep the solver's answer
                        cand = None
                        break
                    lam = rhs / nrm
                else:
                    try:
                        lam = np.linalg.solve(Aa @ Aa.T, rhs)
                    except np.linalg.LinAlgError:  # dependent active rows: the least-norm multipliers
                        lam = np.linalg.lstsq(Aa @ Aa.T, rhs, rcond=None)[0]
                worst = int(np.argmin(lam))
                if lam[worst] >= -1e-9 * scale:
                    cand = u_nom + Aa.T @ lam
                    break
                idx = np.delete(idx, worst)
            else:
                cand = None
            if cand is not None and float((A @ cand - b).min()) >= -1e-10 * scale:
                return cand.copy() if cand is u_nom else cand
        return u
