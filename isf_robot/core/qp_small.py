"""Exact solutions of small filter QPs without input bounds: active sets of one or two rows.

Without input bounds the filter QP ``min |u - u_nom|^2  s.t.  A u >= lb`` (k rows) is the
projection of ``u_nom`` onto a polyhedron. Its KKT conditions for an active set ``S`` are::

    u = u_nom + A_S^T lam,   A_S u = lb_S,   lam >= 0,   A u >= lb,

and, the problem being convex, any ``u`` that meets them is the (unique) solution. With
``r = A u_nom - lb`` (the residuals at ``u_nom``) and ``G = A A^T`` (the Gram matrix):

* ``S = {}``: ``u = u_nom`` when every ``r_i >= 0``;
* ``S = {i}``: ``lam = -r_i / G_ii`` (``r_i < 0``), the residuals at ``u`` are ``r + lam G[:, i]``;
* ``S = {i, j}``: ``[G_ii G_ij; G_ij G_jj] lam = -[r_i; r_j]`` by Cramer's rule, skipped when the
  two rows are nearly parallel (``det <= 1e-12 G_ii G_jj``).

The candidates are screened in floats with ``G`` (most violated row first; the active rows'
own residuals are zero by construction), and the first that meets the conditions is confirmed
on the rows themselves (to ``rel_tol max(1, |lb_i|) max(1, |u|_inf)``): ``u`` is built and ``A u - lb``
computed as the backends' answers are checked. An active set of three or more rows, nearly
parallel rows, an infeasible problem, a row violated beyond ``tol`` at every candidate: ``None``,
and the caller solves with its backend (which decides infeasibility). On the arm, most filter
QPs with several rows have one or two active rows at the solution.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .sums import gram, matvec

__all__ = ["project_few", "FEW_ROWS", "REL_TOL"]

_F64 = np.dtype(np.float64)
_PY = object()  # the compiled path's "decide in Python"

FEW_ROWS = 8
"""Largest number of rows :func:`project_few` enumerates (the pairs grow as k^2)."""

REL_TOL = 1e-12
""":func:`project_few`'s default ``rel_tol``."""


def _holds(res: list[float], tol: list[float]) -> bool:
    for r, t in zip(res, tol):
        if r < -t:  # (finite floats: the negation of r >= -t)
            return False
    return True


def project_few(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, rel_tol: float = REL_TOL,
                kernels: tuple[Callable[..., Any], Callable[..., Any]] | None = None,
                ) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The solution of ``min |u - u_nom|^2 s.t. A u >= lb`` if at most two rows are active there.

    Args:
        A: Rows, shape (k, m), ``k <= FEW_ROWS``.
        lb: Lower bounds, shape (k,).
        u_nom: The point projected, shape (m,).
        rel_tol: A row counts as satisfied at ``r_i >= -rel_tol max(1, |lb_i|)`` (rounding).
        kernels: :func:`~isf_robot.core.fast.few_kernels` (the same answers, compiled), or ``None``.

    Returns:
        ``(u, A u - lb, min_i (A u - lb)_i)``, or ``None`` (see the module docstring).

    """
    if kernels is not None and A.dtype == _F64 and lb.dtype == _F64 and u_nom.dtype == _F64 and A.ndim == 2:
        k, m = A.shape
        if lb.shape == (k,) and u_nom.shape == (m,):
            hit = _compiled(A, lb, u_nom, rel_tol, kernels)
            if hit is not _PY:
                return hit
    r0 = matvec(A, u_nom) - lb
    rl = r0.tolist()
    if not math.isfinite(sum(rl)):
        return None
    tol = [rel_tol * b if b > 1.0 else rel_tol for b in map(abs, lb.tolist())]  # (= rel_tol max(1, |lb_i|))
    k = len(rl)
    neg = [i for i in range(k) if rl[i] < -tol[i]]
    if not neg:
        return u_nom.copy(), r0, min(rl)
    G = gram(A).tolist()
    sqrt = math.sqrt
    viol = sorted((i for i in neg if G[i][i] > 1e-200), key=lambda i: rl[i] / sqrt(G[i][i]))
    rng = range(k)
    for i in viol:  # one active row
        gi = G[i]
        lam = -rl[i] / gi[i]
        for j in rng:  # (row i is active by construction: its predicted residual is 0)
            if j != i and rl[j] + lam * gi[j] < -tol[j]:
                break
        else:
            hit = _confirm(A, lb, tol, u_nom + lam * A[i])
            if hit is not None:
                return hit
    for i in viol:  # two active rows: i (violated at u_nom) and any other
        gi = G[i]
        gii, ri = gi[i], rl[i]
        for j in rng:
            if j == i or (j in viol and j < i):
                continue
            gj = G[j]
            gjj = gj[j]
            if gjj <= 1e-200:
                continue
            gij = gi[j]
            det = gii * gjj - gij * gij
            if not det > 1e-12 * gii * gjj:
                continue
            rj = rl[j]
            li = (-ri * gjj + rj * gij) / det
            lj = (-rj * gii + ri * gij) / det
            if not (li >= 0.0 and lj >= 0.0):
                continue
            for q in rng:
                if q != i and q != j and rl[q] + li * gi[q] + lj * gj[q] < -tol[q]:
                    break
            else:
                hit = _confirm(A, lb, tol, u_nom + li * A[i] + lj * A[j])
                if hit is not None:
                    return hit
    return None


def _compiled(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, rel_tol: float,
              kernels: tuple[Callable[..., Any], Callable[..., Any]]) -> Any:
    """:func:`project_few` with the compiled kernels; ``_PY`` when the Python path must decide.

    The first candidate of the enumeration is confirmed on the rows; if it fails (rounding), the
    Python path enumerates again from the start (the same first candidate, then the next ones).
    """
    candidate, confirm = kernels
    r0 = matvec(A, u_nom) - lb
    tol = np.empty(A.shape[0])
    u = np.empty(A.shape[1])
    code, low = candidate(A, lb, u_nom, r0, gram(A), rel_tol, tol, u)
    if code == 1:
        res = matvec(A, u) - lb
        ok, low = confirm(res, u, tol)
        return (u, res, low) if ok else _PY
    if code == 0:
        return u_nom.copy(), r0, low
    return None if code < 0 else _PY


def _confirm(A: np.ndarray, lb: np.ndarray, tol: list[float],
             u: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """``(u, A u - lb, min)`` when ``u`` is finite and every row holds on the rows themselves.

    To ``tol`` times ``max(1, |u|_inf)``: the rounding of ``A u`` grows with ``u``.
    """
    res = matvec(A, u) - lb
    rl, ul = res.tolist(), u.tolist()
    if not (math.isfinite(sum(rl)) and math.isfinite(sum(ul))):
        return None
    scale = max(1.0, max(map(abs, ul)))
    for r, t in zip(rl, tol):
        if r < -t * scale:
            return None
    return u, res, min(rl)
