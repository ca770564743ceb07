"""The numba kernels of :func:`isf_robot.core.qp_small.project_few` (imported only when numba is installed).

Module-level functions, so numba's cache (``__pycache__``) serves later processes. They make the
pure-Python path's scalar operations in its order (IEEE float64 operations that Python floats and
the compiled loop round alike; numba does not contract them into fused multiply-adds without
``fastmath``); the products ``A u_nom``, ``A A^T`` and ``A u`` are passed in, made in
:mod:`isf_robot.core.sums`' written order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .jit import watch_compiles

watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)


@njit(cache=True, nogil=True)
def few_candidate(A, lb, u_nom, r, G, rel_tol, tol, u):  # pragma: no cover (compiled)
    """The first candidate of :func:`~isf_robot.core.qp_small.project_few`'s enumeration.

    ``r = A u_nom - lb``, ``G = A A^T``; writes ``tol`` (each row's tolerance) and, for a
    candidate, ``u``. Returns ``(code, min r)``: -2 ``r`` not finite (no answer); 0 every row
    holds at ``u_nom`` (``min r`` set); 1 a candidate in ``u``, to be confirmed on the rows; -1 no
    candidate (no answer); 2 ``G`` not finite (the caller enumerates in Python).
    """
    k, m = A.shape
    total = 0.0
    for i in range(k):
        total += r[i]
    if not math.isfinite(total):
        return -2, 0.0
    nneg = 0
    low = math.inf
    for i in range(k):
        b = abs(lb[i])
        t = rel_tol * b if b > 1.0 else rel_tol
        tol[i] = t
        if r[i] < -t:
            nneg += 1
        if r[i] < low:
            low = r[i]
    if nneg == 0:
        return 0, low
    for i in range(k):
        for j in range(k):
            if not math.isfinite(G[i, j]):
                return 2, 0.0
    order = np.empty(k, np.int64)
    keys = np.empty(k)
    isv = np.zeros(k, np.bool_)
    nv = 0
    for i in range(k):  # the violated rows, most violated first (a stable insertion sort: sorted's order)
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
            isv[i] = True
    for a in range(nv):  # one active row
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
            return 1, 0.0
    for a in range(nv):  # two active rows
        i = order[a]
        gii = G[i, i]
        ri = r[i]
        for j in range(k):
            if j == i or (isv[j] and j < i):
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
                return 1, 0.0
    return -1, 0.0


@njit(cache=True, nogil=True)
def few_confirm(res, u, tol):  # pragma: no cover (compiled)
    """``(ok, min res)``: ``res`` and ``u`` finite and ``res_i >= -tol_i max(1, |u|_inf)`` for every row."""
    total = 0.0
    for x in res:
        total += x
    if not math.isfinite(total):
        return False, 0.0
    total = 0.0
    scale = 1.0
    for x in u:
        total += x
        if abs(x) > scale:
            scale = abs(x)
    if not math.isfinite(total):
        return False, 0.0
    low = math.inf
    for i in range(res.shape[0]):
        if res[i] < -tol[i] * scale:
            return False, 0.0
        if res[i] < low:
            low = res[i]
    return True, low
