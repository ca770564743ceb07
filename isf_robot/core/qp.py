"""Safety-filter quadratic programs: build step and solve step.

Every filter in the paper has the form (eqs. filter and filter_inc)::

    minimise    |u - u_nom|^2
    subject to  A u >= lb_rows          (one row per barrier)
                u_min <= u <= u_max     (optional input bounds)

with row i ``A_i = Lg h_i`` and ``lb_i = -Lf h_i + |dh_i/dx| d_bar + r_i`` where
``r_i = -alpha(h_i)`` for the robust barrier condition (eq. barr_cond) and ``r_i = b`` for the
safety-promoting condition (eq. filter_inc). :func:`build_filter_qp` returns the problem,
:class:`QPSolver` solves it with ProxQP (proxsuite) at explicit tolerances, reusing solver
workspaces, and checks the answer against the constraints before returning it. One row and
no bounds has the closed form :func:`project_halfspace`, used as a fast path and a test oracle.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from .exceptions import ConfigError, ShapeError, SolverError
from .validation import check_positive

__all__ = ["FilterQP", "QPResult", "QPSolver", "build_filter_qp", "project_halfspace"]

QPStatus = Literal["unconstrained", "closed_form", "optimal", "infeasible", "fallback"]


@dataclass(frozen=True)
class FilterQP:
    """The filter QP ``min |u - u_nom|^2  s.t.  A u >= lb,  u_min <= u <= u_max``.

    Attributes:
        u_nom: Nominal command, shape (m,).
        A: Constraint rows ``Lg h``, shape (k, m).
        lb: Row lower bounds, shape (k,).
        u_min: Lower input bounds, shape (m,), or ``None``.
        u_max: Upper input bounds, shape (m,), or ``None``.
        kinds: Per row ``"robust"`` or ``"promote"``.
        names: Per row barrier label.

    """

    u_nom: np.ndarray
    A: np.ndarray
    lb: np.ndarray
    u_min: np.ndarray | None = None
    u_max: np.ndarray | None = None
    kinds: tuple[str, ...] = ()
    names: tuple[str, ...] = ()

    @property
    def m(self) -> int:
        """Number of decision variables."""
        return int(self.u_nom.shape[0])

    @property
    def k(self) -> int:
        """Number of barrier rows."""
        return int(self.A.shape[0])

    @property
    def has_bounds(self) -> bool:
        """Whether input bounds are present."""
        return self.u_min is not None or self.u_max is not None

    def residuals(self, u: np.ndarray) -> np.ndarray:
        """Row slacks ``A u - lb`` (>= 0 when satisfied), shape (k,)."""
        return self.A @ u - self.lb

    def max_violation(self, u: np.ndarray) -> float:
        """Largest constraint violation (rows and bounds) of ``u``; 0 when feasible."""
        v = 0.0
        if self.k:
            v = max(v, float(np.max(-self.residuals(u), initial=0.0)))
        if self.u_min is not None:
            v = max(v, float(np.max(self.u_min - u, initial=0.0)))
        if self.u_max is not None:
            v = max(v, float(np.max(u - self.u_max, initial=0.0)))
        return v


@dataclass(frozen=True)
class QPResult:
    """Outcome of one filter solve.

    Attributes:
        u: The command, shape (m,).
        status: ``"unconstrained"`` (no rows), ``"closed_form"``, ``"optimal"``,
            ``"infeasible"`` or ``"fallback"`` (a configured fallback produced ``u``).
        active: Per row, whether the constraint is active at ``u``, shape (k,) bool.
        solve_time_s: Wall time of the solve [s].
        iterations: Solver iterations (0 for closed forms).
        max_violation: Largest constraint violation of ``u`` (0 up to tolerance when solved).
        relaxed: Indices of rows whose promotion was relaxed to the robust condition.

    """

    u: np.ndarray
    status: str
    active: np.ndarray
    solve_time_s: float
    iterations: int = 0
    max_violation: float = 0.0
    relaxed: tuple[int, ...] = field(default_factory=tuple)

    @property
    def ok(self) -> bool:
        """Whether ``u`` satisfies every constraint (solved exactly or by closed form)."""
        return self.status in ("unconstrained", "closed_form", "optimal")


def build_filter_qp(
    u_nom: np.ndarray,
    lf: np.ndarray,
    lg: np.ndarray,
    grad_norm: np.ndarray,
    rhs: np.ndarray,
    d_bar: float,
    *,
    u_min: np.ndarray | None = None,
    u_max: np.ndarray | None = None,
    kinds: tuple[str, ...] = (),
    names: tuple[str, ...] = (),
) -> FilterQP:
    """Build the filter QP.

    Row i reads ``lf_i + lg_i u - grad_norm_i d_bar >= rhs_i``; pass ``rhs_i = -alpha(h_i)``
    for the robust barrier condition and ``rhs_i = b`` for the safety-promoting one.

    Args:
        u_nom: Nominal command, shape (m,).
        lf: Drift terms ``Lf h`` (including ``dh/dt``), shape (k,).
        lg: Input terms ``Lg h``, shape (k, m).
        grad_norm: ``|dh/dx|``, shape (k,).
        rhs: Right-hand sides, shape (k,).
        d_bar: Disturbance bound, >= 0.
        u_min: Optional lower input bounds, shape (m,).
        u_max: Optional upper input bounds, shape (m,).
        kinds: Row kinds (labels only).
        names: Row names (labels only).

    Returns:
        The :class:`FilterQP`.

    """
    m = u_nom.shape[0]
    if lg.ndim != 2 or lg.shape[1] != m:
        raise ShapeError(f"Lg h must have shape (k, {m}), got {lg.shape}")
    lb = rhs - lf + grad_norm * d_bar
    return FilterQP(u_nom=u_nom, A=lg, lb=lb, u_min=u_min, u_max=u_max, kinds=kinds, names=names)


def project_halfspace(u_nom: np.ndarray, a: np.ndarray, lb: float) -> np.ndarray:
    """Closed-form solution of ``min |u - u_nom|^2  s.t.  a^T u >= lb``.

    ``u = u_nom + max(0, lb - a^T u_nom) / |a|^2 * a``. Raises :class:`SolverError` when
    ``a = 0`` and the constraint is violated (no ``u`` can satisfy it).
    """
    slack = lb - float(a @ u_nom)
    if slack <= 0.0:
        return u_nom.copy()
    aa = float(a @ a)
    if aa == 0.0:
        raise SolverError(f"constraint 0 >= {lb:.6g} cannot be satisfied (Lg h = 0)")
    return u_nom + (slack / aa) * a


class _Workspace:
    """A ProxQP dense workspace and whether it has been initialised."""

    __slots__ = ("qp", "initialised", "H", "upper", "free_lo", "free_hi")

    def __init__(self, qp: Any, m: int, k: int) -> None:
        self.qp = qp
        self.initialised = False
        self.H = np.eye(m)
        self.upper = np.full(k, 1e30)
        self.free_lo = np.full(m, -1e30)
        self.free_hi = np.full(m, 1e30)


class QPSolver:
    """Solves :class:`FilterQP` instances with ProxQP, reusing workspaces per problem size.

    Args:
        eps_abs: Absolute tolerance for ProxQP (primal, dual and duality gap), > 0.
        feas_tol: Largest constraint violation accepted in the returned command; a larger
            one is treated as a solver failure, never returned silently.
        active_tol: A row is "active" when its slack is below this.
        max_iter: Iteration limit of a filter solve. Warm-started filter QPs converge in tens
            of iterations; a problem still unsolved at the limit goes to the phase-1 check,
            which decides infeasibility, so a low limit bounds the cost of infeasible steps.
        closed_form: Use :func:`project_halfspace` for a single row without bounds.
        backend: ``"proxsuite"`` (direct, reuses workspaces) or ``"qpsolvers"``
            (``qpsolvers.solve_problem(..., solver="proxqp")``, no reuse).

    """

    def __init__(
        self,
        eps_abs: float = 1e-9,
        feas_tol: float = 1e-7,
        active_tol: float = 1e-6,
        max_iter: int = 300,
        closed_form: bool = True,
        backend: str = "proxsuite",
        polish: bool = True,
    ) -> None:
        self.eps_abs = check_positive(eps_abs, "eps_abs")
        self.feas_tol = check_positive(feas_tol, "feas_tol")
        self.active_tol = check_positive(active_tol, "active_tol")
        if int(max_iter) < 1:
            raise ConfigError(f"max_iter must be >= 1, got {max_iter}")
        self.max_iter = int(max_iter)
        self.closed_form = bool(closed_form)
        if backend not in ("proxsuite", "qpsolvers"):
            raise ConfigError(f"backend must be 'proxsuite' or 'qpsolvers', got {backend!r}")
        self.backend = backend
        self.polish = bool(polish)
        self._cache: dict[tuple[int, int, bool], _Workspace] = {}
        self.solves = 0

    # -- workspace -----------------------------------------------------------------------
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
            s.initial_guess = proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            qp = _Workspace(qp, m, k)
            self._cache[key] = qp
        return qp

    def _active(self, qp: FilterQP, u: np.ndarray) -> np.ndarray:
        if qp.k == 0:
            return np.zeros(0, dtype=bool)
        return qp.residuals(u) <= self.active_tol

    def solve(self, qp: FilterQP) -> QPResult:
        """Solve ``qp`` and check the answer against its constraints.

        The result has status ``"optimal"``/``"closed_form"``/``"unconstrained"`` when the
        command satisfies every row and bound, or
        ``"infeasible"`` (``u`` is then the least-violation command: evidence, not safe).

        Raises:
            SolverError: The solver failed for another reason (iteration limit, numerical
                trouble) or returned a command violating the constraints beyond ``feas_tol``.

        """
        t0 = time.perf_counter()
        m, k = qp.m, qp.k
        box = qp.has_bounds
        if k == 0 and not box:
            return QPResult(qp.u_nom.copy(), "unconstrained", np.zeros(0, bool), time.perf_counter() - t0)
        if k == 1 and not box and self.closed_form:
            a = qp.A[0]
            if not np.any(a) and qp.lb[0] > 0.0:
                return QPResult(qp.u_nom.copy(), "infeasible", np.ones(1, bool), time.perf_counter() - t0,
                                max_violation=float(qp.lb[0]))
            u = project_halfspace(qp.u_nom, a, float(qp.lb[0]))
            return QPResult(u, "closed_form", self._active(qp, u), time.perf_counter() - t0)
        self.solves += 1
        if self.backend == "qpsolvers":
            u, iters, status = self._solve_qpsolvers(qp)
        else:
            u, iters, status = self._solve_proxsuite(qp, m, k, box)
        dt = time.perf_counter() - t0
        if status == "infeasible":
            # u is the least-violation command: evidence for the caller, never to be applied
            # as if it were safe (the filters turn this into an exception or a recorded fallback)
            return QPResult(u, "infeasible", np.ones(k, bool), dt, iters, max_violation=qp.max_violation(u))
        if self.polish:
            u = self._polish(qp, u)
        res = qp.A @ u - qp.lb if k else np.zeros(0)
        viol = float(np.max(-res, initial=0.0))
        if box:
            viol = max(viol, qp.max_violation(u))
        scale = max(1.0, float(np.max(np.abs(qp.lb), initial=0.0)))
        if not np.all(np.isfinite(u)) or viol > self.feas_tol * scale:
            raise SolverError(
                f"ProxQP returned a command violating the constraints by {viol:.3g} "
                f"(status {status}, {iters} iterations)",
                qp=qp,
            )
        return QPResult(u, "optimal", res <= self.active_tol, dt, iters, viol)

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
                    if nrm == 0.0:
                        cand = None
                        break
                    lam = rhs / nrm
                else:
                    try:
                        lam = np.linalg.solve(Aa @ Aa.T, rhs)
                    except np.linalg.LinAlgError:
                        cand = None  # dependent active rows: keep the solver's answer
                        break
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

    def _solve_proxsuite(self, qp: FilterQP, m: int, k: int, box: bool) -> tuple[np.ndarray, int, str]:
        from proxsuite import proxqp

        wrap = self._workspace(m, k, box)
        ws = wrap.qp
        H = wrap.H
        g = -qp.u_nom
        upper = wrap.upper
        lbox = qp.u_min if qp.u_min is not None else wrap.free_lo
        ubox = qp.u_max if qp.u_max is not None else wrap.free_hi
        if not wrap.initialised:
            if box:
                ws.init(H, g, None, None, qp.A, qp.lb, upper, lbox, ubox)
            else:
                ws.init(H, g, None, None, qp.A, qp.lb, upper)
            wrap.initialised = True
        else:
            if box:
                ws.update(g=g, C=qp.A, l=qp.lb, l_box=lbox, u_box=ubox, update_preconditioner=True)
            else:
                ws.update(g=g, C=qp.A, l=qp.lb, update_preconditioner=True)
        ws.solve()
        st = ws.results.info.status
        iters = int(ws.results.info.iter)
        if st == proxqp.QPSolverOutput.PROXQP_SOLVED:
            return np.array(ws.results.x, dtype=float), iters, "solved"
        # Not solved (infeasible, iteration limit, ...): drop the workspace, since its warm
        # start is now meaningless, and decide feasibility with a phase-1 problem that is
        # always feasible. Never hand back a guess.
        unconverged = np.array(ws.results.x, dtype=float)
        del self._cache[(m, k, box)]
        violation, u_least = self.least_violation(qp)
        # A badly scaled but feasible problem can stall ProxQP and leave the penalised phase-1
        # answer slightly infeasible: an exact active-set step from either point settles it.
        scale = max(1.0, float(np.max(np.abs(qp.lb), initial=0.0)))
        for guess in (unconverged, u_least):
            if not np.all(np.isfinite(guess)):
                continue
            exact = self._polish(qp, guess)
            if exact is not guess and qp.max_violation(exact) <= self.feas_tol * scale:
                return exact, iters, "solved"
        if violation > self.feas_tol:
            return u_least, iters, "infeasible"
        raise SolverError(
            f"ProxQP failed with status {st.name} after {iters} iterations on a feasible problem "
            f"(phase-1 violation {violation:.3g})",
            qp=qp,
        )

    def least_violation(self, qp: FilterQP, weight: float = 1e6) -> tuple[float, np.ndarray]:
        """Solve the always-feasible slack problem of ``qp``.

        ``min |u - u_nom|^2 + weight |s|^2  s.t.  A u + s >= lb,  s >= 0,  u_min <= u <= u_max``.

        Returns:
            ``(max row violation of the returned u, u)``. A violation above ``feas_tol``
            certifies (to tolerance) that ``qp`` is infeasible.

        """
        from proxsuite import proxqp

        m, k = qp.m, qp.k
        n = m + k
        H = np.zeros((n, n))
        H[:m, :m] = np.eye(m)
        H[m:, m:] = weight * np.eye(k)
        g = np.concatenate([-qp.u_nom, np.zeros(k)])
        C = np.hstack([qp.A, np.eye(k)])
        lbox = np.concatenate([qp.u_min if qp.u_min is not None else np.full(m, -1e30), np.zeros(k)])
        ubox = np.concatenate([qp.u_max if qp.u_max is not None else np.full(m, 1e30), np.full(k, 1e30)])
        ws = proxqp.dense.QP(n, 0, k, True)
        ws.settings.eps_abs = self.eps_abs
        ws.settings.eps_rel = 0.0
        ws.settings.max_iter = 20 * self.max_iter
        ws.init(H, g, None, None, C, qp.lb, np.full(k, 1e30), lbox, ubox)
        ws.solve()
        u = np.array(ws.results.x[:m], dtype=float)
        if qp.u_min is not None:
            u = np.maximum(u, qp.u_min)
        if qp.u_max is not None:
            u = np.minimum(u, qp.u_max)
        return qp.max_violation(u), u

    def _solve_qpsolvers(self, qp: FilterQP) -> tuple[np.ndarray, int, str]:
        import qpsolvers

        problem = qpsolvers.Problem(
            P=np.eye(qp.m), q=-qp.u_nom, G=-qp.A if qp.k else None, h=-qp.lb if qp.k else None,
            lb=qp.u_min, ub=qp.u_max,
        )
        sol = qpsolvers.solve_problem(
            problem, solver="proxqp", eps_abs=self.eps_abs, eps_rel=0.0, check_duality_gap=True,
            max_iter=self.max_iter,
        )
        if sol.found and sol.x is not None:
            return np.asarray(sol.x, dtype=float), 0, "solved"
        return qp.u_nom.copy(), 0, "infeasible"
