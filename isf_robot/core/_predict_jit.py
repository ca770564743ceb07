"""The numba kernels of :func:`isf_robot.core.intermittent.predict`'s stacked way (imported only with numba).

A module-level function that calls no compiled function of another file, so numba's cache
(``__pycache__``) serves later processes and is invalidated by an edit of this file.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .jit import watch_compiles

watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)


@njit(cache=True, nogil=True)
def predict_rows(lf, lg, u, gn, d_bar, h, gain, av, k, xi, fails, nfail, keys, nkeys, out):  # pragma: no cover
    """``Xi_on`` of every predicted point's rows and what :func:`predict` reads of them, point by point.

    Point ``j`` has ``k[j]`` rows in row ``j`` of the 2-D arrays ``lf``, ``gn``, ``h`` and ``av``
    (``alpha(h)``; with ``gain > 0``, a linear alpha, ``gain h`` instead, the product
    ``Linear.vector`` makes) and of the 3-D ``lg`` (``Lg h``, shape (n, K, m)), its command ``u[j]``.
    ``xi[j, i] = ((lf + lg u) - gn d_bar) + av``: :func:`~isf_robot.core.triggers.xi_on`'s
    operations in its order (``lg u`` each row's products added in column order from the first, as
    :func:`isf_robot.core.sums.matvec`), as the filter's kernel ``_xi_jit.xi_screen`` makes them.
    Per point, in order: the sum of its values in Python's order (a point whose sum is not finite
    stops the pass: returned as ``bad``), the least value (``<``: the first of equal values), and
    the rows with ``xi <= 0`` (``fails[j, :nfail[j]]``, ascending). Returns ``(bad, xi_min, c)``:
    ``bad`` -1 when every point is finite; ``xi_min`` the least value over the points before
    ``bad`` that have rows (``inf``: none); with ``keys`` (shape (n, K); no rows: none) and every
    point finite, ``c`` failing rows' keys in ``out[:c]`` (:func:`failing_keys`, ``nkeys`` keys;
    -1: a key outside them), else 0.
    """
    n = k.shape[0]
    m = u.shape[1]
    low = math.inf
    for j in range(n):
        kj = k[j]
        nfail[j] = 0
        if kj == 0:
            continue
        total = 0.0
        lo = math.inf
        for i in range(kj):
            lgu = 0.0
            if m > 0:
                lgu = lg[j, i, 0] * u[j, 0]
                for q in range(1, m):
                    lgu = lgu + lg[j, i, q] * u[j, q]
            x = ((lf[j, i] + lgu) - gn[j, i] * d_bar) + (gain * h[j, i] if gain > 0.0 else av[j, i])
            xi[j, i] = x
            total += x
            if x < lo:
                lo = x
        if not math.isfinite(total):
            return j, low, 0
        if lo < low:
            low = lo
        if lo <= 0.0:
            c = 0
            for i in range(kj):
                if xi[j, i] <= 0.0:
                    fails[j, c] = i
                    c += 1
            nfail[j] = c
    if keys.shape[0] == 0:
        return -1, low, 0
    return -1, low, failing_keys(keys, fails, nfail, np.zeros(nkeys, np.bool_), out)


@njit(cache=True, nogil=True)
def failing_keys(keys, fails, nfail, seen, out):  # pragma: no cover (compiled)
    """The keys of the failing rows (``keys[j, fails[j, i]]`` for ``i < nfail[j]``), each once, in order of first sight.

    ``seen``: a False array with one entry per key (left False again); ``out``: room for every failing
    row. Returns their number, or -1 if a key lies outside ``seen`` (the caller's error).
    """
    c = 0
    nk = seen.shape[0]
    for j in range(nfail.shape[0]):
        for i in range(nfail[j]):
            key = keys[j, fails[j, i]]
            if key < 0 or key >= nk:
                for r in range(c):
                    seen[out[r]] = False
                return -1
            if not seen[key]:
                seen[key] = True
                out[c] = key
                c += 1
    for r in range(c):
        seen[out[r]] = False
    return c
