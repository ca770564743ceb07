"""Closed forms of the filter QP without input bounds: the projection of ``u_nom`` onto one or a few rows.

Without input bounds the filter QP ``min |u - u_nom|^2  s.t.  A u >= lb`` (k rows) is the projection
of ``u_nom`` onto a polyhedron. Its KKT conditions for an active set ``S`` are::

    u = u_nom + A_S^T lam,   A_S u = lb_S,   lam >= 0,   A u >= lb,

and, the problem being convex, any ``u`` that meets them is the (unique) solution. With
``r = A u_nom - lb`` (the residuals at ``u_nom``) and ``G = A A^T``:

* one row (:func:`project_row`): ``u = u_nom + max(0, -r) / |a|^2 a``;
* a few rows (:func:`project_few`, at most :data:`FEW_ROWS`): ``S = {}`` when every ``r_i >= 0``;
  ``S = {i}`` with ``lam = -r_i / G_ii``; ``S = {i, j}`` by Cramer's rule, skipped when the two rows
  are nearly parallel (``det <= 1e-12 G_ii G_jj``). Candidates are screened with ``G`` (most violated
  row first) and the first that meets the conditions is confirmed on the rows themselves (``A u - lb``
  to ``rel_tol max(1, |lb_i|) max(1, |u|_inf)``). An active set of three or more rows, nearly
  parallel rows, an infeasible problem: no answer, and the caller's QP backend decides.

Plain functions over numpy arrays; :func:`~isf_robot.core.jit.compiled` compiles these same
functions (the filters and :class:`~isf_robot.core.qp_solver.QPSolver` call them one way or the
other). Every answer is checked before it is returned.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import formula

__all__ = ["project_row", "project_few", "FEW_ROWS", "REL_TOL"]

FEW_ROWS = 8
"""Largest number of rows :func:`project_few` enumerates (the pairs grow as k^2)."""

REL_TOL = 1e-12
""":func:`project_few`'s ``rel_tol``."""


@formula
def project_row(a: np.ndarray, lb: float, u_nom: np.ndarray, feas_tol: float, u: np.ndarray) -> tuple:
    """``min |u - u_nom|^2  s.t.  a u >= lb``, checked: ``(code, slack)``.

    ``code`` 0: the row holds at ``u_nom`` (the answer is ``u_nom``; ``u`` not written); 1: the
    projection, written to ``u``; -1: no closed-form answer (``|a|^2`` underflows, or the answer
    violates the row beyond ``feas_tol max(1, |lb|)`` or is not finite: the caller's backend
    decides). ``slack = a u - lb`` of the answer.
    """
    aa = a @ a
    if not aa > 1e-200:
        return -1, 0.0
    gap = lb - a @ u_nom
    if gap <= 0.0:
        if not math.isfinite(u_nom @ u_nom):
            return -1, 0.0
        return 0, -gap
    u[:] = u_nom + (gap / aa) * a
    slack = a @ u - lb
    if not (slack >= -feas_tol * max(1.0, abs(lb)) and math.isfinite(u @ u)):
        return -1, 0.0
    return 1, slack


@formula
def project_few(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, rel_tol: float, u: np.ndarray,
                res: np.ndarray) -> tuple:
    """``min |u - u_nom|^2  s.t.  A u >= lb`` when at most two rows are active there: ``(code, min residual)``.

    ``code`` 0: every row holds at ``u_nom`` (``u``, ``res = A u - lb`` written); 1: the solution in
    ``u`` and ``res``; -1: no such answer (see the module docstring). ``A`` (k, m) with k <= FEW_ROWS.
    """
    k = A.shape[0]
    r = A @ u_nom - lb
    if not math.isfinite(np.sum(r)):
        return -1, 0.0
    tol = rel_tol * np.maximum(1.0, np.abs(lb))
    neg = r < -tol
    if not neg.any():
        u[:] = u_nom
        res[:] = r
        return 0, np.min(r)
    G = A @ A.T  # (a non-finite G gives no candidate that passes; _confirm checks every answer)
    diag = np.diag(G).copy()
    viol = np.flatnonzero(neg & (diag > 1e-200))
    order = viol
    if viol.shape[0] > 1:  # most violated first
        order = viol[np.argsort(r[viol] / np.sqrt(diag[viol]), kind="mergesort")]
    for i in order:  # one active row
        lam = -r[i] / G[i, i]
        pred = r + lam * G[i]
        pred[i] = 0.0  # (active by construction)
        if np.all(pred >= -tol):
            u[:] = u_nom + lam * A[i]
            low = _confirm(A, lb, u, tol, res)
            if low == low:
                return 1, low
    violated = np.zeros(k, np.bool_)
    violated[viol] = True
    for i in order:  # two active rows: i (violated at u_nom) and any other
        gii, ri = G[i, i], r[i]
        for j in range(k):
            if j == i or (violated[j] and j < i):
                continue
            gjj = G[j, j]
            if gjj <= 1e-200:
                continue
            gij = G[i, j]
            det = gii * gjj - gij * gij
            if not det > 1e-12 * gii * gjj:
                continue
            rj = r[j]
            li = (-ri * gjj + rj * gij) / det
            lj = (-rj * gii + ri * gij) / det
            if not (li >= 0.0 and lj >= 0.0):
                continue
            pred = r + li * G[i] + lj * G[j]
            pred[i] = 0.0
            pred[j] = 0.0
            if np.all(pred >= -tol):
                u[:] = (u_nom + li * A[i]) + lj * A[j]
                low = _confirm(A, lb, u, tol, res)
                if low == low:
                    return 1, low
    return -1, 0.0


@formula
def _confirm(A: np.ndarray, lb: np.ndarray, u: np.ndarray, tol: np.ndarray, res: np.ndarray) -> float:
    """``min(A u - lb)`` (``res``) when ``u`` is finite and every row holds to ``tol max(1, |u|_inf)``; NaN if not."""
    res[:] = A @ u - lb
    scale = max(1.0, np.max(np.abs(u)))
    if not (scale < math.inf and np.all(res >= -tol * scale)):  # (NaN anywhere: refused)
        return math.nan
    return np.min(res)
