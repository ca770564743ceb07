"""The numba kernels of the filters' screened few-row step (imported only when numba is installed).

Module-level functions, so numba's cache (``__pycache__``) serves later processes. Each makes
the general path's elementwise operations (numpy's, in :meth:`_FilterBase._solve_rows`,
:meth:`_FilterBase.qp_lower` and :func:`~isf_robot.core.qp_small.project_few`) in their order:
IEEE float64 operations that numpy and the compiled loop round alike (numba does not contract
them into fused multiply-adds without ``fastmath``). :func:`few_step` also makes the few-row
products (``A u_nom``, ``A A^T``, ``A u``, ``Lg h du``) in the written order of
:mod:`isf_robot.core.sums` (each row's products added in column order, from the first), as the
general path does. :mod:`isf_robot.core.filter_short` calls them; ``tests/core/test_fast_step.py``
checks them against the general path bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._few_jit import few_candidate, few_confirm
from .jit import watch_compiles

watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)


@njit(cache=True, nogil=True, inline="always")
def _npmax(a, b):  # pragma: no cover (compiled)
    """``np.maximum(a, b)``: NaN if either is NaN, else ``a`` when ``a > b``, else ``b`` (equal: ``b``)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a > b else b


@njit(cache=True, nogil=True)
def select_rows(xi, screen, floor, promote, rows):  # pragma: no cover (compiled)
    """The kept rows: ``xi < np.maximum(screen, floor)`` (``floor > 0``; else ``xi < screen``), or promoted.

    ``screen``: one threshold for every row or one per row; ``promote``: no entries (none) or one
    per row. Writes the kept rows' indices, ascending, to ``rows`` and returns their count.
    """
    k = xi.shape[0]
    ns = screen.shape[0]
    npr = promote.shape[0]
    up = floor > 0.0
    n = 0
    for i in range(k):
        s = screen[i] if ns > 1 else screen[0]
        if up:
            s = _npmax(s, floor)
        if xi[i] < s or (npr > 0 and promote[i]):
            rows[n] = i
            n += 1
    return n


@njit(cache=True, nogil=True)
def few_lower_candidate(rows, h, lf, gn, d_bar, gain, av, av_rows, promote, ramp, b, Au, G, A, u_nom,
                        rel_tol, buf, u):  # pragma: no cover (compiled)
    """The kept rows' QP bounds (``qp_lower``), ``r = A u_nom - lb`` and the few-row enumeration's first candidate.

    Row ``j`` of the QP is row ``rows[j]`` of the filter's data. ``alpha(h)``: ``gain h`` when
    ``gain > 0``, else ``av`` (indexed by the QP's row when ``av_rows``, else by the data's).
    ``promote`` (no entries: none) and ``ramp`` (no entries: 1 for every row) are indexed by the
    data's row. Writes ``lb``, ``r`` and the rows' tolerances to ``buf[0]``, ``buf[1]``, ``buf[2]``
    (the first ``n`` entries), then returns :func:`~isf_robot.core._few_jit.few_candidate`'s
    ``(code, min r)`` (``Au = A u_nom``, ``G = A A^T``: :mod:`isf_robot.core.sums`' products).
    """
    n = rows.shape[0]
    lb, r, tol = buf[0, :n], buf[1, :n], buf[2, :n]
    npr = promote.shape[0]
    nr = ramp.shape[0]
    any_p = False
    all_one = True
    for j in range(n):
        i = rows[j]
        if npr > 0 and promote[i]:
            any_p = True
        if nr > 0 and not ramp[i] >= 1.0:
            all_one = False
    for j in range(n):
        i = rows[j]
        if gain > 0.0:
            rhs = -(gain * h[i])
        else:
            rhs = -(av[j] if av_rows else av[i])
        if any_p and promote[i]:
            if all_one:
                rhs = b
            else:
                w = ramp[i]
                rhs = _npmax(rhs, w * b + (1.0 - w) * rhs)
        lb[j] = (rhs - lf[i]) + gn[i] * d_bar
        r[j] = Au[j] - lb[j]
    return few_candidate(A, lb, u_nom, r, G, rel_tol, tol, u)


