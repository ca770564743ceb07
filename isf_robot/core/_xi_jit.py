"""The numba kernel of :mod:`isf_robot.core.fast` (imported only when numba is installed).

A module-level function, so numba's cache (``__pycache__``) serves later processes. The product
``Lg h u`` of each row is made here in :func:`isf_robot.core.sums.matvec`'s written order (the row's
products added in column order, from the first), as :func:`~isf_robot.core.triggers.xi_on` makes it.
"""

from __future__ import annotations

import math

from numba import njit

from .jit import watch_compiles

watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)


@njit(cache=True, nogil=True, inline="always")
def row_times(a, i, u):  # pragma: no cover (compiled)
    """``a[i] . u``: the products added in column order, from the first (0 without columns; ``sums.matvec``)."""
    m = u.shape[0]
    if m == 0:
        return 0.0
    s = a[i, 0] * u[0]
    for q in range(1, m):
        s = s + a[i, q] * u[q]
    return s


@njit(cache=True, nogil=True, inline="always")
def _xi_row(lf, lg, u, gn, d_bar, h, gain, av, i):  # pragma: no cover (compiled)
    """Row ``i``'s ``Xi_on``: ``((lf + lg u) - gn d_bar) + alpha(h)`` (``gain h`` when ``gain > 0``, else ``av``)."""
    return ((lf[i] + row_times(lg, i, u)) - gn[i] * d_bar) + (gain * h[i] if gain > 0.0 else av[i])


@njit(cache=True, nogil=True)
def xi_plain(lf, lg, u, gn, d_bar, h, gain, av, out):  # pragma: no cover (compiled)
    """:func:`xi_screen` without thresholds (no rows counted or listed): one argument less to pass per step."""
    k = out.shape[0]
    total = 0.0
    low = math.inf
    arg = 0
    for i in range(k):
        x = _xi_row(lf, lg, u, gn, d_bar, h, gain, av, i)
        out[i] = x
        total += x
        if x < low:
            low = x
            arg = i
    return total, low, arg


@njit(cache=True, nogil=True)
def xi_screen(lf, lg, u, gn, d_bar, h, gain, av, screen, out, rows):  # pragma: no cover (compiled)
    """``out = ((lf + lg u) - gn d_bar) + av`` and, in the same pass, what the filter step reads of it.

    ``av``: ``alpha(h)`` per row; with ``gain > 0`` (a linear alpha) ``av_i = gain h_i`` instead
    (the product ``Linear.vector`` makes). Returns ``(sum, min, first index of the min, rows below
    their threshold, first such row)``; ``screen``: no entries (no screening: count -1), one
    (every row's threshold) or one per row. The rows below their threshold are written to ``rows``
    (ascending) as far as it has room.
    """
    k = out.shape[0]
    ns = screen.shape[0]
    total = 0.0
    low = math.inf
    arg = 0
    kept = 0 if ns else -1
    first = -1
    for i in range(k):
        x = _xi_row(lf, lg, u, gn, d_bar, h, gain, av, i)
        out[i] = x
        total += x
        if x < low:
            low = x
            arg = i
        if ns:
            if x < (screen[i] if ns > 1 else screen[0]):
                if kept < rows.shape[0]:
                    rows[kept] = i
                kept += 1
                if first < 0:
                    first = i
    return total, low, arg, kept, first
