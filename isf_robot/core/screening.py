"""Row screening: the filter QP keeps the rows that can bind, and checks the others at its answer.

A row whose robust slack under ``u_nom`` (``Xi_on,i``) is at least its threshold ``screen_i`` is left
out of the QP; at the QP's answer ``u`` every row left out must keep slack ``Xi_on,i + Lg h_i (u -
u_nom) >= active_tol``, or the QP is solved again with every row. So screening saves work on a
robot's many far-away rows and never changes a command. The intermittent filter raises each
threshold to its off margin ``c`` and keeps every promoted row, so a screened row is never promoted.

Plain functions over numpy arrays, compiled as they are by :func:`~isf_robot.core.jit.compiled`.
"""

from __future__ import annotations

import numpy as np

from .jit import formula

__all__ = ["kept_rows", "solved_rows", "screened_rows", "others_hold"]


@formula
def kept_rows(xi: np.ndarray, screen: np.ndarray, floor: float, promote: np.ndarray, rows: np.ndarray) -> int:
    """The rows kept: ``xi < max(screen, floor)`` (``floor > 0``; else ``xi < screen``), or promoted.

    ``screen``: one threshold for every row, or one per row; ``promote``: no entries (none) or one per
    row. Writes the kept rows, ascending, to ``rows`` and returns their number.
    """
    if floor > 0.0:
        keep = xi < np.maximum(screen, floor)
    else:
        keep = xi < screen
    if promote.shape[0]:
        keep = keep | promote
    got = np.flatnonzero(keep)
    rows[:got.shape[0]] = got
    return got.shape[0]


@formula
def solved_rows(kept: int, argmin: int, k: int, rows: np.ndarray) -> int:
    """The rows a filter step solves, written to ``rows``; returns their number.

    ``rows[:kept]``: the rows kept by screening. None kept (``kept == 0``): the row of least slack
    ``argmin`` alone; no screening (``kept < 0``) or every row kept: every row, ascending.
    """
    if kept == 0:
        rows[0] = argmin
        return 1
    if 0 < kept < k:
        return kept
    for i in range(k):
        rows[i] = i
    return k


@formula
def screened_rows(xi: np.ndarray, screen: np.ndarray, floor: float, promote: np.ndarray, argmin: int,
                  rows: np.ndarray) -> int:
    """:func:`solved_rows` of :func:`kept_rows` (``screen`` without entries: no screening, every row).

    ``argmin``: the row of least ``xi`` (-1: found here when needed).
    """
    k = xi.shape[0]
    kept = kept_rows(xi, screen, floor, promote, rows) if screen.shape[0] else -1
    if kept == 0 and argmin < 0:
        argmin = int(np.argmin(xi))
    return solved_rows(kept, argmin, k, rows)


@formula
def others_hold(xi: np.ndarray, lg: np.ndarray, du: np.ndarray, rows: np.ndarray, active_tol: float) -> bool:
    """Whether every row not in ``rows`` keeps robust slack ``xi + Lg h du >= active_tol`` (NaN: no)."""
    slack = xi + lg @ du
    slack[rows] = np.inf
    return np.min(slack) >= active_tol