@njit(cache=True, nogil=True)
def few_finish(Au, u, u_nom, buf, active_tol, active, du):  # pragma: no cover (compiled)
    """``res = A u - lb``, its check (``_few_jit.few_confirm``), ``active = res <= active_tol``, ``du = u - u_nom``.

    ``lb`` and the tolerances in ``buf[0]`` and ``buf[2]`` (:func:`few_lower_candidate`); ``res`` goes
    to ``buf[3]``. Returns ``(ok, min res)``; ``active`` and ``du`` are written only when ``ok``.
    """
    n = active.shape[0]
    lb, tol, res = buf[0, :n], buf[2, :n], buf[3, :n]
    for j in range(n):
        res[j] = Au[j] - lb[j]
    ok, low = few_confirm(res, u, tol)
    if ok:
        for j in range(res.shape[0]):
            active[j] = res[j] <= active_tol
        for q in range(u.shape[0]):
            du[q] = u[q] - u_nom[q]
    return ok, low


@njit(cache=True, nogil=True)
def screened_hold(xi, lgdu, rows, n, active_tol):  # pragma: no cover (compiled)
    """Whether every row not in ``rows[:n]`` (ascending) has ``xi + lgdu >= active_tol`` (NaN: no)."""
    j = 0
    for i in range(xi.shape[0]):
        if j < n and rows[j] == i:
            j += 1
            continue
        if not xi[i] + lgdu[i] >= active_tol:
            return False
    return True


@njit(cache=True, nogil=True)
def on_rows(xi, c, failing, ramp_on, ids, W, inw, rate, screen, mask, weights, rows):  # pragma: no cover (compiled)
    """The intermittent filter's on step before its QP: the promoted rows, the hand-over ramp and the kept rows.

    ``mask = xi < c`` or ``failing`` (no entries: none). With ``ramp_on``, the hand-over ramp of
    :meth:`~isf_robot.core.filters.IntermittentSafetyFilter._row_ramp` on per-key state:
    ``ids[i]`` is row ``i``'s key, ``W``/``inw`` each key's weight and whether it has one; a key
    is promoted now when its last row is; every other key with a weight moves down by ``rate``
    (dropped at <= 0), a promoted one up by ``rate`` (at most 1; a new one starts at 0); then
    ``mask``/``weights`` are the rows whose key has a weight >= 0 (and that weight; 1 elsewhere).
    With a threshold in ``screen`` (one, or one per row): writes the kept rows (``xi <
    np.maximum(screen, c)`` for ``c > 0``, or in ``mask``) to ``rows`` and returns their count;
    -1 without.
    """
    k = xi.shape[0]
    nf = failing.shape[0]
    for i in range(k):
        mask[i] = xi[i] < c or (nf > 0 and failing[i])
    if ramp_on:
        nid = W.shape[0]
        cur = np.full(nid, -1, np.int8)  # per key: promoted now (its last row), 0 not, -1 not a row now
        for i in range(k):
            cur[ids[i]] = 1 if mask[i] else 0
        for q in range(nid):
            if inw[q] and cur[q] != 1:
                W[q] -= rate
                if W[q] <= 0.0:
                    inw[q] = False
        for q in range(nid):
            if cur[q] == 1:
                if inw[q]:
                    x = W[q] + rate
                    W[q] = x if x < 1.0 else 1.0  # (= min(1.0, x), NaN included)
                else:
                    W[q] = 0.0
                    inw[q] = True
        for i in range(k):
            q = ids[i]
            if inw[q] and W[q] >= 0.0:
                mask[i] = True
                weights[i] = W[q]
            else:
                mask[i] = False
                weights[i] = 1.0
    if screen.shape[0] == 0:
        return -1
    return select_rows(xi, screen, c, mask, rows)


@njit(cache=True, nogil=True, inline="always")
def _dot(v, w, m):  # pragma: no cover (compiled)
    """``v . w`` of two vectors of ``m >= 1`` entries (any layout), added in order from the first (``sums.dot``)."""
    s = v[0] * w[0]
    for q in range(1, m):
        s = s + v[q] * w[q]
    return s


