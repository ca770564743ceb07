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
  parallel rows, an infeasible problem: no answer;
* any active set of at most ``m`` rows of a few (:func:`project_active`, where :func:`project_few` has no
  answer): a primal active-set iteration, its answer returned only with the KKT conditions above met
  (``lam >= 0``, every row confirmed as above). Dependent or nearly singular active rows, no convergence,
  an infeasible problem: no answer, and the caller's QP backend decides.

With input bounds, the answer of the rows alone is the bounded optimum when it satisfies them
(:func:`within_bounds`; no bound active): :func:`project_few_within` (:func:`project_few`, else
:func:`project_active`, kept only within the bounds).

Plain functions over numpy arrays; :func:`~isf_robot.core.jit.compiled` compiles these same
functions (the filters and :class:`~isf_robot.core.qp_solver.QPSolver` call them one way or the
other). Every answer is checked before it is returned.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import formula

__all__ = ["project_row", "project_few", "project_few_within", "project_active", "within_bounds", "FEW_ROWS",
           "REL_TOL"]

FEW_ROWS = 8
"""Largest number of rows :func:`project_few` enumerates (the pairs grow as k^2)."""

REL_TOL = 1e-12
""":func:`project_few`'s ``rel_tol``."""


@formula
def project_row(a: np.ndarray, lb: float, u_nom: np.ndarray, feas_tol: float, u: np.ndarray) -> tuple:
    """``min |u - u_nom|^2  s.t.  a u >= lb``, checked: ``(code, slack)``.

    ``code`` 0: the row holds at ``u_nom`` (the answer is ``u_nom``; ``u`` not written); 1: the
    projection, written to ``u``; -1: no closed-form answer (``|a|^2`` underflows while the row is
    violated, or the answer violates the row beyond ``feas_tol max(1, |lb|)`` or is not finite: the
    caller's backend decides). ``slack = a u - lb`` of the answer.
    """
    gap = lb - a @ u_nom
    if gap <= 0.0:
        if not math.isfinite(u_nom @ u_nom):
            return -1, 0.0
        return 0, -gap
    aa = a @ a
    if not aa > 1e-200:
        return -1, 0.0
    u[:] = u_nom + (gap / aa) * a
    slack = a @ u - lb
    if not (slack >= -feas_tol * max(1.0, abs(lb)) and math.isfinite(u @ u)):
        return -1, 0.0
    return 1, slack


@formula
def _residuals(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, rel_tol: float) -> tuple:
    """``(r, tol, total)``: the rows' residuals ``a_i u_nom - lb_i``, tolerances ``rel_tol max(1, |lb_i|)``, and sum."""
    k, m = A.shape
    r = np.empty(k)
    tol = np.empty(k)
    total = 0.0
    for i in range(k):
        s = -lb[i]
        for q in range(m):
            s += A[i, q] * u_nom[q]
        r[i] = s
        total += s
        tol[i] = rel_tol * max(1.0, abs(lb[i]))
    return r, tol, total


@formula
def _gram(A: np.ndarray) -> np.ndarray:
    """``G = A A^T`` (k, k), each entry summed in the order of the inputs."""
    k, m = A.shape
    G = np.empty((k, k))
    for i in range(k):
        for j in range(i, k):
            s = 0.0
            for q in range(m):
                s += A[i, q] * A[j, q]
            G[i, j] = s
            G[j, i] = s
    return G


