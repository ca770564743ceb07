"""Safety-filter quadratic programs: build step and solve step.

Every filter in the paper has the form (eqs. filter and filter_inc)::

    minimise    |u - u_nom|^2
    subject to  A u >= lb_rows          (one row per barrier)
                u_min <= u <= u_max     (optional input bounds)

with row i ``A_i = Lg h_i`` and ``lb_i = -Lf h_i + |dh_i/dx| d_bar + r_i`` where
``r_i = -alpha(h_i)`` for the robust barrier condition (eq. barr_cond) and ``r_i = b`` for the
safety-promoting condition (eq. filter_inc). :func:`build_filter_qp` returns the problem,
:class:`~isf_robot.core.qp_solver.QPSolver` solves it (daqp by default, ProxQP selectable) at
explicit tolerances and checks the answer against the constraints before returning it. One row and
no bounds has the closed form :func:`project_halfspace` (:func:`~isf_robot.core.projection.project_row`).

This module holds the problem and its result; :mod:`isf_robot.core.qp_solver` solves it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from .exceptions import ShapeError, SolverError
from .jit import compiled
from .projection import project_row
from .qp_check import NO_BOUND, answer_violation
from .robust import row_lower

__all__ = ["FilterQP", "QPResult", "build_filter_qp", "project_halfspace"]


_new, _set = object.__new__, object.__setattr__  # (the fast constructors: a frozen dataclass's __dict__ set whole)

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
        kinds: Per row ``"robust"`` or ``"promote"``; empty when every row is robust.
        names: Per row barrier label.

    """

    u_nom: np.ndarray
    A: np.ndarray
    lb: np.ndarray
    u_min: np.ndarray | None = None
    u_max: np.ndarray | None = None
    kinds: tuple[str, ...] = ()
    names: tuple[str, ...] = ()

    @classmethod
    def _of(cls, u_nom: np.ndarray, A: np.ndarray, lb: np.ndarray, u_min: np.ndarray | None = None,
            u_max: np.ndarray | None = None, kinds: tuple[str, ...] = (), names: tuple[str, ...] = ()) -> FilterQP:
        """The problem with these fields, unchecked: the filters' per-step fast path.

        Same object as ``FilterQP(...)`` would build, without the frozen dataclass's
        field-by-field ``__init__``.
        """
        qp = _new(cls)
        _set(qp, "__dict__", {"u_nom": u_nom, "A": A, "lb": lb, "u_min": u_min, "u_max": u_max, "kinds": kinds,
                              "names": names})
        return qp

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
        """Largest constraint violation (rows and bounds) of ``u``; 0 when feasible, NaN when it cannot be told.

        NaN: ``u`` or a row's slack not finite, or the command's sum overflowing.
        :func:`~isf_robot.core.qp_check.answer_violation`'s ``violation`` (compiled or as written).
        """
        u = np.asarray(u, dtype=float)
        lo = NO_BOUND if self.u_min is None else self.u_min
        hi = NO_BOUND if self.u_max is None else self.u_max
        return float(compiled(answer_violation)(self.A, self.residuals(u), u, self.u_nom, lo, hi)[0])


@dataclass(frozen=True)
class QPResult:
    """Outcome of one filter solve.

    Attributes:
        u: The command, shape (m,).
        status: ``"unconstrained"`` (no rows), ``"closed_form"``, ``"optimal"``,
            ``"infeasible"`` or ``"fallback"`` (a configured fallback produced ``u``).
        active: Per row, whether the constraint is active at ``u``, shape (k,) bool (a closed form's is
            a shared read-only array: copy it to change it).
        solve_time_s: Wall time of the solve [s] (the standard filter's closed form: of its compiled call,
            ``Xi_on`` of every row included).
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

    @classmethod
    def _of(cls, u: np.ndarray, status: str, active: np.ndarray, solve_time_s: float, iterations: int = 0,
            max_violation: float = 0.0, relaxed: tuple[int, ...] = ()) -> QPResult:
        """The result with these fields, unchecked: the closed form's fast path.

        Same object as ``QPResult(...)`` would build, without the frozen dataclass's
        field-by-field ``__init__``.
        """
        res = _new(cls)
        _set(res, "__dict__", {"u": u, "status": status, "active": active, "solve_time_s": solve_time_s,
                               "iterations": iterations, "max_violation": max_violation, "relaxed": relaxed})
        return res

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
    lb = row_lower(np.asarray(rhs, dtype=float), lf, grad_norm, d_bar)
    return FilterQP(u_nom=u_nom, A=lg, lb=lb, u_min=u_min, u_max=u_max, kinds=kinds, names=names)


def project_halfspace(u_nom: np.ndarray, a: np.ndarray, lb: float) -> np.ndarray:
    """Closed-form solution of ``min |u - u_nom|^2  s.t.  a^T u >= lb``.

    ``u = u_nom + max(0, lb - a^T u_nom) / |a|^2 * a``
    (:func:`~isf_robot.core.projection.project_row`). Raises :class:`SolverError` when no answer
    exists (``a = 0`` and the constraint violated) or it is not finite.
    """
    u_nom = np.asarray(u_nom, dtype=float)
    u = np.empty(u_nom.shape[0])
    code, _ = project_row(np.asarray(a, dtype=float), float(lb), u_nom, math.inf, u)
    if code < 0:
        raise SolverError(f"constraint {np.asarray(a)} u >= {lb:.6g} has no closed-form answer from {u_nom} "
                          f"(|a| = 0 or not finite)")
    return u_nom.copy() if code == 0 else u