@njit(cache=True, nogil=True)
def few_step(rows, h, lf, gn, d_bar, gain, av, av_rows, promote, ramp, b, lg, u_nom, rel_tol, buf, u,
             active_tol, active, du, xi, hold):  # pragma: no cover (compiled)
    """The screened few-row step in one call: :func:`few_lower_candidate`, :func:`few_finish` and :func:`screened_hold`.

    The QP's rows ``A`` are the rows ``rows`` of ``lg`` (``Lg h``, shape (k, m), m >= 1); its
    products ``A u_nom``, ``A A^T``, ``A u`` and the rows' ``Lg h du`` are made here in
    :mod:`isf_robot.core.sums`' order. Returns ``(code, low, held)``: ``code`` 0 every kept row
    holds at ``u_nom`` (``u`` = ``u_nom``, ``active``, ``du = 0`` written), 1 a confirmed
    candidate (``u``, ``active``, ``du`` written), 2 the Python enumeration decides (``G`` not
    finite, or the candidate failed its confirmation; ``buf[0]`` holds ``lb``), < 0 no few-row
    answer; ``low`` the least residual; ``held`` (codes 0 and 1, with ``hold``) whether every row
    not in ``rows`` keeps slack ``xi + Lg h du >= active_tol`` (True without ``hold``).
    """
    n = rows.shape[0]
    m = u_nom.shape[0]
    A = np.empty((n, m))
    for j in range(n):
        for q in range(m):
            A[j, q] = lg[rows[j], q]
    Au = np.empty(n)
    G = np.empty((n, n))
    for j in range(n):
        Au[j] = _dot(A[j], u_nom, m)
        for c in range(n):
            G[j, c] = _dot(A[j], A[c], m)
    code, low = few_lower_candidate(rows, h, lf, gn, d_bar, gain, av, av_rows, promote, ramp, b, Au, G, A, u_nom,
                                    rel_tol, buf, u)
    if code == 0:
        for q in range(m):
            u[q] = u_nom[q]
            du[q] = u[q] - u_nom[q]
        for j in range(n):
            active[j] = buf[1, j] <= active_tol
    elif code == 1:
        for j in range(n):
            Au[j] = _dot(A[j], u, m)
        ok, low = few_finish(Au, u, u_nom, buf, active_tol, active, du)
        if not ok:
            return 2, low, False
    else:
        return code, low, False
    if not hold:
        return code, low, True
    lgdu = np.zeros(xi.shape[0])
    j = 0
    for i in range(xi.shape[0]):
        if j < n and rows[j] == i:
            j += 1
            continue
        lgdu[i] = _dot(lg[i], du, m)
    return code, low, screened_hold(xi, lgdu, rows, n, active_tol)


@njit(cache=True, nogil=True)
def one_step(i, lb, lg, u_nom, feas_tol, active_tol, xi, u, du):  # pragma: no cover (compiled)
    """One kept row ``i`` (``lg[i] u >= lb``) in one call: the closed form and the check of every other row.

    :meth:`~isf_robot.core.qp_solver.QPSolver.solve_row`'s operations in its order, the products
    ``a . a``, ``a . u_nom``, ``a . u``, ``u . u`` and the other rows' ``Lg h (u - u_nom)`` in
    :mod:`isf_robot.core.sums`' written order. Returns ``(code, slack, held)``: -1 no closed-form
    answer (``|a|^2`` underflows, the answer violates the row beyond ``feas_tol`` or is not finite:
    the caller solves the general way); 0 the row holds at ``u_nom`` (the answer is ``u_nom``;
    ``u``/``du`` not written); 1 ``u = u_nom + (gap / |a|^2) a`` and ``du = u - u_nom`` written.
    ``slack = a . u - lb``; ``held``: every other row keeps ``xi_j + Lg h_j du >= active_tol``.
    """
    m = u_nom.shape[0]
    aa = _dot(lg[i], lg[i], m) if m else 0.0
    if not aa > 1e-200:
        return -1, 0.0, False
    gap = lb - _dot(lg[i], u_nom, m)
    if gap <= 0.0:
        if not np.isfinite(_dot(u_nom, u_nom, m)):
            return -1, 0.0, False
        for j in range(xi.shape[0]):  # (du = 0: the other rows' slack is their xi)
            if j != i and not xi[j] >= active_tol:
                return 0, -gap, False
        return 0, -gap, True
    s = gap / aa
    for q in range(m):
        u[q] = u_nom[q] + s * lg[i, q]
        du[q] = u[q] - u_nom[q]
    slack = _dot(lg[i], u, m) - lb
    b = abs(lb)
    if not (slack >= -feas_tol * (b if b > 1.0 else 1.0) and np.isfinite(_dot(u, u, m))):
        return -1, 0.0, False
    for j in range(xi.shape[0]):
        if j != i and not xi[j] + _dot(lg[j], du, m) >= active_tol:
            return 1, slack, False
    return 1, slack, True
