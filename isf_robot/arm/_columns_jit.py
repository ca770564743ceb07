"""The compiled row write of :class:`~isf_robot.arm.step_columns.StepColumns` (imported only when numba is installed).

:func:`write_row` writes one control step into its row at the tick: the state and commands, the scalars,
``Xi_on``'s minimum, the tick's barrier values scattered into the row of ``h`` (the pairs beyond the cut-off
at their far value), ``h``'s minimum, the goal's position, and the near pairs with their witness points in the
flat buffers. What :meth:`StepColumns.seal <isf_robot.arm.step_columns.StepColumns.seal>` does for a stretch
of rows with NumPy (the path without numba, and for rows of other types), done for one row, so that nothing of
the step is kept until a seal. The block's own arrays and the state's sources are passed as one table of their
addresses (:func:`table`): a numba call costs about 0.1 us per array argument, which for the twenty-odd arrays a
row touches was more than the copy itself.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from llvmlite import ir
from numba import carray, types

from isf_robot.core.jit import formula

from ._kernels_jit import _pointer, f64p, i64p

__all__ = ["table", "write_row", "least", "SLOTS"]

u8p = _pointer(ir.IntType(8), types.uint8)
"""``u8p(addr)``: the address ``addr`` as a uint8 pointer (a NumPy bool array's bytes)."""

SLOTS = ("row_state", "width", "t", "on", "qp_solved", "fallback", "goal_index", "xi_min", "h", "k", "n_collision",
         "h_far", "h_min", "pair_start", "pairs", "witness", "goal_pos", "goals", "n_goals", "capacity")
"""The table's slots after the sources' (address, length) pairs, in order."""
_S = {name: i for i, name in enumerate(SLOTS)}
ROW_STATE, WIDTH, T, ON, QP, FALLBACK, GOAL_INDEX, XI_MIN, H, K, NC, H_FAR, H_MIN, PAIR_START, PAIRS, WITNESS, \
    GOAL_POS, GOALS, N_GOALS, CAPACITY = range(len(SLOTS))


def table(sources: Sequence[np.ndarray], **arrays: np.ndarray | int) -> np.ndarray:
    """The address table of :func:`write_row`: ``[m, (address, length) of each source, then the slots]``.

    ``sources``: the state's 1-D float64 contiguous views, in the row's order; ``arrays``: every slot of
    :data:`SLOTS` by name, an array (its address) or an int (taken as it is). The arrays must outlive the table.
    """
    m = len(sources)
    p = np.zeros(1 + 2 * m + len(SLOTS), dtype=np.int64)
    p[0] = m
    for k, s in enumerate(sources):
        p[1 + 2 * k], p[2 + 2 * k] = s.ctypes.data, s.size
    for name, v in arrays.items():
        p[1 + 2 * m + _S[name]] = v.ctypes.data if isinstance(v, np.ndarray) else int(v)
    return p


@formula
def least(a):  # type: ignore[no-untyped-def]
    """The smallest value of the 1-D array ``a``: NaN when it holds one (as NumPy's minimum), ``inf`` when empty."""
    lo = math.inf
    for e in range(a.shape[0]):
        v = a[e]
        if v != v:
            return v
        if v < lo:
            lo = v
    return lo


def write_row(p, i, t, on, qp, fallback, goal, u, u_nom, xi, rows, tick_h, wit, has_wit):  # type: ignore[no-untyped-def]  # pragma: no cover (compiled)
    """Write row ``i`` (see the module docstring); returns the pairs used after it, or -1 (nothing written).

    -1 when the row does not fit: ``i`` is past the block's capacity, ``u`` and ``u_nom`` are not of the
    row's width of joints, a near pair's index is not one of the block's collision pairs, ``tick_h`` does not
    hold the near pairs' and the joint rows' values, or the witness points are not of shape (j, 2 or more, 3);
    the caller then writes the row the NumPy way (which says what is wrong). ``wit``: the pairs' witness
    points, read when ``has_wit``.
    """
    m = p[0]
    b = 1 + 2 * m
    cap, k, nc = p[b + CAPACITY], p[b + K], p[b + NC]
    w = p[b + WIDTH]
    if i < 0 or i >= cap:
        return -1
    state = 0
    for s in range(m):
        state += p[2 + 2 * s]
    if u.shape[0] != u_nom.shape[0] or state + 2 * u.shape[0] != w:
        return -1
    j = rows.shape[0]
    if tick_h.shape[0] != j + k - nc:
        return -1
    if has_wit and (wit.shape[0] != j or wit.shape[1] < 2 or wit.shape[2] != 3):
        return -1
    for r in range(j):
        if rows[r] < 0 or rows[r] >= nc:
            return -1
    row = carray(f64p(p[b + ROW_STATE] + 8 * w * i), w)
    c = 0
    for s in range(m):
        src = carray(f64p(p[1 + 2 * s]), p[2 + 2 * s])
        for e in range(src.shape[0]):
            row[c] = src[e]
            c += 1
    for e in range(u.shape[0]):
        row[c] = u[e]
        c += 1
    for e in range(u_nom.shape[0]):
        row[c] = u_nom[e]
        c += 1
    carray(f64p(p[b + T]), cap)[i] = t
    carray(u8p(p[b + ON]), cap)[i] = 1 if on else 0
    carray(u8p(p[b + QP]), cap)[i] = 1 if qp else 0
    carray(u8p(p[b + FALLBACK]), cap)[i] = 1 if fallback else 0
    carray(i64p(p[b + GOAL_INDEX]), cap)[i] = goal
    carray(f64p(p[b + XI_MIN]), cap)[i] = least(xi)
    h = carray(f64p(p[b + H] + 8 * k * i), k)
    far = carray(f64p(p[b + H_FAR]), nc)
    for q in range(nc):
        h[q] = far[q]
    for r in range(j):
        h[rows[r]] = tick_h[r]
    for q in range(k - nc):
        h[nc + q] = tick_h[j + q]
    carray(f64p(p[b + H_MIN]), cap)[i] = least(h)
    gp = carray(f64p(p[b + GOAL_POS] + 24 * i), 3)
    ng = p[b + N_GOALS]
    if 0 <= goal < ng:
        g = carray(f64p(p[b + GOALS] + 24 * goal), 3)
        for d in range(3):
            gp[d] = g[d]
    else:
        for d in range(3):
            gp[d] = math.nan
    ps = carray(i64p(p[b + PAIR_START]), cap + 1)
    p0 = ps[i]
    pairs = carray(i64p(p[b + PAIRS] + 8 * p0), j)
    points = carray(f64p(p[b + WITNESS] + 48 * p0), (j, 2, 3))
    for r in range(j):
        pairs[r] = rows[r]
        for a in range(2):
            for d in range(3):
                points[r, a, d] = wit[r, a, d] if has_wit else math.nan
    ps[i + 1] = p0 + j
    return p0 + j