@formula
def project_few(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, rel_tol: float, u: np.ndarray,
                res: np.ndarray) -> tuple:
    """``min |u - u_nom|^2  s.t.  A u >= lb`` when at most two rows are active there: ``(code, min residual)``.

    ``code`` 0: every row holds at ``u_nom`` (``u``, ``res = A u - lb`` written); 1: the solution in
    ``u`` and ``res``; -1: no such answer (see the module docstring). ``A`` (k, m) with k <= FEW_ROWS.
    Written as loops over the few rows (what the compiled code runs fastest).
    """
    k, m = A.shape
    r, tol, total = _residuals(A, lb, u_nom, rel_tol)
    if not math.isfinite(total):
        return -1, 0.0
    low = math.inf
    nneg = 0
    for i in range(k):
        if r[i] < -tol[i]:
            nneg += 1
        low = min(low, r[i])
    if nneg == 0:
        u[:] = u_nom
        res[:k] = r
        return 0, low
    G = _gram(A)
    order = np.empty(k, np.int64)  # the violated rows, most violated first (a stable insertion sort)
    keys = np.empty(k)
    violated = np.zeros(k, np.bool_)
    nv = 0
    for i in range(k):
        if r[i] < -tol[i] and G[i, i] > 1e-200:
            key = r[i] / math.sqrt(G[i, i])
            p = nv
            while p > 0 and key < keys[p - 1]:
                keys[p] = keys[p - 1]
                order[p] = order[p - 1]
                p -= 1
            keys[p] = key
            order[p] = i
            nv += 1
            violated[i] = True
    for a in range(nv):  # one active row: lam = -r_i / G_ii
        i = order[a]
        lam = -r[i] / G[i, i]
        ok = True
        for j in range(k):
            if j != i and r[j] + lam * G[i, j] < -tol[j]:
                ok = False
                break
        if ok:
            for q in range(m):
                u[q] = u_nom[q] + lam * A[i, q]
            got = _confirm(A, lb, u, tol, res)
            if got == got:
                return 1, got
    for a in range(nv):  # two active rows: i (violated at u_nom) and any other, by Cramer's rule
        i = order[a]
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
            ok = True
            for q in range(k):
                if q != i and q != j and r[q] + li * G[i, q] + lj * G[j, q] < -tol[q]:
                    ok = False
                    break
            if ok:
                for q in range(m):
                    u[q] = (u_nom[q] + li * A[i, q]) + lj * A[j, q]
                got = _confirm(A, lb, u, tol, res)
                if got == got:
                    return 1, got
    return -1, 0.0


@formula
def project_few_within(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, rel_tol: float, u_min: np.ndarray,
                       u_max: np.ndarray, u: np.ndarray, res: np.ndarray) -> tuple:
    """:func:`project_few`'s answer (else :func:`project_active`'s) kept only within ``u_min <= u <= u_max``.

    ``(code, min residual)``.

    The optimum of the rows alone, when it satisfies the bounds, is the optimum with the bounds too (a subset of
    the feasible set that holds the optimum; the bounds take no multiplier). ``u_min``, ``u_max``: length 0 for
    none. ``code`` as :func:`project_few`'s; -1 also when a bound fails (exactly, no tolerance: a bound that the
    answer crosses by any amount binds at the bounded optimum, which the caller's backend finds).
    """
    code, low = project_few(A, lb, u_nom, rel_tol, u, res)
    if code < 0:
        code, low = project_active(A, lb, u_nom, rel_tol, u, res)
        if code < 0:
            return code, low
    if not within_bounds(u, u_min, u_max):
        return -1, 0.0
    return code, low


@formula
def project_active(A: np.ndarray, lb: np.ndarray, u_nom: np.ndarray, rel_tol: float, u: np.ndarray,
                   res: np.ndarray) -> tuple:
    """``min |u - u_nom|^2  s.t.  A u >= lb`` (at most ``FEW_ROWS`` rows) by a primal active-set iteration, certified.

    From ``u_nom``: add the most violated row (normalised by ``|a_i|``) to the active set ``S``, solve
    ``G_SS lam = -r_S`` (``u = u_nom + A_S^T lam``; Gaussian elimination with partial pivoting), drop the row of the
    most negative multiplier until every ``lam >= 0``; until no row is violated (at most ``3 k + 3`` additions). An
    answer is returned only with its certificate, the KKT conditions: ``lam >= 0`` and every row holding to
    ``rel_tol max(1, |lb_i|) max(1, |u|_inf)`` (:func:`_confirm`; stationarity and ``A_S u = lb_S`` by
    construction): the optimum to that tolerance. ``(code, min residual)`` as :func:`project_few`'s
    (``res = A u - lb``); -1 (the caller's backend decides): more active rows than inputs, a (nearly) singular
    ``G_SS`` (pivot below ``1e-12`` of ``G``'s largest diagonal), no convergence, or an answer without its
    certificate.
    """
    k, m = A.shape
    r, tol, total = _residuals(A, lb, u_nom, rel_tol)
    if not math.isfinite(total):
        return -1, 0.0
    G = _gram(A)
    gmax = 0.0
    for i in range(k):
        gmax = max(gmax, G[i, i])
    S = np.empty(k, np.int64)
    inS = np.zeros(k, np.bool_)
    lam = np.zeros(k)
    M = np.empty((k, k + 1))
    slack = r.copy()
    ns = 0
    done = False
    for _ in range(3 * k + 3):
        add = -1
        worst = 0.0
        for i in range(k):
            if not inS[i] and slack[i] < -tol[i] and G[i, i] > 1e-200:
                key = slack[i] / math.sqrt(G[i, i])
                if key < worst:
                    worst, add = key, i
        if add < 0:
            done = True
            break
        if ns == m:  # (more active rows than inputs: dependent; the backend)
            return -1, 0.0
        S[ns] = add
        inS[add] = True
        ns += 1
        while True:
            for a in range(ns):  # the system G_SS lam = -r_S, augmented
                for b in range(ns):
                    M[a, b] = G[S[a], S[b]]
                M[a, ns] = -r[S[a]]
            for c in range(ns):  # elimination with partial pivoting
                piv = c
                for a in range(c + 1, ns):
                    if abs(M[a, c]) > abs(M[piv, c]):
                        piv = a
                if not abs(M[piv, c]) > 1e-12 * gmax:
                    return -1, 0.0
                if piv != c:
                    for b in range(c, ns + 1):
                        M[c, b], M[piv, b] = M[piv, b], M[c, b]
                for a in range(c + 1, ns):
                    f = M[a, c] / M[c, c]
                    for b in range(c, ns + 1):
                        M[a, b] -= f * M[c, b]
            for c in range(ns - 1, -1, -1):
                s = M[c, ns]
                for b in range(c + 1, ns):
                    s -= M[c, b] * lam[b]
                lam[c] = s / M[c, c]
            drop = -1
            low = 0.0
            for a in range(ns):
                if lam[a] < low:
                    low, drop = lam[a], a
            if drop < 0:
                break
            inS[S[drop]] = False
            for a in range(drop, ns - 1):
                S[a] = S[a + 1]
            ns -= 1
            if ns == 0:
                break
        for i in range(k):
            s = r[i]
            for a in range(ns):
                s += G[i, S[a]] * lam[a]
            slack[i] = s
    if not done:
        return -1, 0.0
    for q in range(m):
        s = u_nom[q]
        for a in range(ns):
            s += lam[a] * A[S[a], q]
        u[q] = s
    got = _confirm(A, lb, u, tol, res)  # (also a violated row too small to add: refused here)
    if got == got:
        return (0 if ns == 0 else 1), got
    return -1, 0.0


@formula
def within_bounds(u: np.ndarray, u_min: np.ndarray, u_max: np.ndarray) -> bool:
    """``u_min <= u <= u_max`` exactly (length 0: no bound; NaN: false; a bound not of ``u``'s length: false)."""
    m = u.shape[0]
    if (u_min.shape[0] != 0 and u_min.shape[0] != m) or (u_max.shape[0] != 0 and u_max.shape[0] != m):
        return False
    for q in range(u_min.shape[0]):
        if not u[q] >= u_min[q]:
            return False
    for q in range(u_max.shape[0]):
        if not u[q] <= u_max[q]:
            return False
    return True


@formula
def _confirm(A: np.ndarray, lb: np.ndarray, u: np.ndarray, tol: np.ndarray, res: np.ndarray) -> float:
    """``min(A u - lb)`` (``res``) when ``u`` is finite and every row holds to ``tol max(1, |u|_inf)``; NaN if not."""
    k, m = A.shape
    scale = 1.0
    for q in range(m):
        scale = max(scale, abs(u[q]))
    if not scale < math.inf:  # (NaN or inf in u)
        return math.nan
    low = math.inf
    for i in range(k):
        s = -lb[i]
        for q in range(m):
            s += A[i, q] * u[q]
        res[i] = s
        if not s >= -tol[i] * scale:  # (NaN: refused)
            return math.nan
        low = min(low, s)
    return low
