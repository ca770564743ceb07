"""A filter solve without the QP backend: the kept rows' bounds, their closed form, the check of the other rows.

One call for what most control steps of a robot need (the rows that can bind are one or a few; input
bounds, with ``few``, that the answer satisfies): :func:`~isf_robot.core.robust.row_bounds` of the kept rows,
:func:`~isf_robot.core.projection.project_row` (one row) or
:func:`~isf_robot.core.projection.project_few` (2 to ``FEW_ROWS`` rows; where it has no answer,
:func:`~isf_robot.core.projection.project_active`), and
:func:`~isf_robot.core.screening.others_hold` on the rows screened out. The same functions the
general path calls one by one, composed: compiled as one call (:func:`~isf_robot.core.jit.compiled`)
it saves their separate calls' overhead; as written it runs them in numpy.

:func:`xi_closed_step` is the standard filter's whole step in one call: :func:`~isf_robot.core.robust.xi_pass`
(``Xi_on`` of every row and the rows below their screening thresholds), the rows the filter solves
(:func:`~isf_robot.core.screening.solved_rows`) and :func:`closed_step` on them;
:func:`screened_closed_step` the rows kept by screening (:func:`~isf_robot.core.screening.screened_rows`:
promoted rows always) and :func:`closed_step` on them, given ``Xi_on`` (the filters' other solves);
:func:`promoted_closed_step` the intermittent filter's on step: the rows it promotes
(:func:`~isf_robot.core.handover.promote_rows`) and :func:`screened_closed_step`.
"""

from __future__ import annotations

import math

import numpy as np

from .handover import promote_rows
from .jit import formula
from .projection import FEW_ROWS, REL_TOL, project_few_within, project_row, within_bounds
from .robust import row_bound, row_bounds, xi_pass
from .screening import others_hold, screened_rows, solved_rows

__all__ = ["closed_step", "active_bits", "xi_closed_step", "screened_closed_step", "promoted_closed_step"]


@formula
def closed_step(rows: np.ndarray, lf: np.ndarray, grad_norm: np.ndarray, d_bar: float, alpha_h: np.ndarray,
                promote: np.ndarray, ramp: np.ndarray, b: float, lg: np.ndarray, u_nom: np.ndarray, xi: np.ndarray,
                feas_tol: float, active_tol: float, few: bool, u_min: np.ndarray, u_max: np.ndarray, u: np.ndarray,
                res: np.ndarray) -> tuple:
    """The filter QP on the rows ``rows`` (ascending) by its closed form: ``(code, least slack, others hold)``.

    ``code`` 0: the rows hold at ``u_nom`` (the answer is ``u_nom``); 1: the answer is in ``u``;
    -1: no closed-form answer (the QP decides); -2: not a closed-form problem (more than one row
    without ``few``, or more than ``FEW_ROWS``; input bounds without ``few``). ``res[:n]``: the rows'
    slacks ``A u - lb`` (one row: ``res[0]``). ``others hold``: every row not in ``rows`` keeps
    ``xi + Lg h (u - u_nom) >= active_tol`` (true when every row is kept). ``u_min``, ``u_max``: input
    bounds (length 0: none); the rows' answer is kept only when it satisfies them
    (:func:`~isf_robot.core.projection.within_bounds`: then no bound is active and it is the bounded
    optimum), else -1.
    """
    n = rows.shape[0]
    bounded = u_min.shape[0] > 0 or u_max.shape[0] > 0
    if n == 0 or ((n > 1 or bounded) and not few) or n > FEW_ROWS:
        return -2, 0.0, False
    if n == 1:
        i = rows[0]
        code, low = project_row(lg[i], row_bound(i, lf, grad_norm, d_bar, alpha_h, promote, ramp, b), u_nom,
                                feas_tol, u)
        res[0] = low
        if code >= 0 and bounded and not within_bounds(u_nom if code == 0 else u, u_min, u_max):
            code = -1
    else:  # (project_few, else the certified active-set iteration, kept within the bounds)
        A, lb = lg[rows], row_bounds(rows, lf, grad_norm, d_bar, alpha_h, promote, ramp, b)
        code, low = project_few_within(A, lb, u_nom, REL_TOL, u_min, u_max, u, res[:n])
    if code < 0:
        return code, 0.0, False
    if n == xi.shape[0]:
        return code, low, True
    if code == 0:
        return code, low, others_hold(xi, lg, np.zeros(u_nom.shape[0]), rows, active_tol)
    return code, low, others_hold(xi, lg, u - u_nom, rows, active_tol)


@formula
def active_bits(res: np.ndarray, n: int, active_tol: float) -> int:
    """The rows active at a closed form's answer as bits: bit ``i`` set when ``res[i] <= active_tol`` (``i < n``)."""
    bits = 0
    for i in range(n):
        if res[i] <= active_tol:
            bits |= 1 << i
    return bits


def xi_closed_step(lf: np.ndarray, lg: np.ndarray, u_nom: np.ndarray, grad_norm: np.ndarray, d_bar: float,
                   h: np.ndarray, gain: float, av: np.ndarray, screen: np.ndarray, xi: np.ndarray, rows: np.ndarray,
                   promote: np.ndarray, ramp: np.ndarray, feas_tol: float, active_tol: float, few: bool,
                   u_min: np.ndarray, u_max: np.ndarray, u: np.ndarray, res: np.ndarray) -> tuple:
    """The standard filter's step in one pass: ``Xi_on`` of every row, then the robust rows it keeps by closed form.

    :func:`~isf_robot.core.robust.xi_pass` (arguments as there; at least one row), the rows
    :func:`~isf_robot.core.screening.solved_rows` picks (written to ``rows``) and :func:`closed_step` on
    them with the robust bounds (``promote``, ``ramp``: no entries). Returns ``(sum, min, argmin, kept, n, code, slack,
    others hold, active)``: xi_pass's four, the rows solved, closed_step's three and :func:`active_bits`
    of the answer; ``code`` -3 (nothing solved) when ``sum`` is not finite.
    """
    total, low, arg, kept = xi_pass(lf, lg, u_nom, grad_norm, d_bar, h, gain, av, screen, xi, rows)
    if not math.isfinite(total):
        return total, low, arg, kept, 0, -3, 0.0, False, 0
    n = solved_rows(kept, arg, xi.shape[0], rows)
    code, slack, held = closed_step(rows[:n], lf, grad_norm, d_bar, av, promote, ramp, 0.0, lg, u_nom, xi, feas_tol,
                                    active_tol, few, u_min, u_max, u, res)
    return total, low, arg, kept, n, code, slack, held, active_bits(res, n, active_tol) if code >= 0 else 0


@formula
def screened_closed_step(xi: np.ndarray, screen: np.ndarray, floor: float, promote: np.ndarray, argmin: int,
                         rows: np.ndarray, lf: np.ndarray, grad_norm: np.ndarray, d_bar: float, alpha_h: np.ndarray,
                         ramp: np.ndarray, b: float, lg: np.ndarray, u_nom: np.ndarray, feas_tol: float,
                         active_tol: float, few: bool, u_min: np.ndarray, u_max: np.ndarray, u: np.ndarray,
                         res: np.ndarray) -> tuple:
    """The rows a filter step solves and their closed form, in one pass: ``(n, code, slack, others hold, active)``.

    :func:`~isf_robot.core.screening.screened_rows` (the ``n`` rows, written to ``rows``),
    :func:`closed_step` on them (arguments as there) and :func:`active_bits` of the answer.
    """
    n = screened_rows(xi, screen, floor, promote, argmin, rows)
    code, slack, held = closed_step(rows[:n], lf, grad_norm, d_bar, alpha_h, promote, ramp, b, lg, u_nom, xi, feas_tol,
                                    active_tol, few, u_min, u_max, u, res)
    return n, code, slack, held, active_bits(res, n, active_tol) if code >= 0 else 0


def promoted_closed_step(xi: np.ndarray, c: float, failing: np.ndarray, ramp_on: bool, ids: np.ndarray, W: np.ndarray,
                         inw: np.ndarray, rate: float, promote: np.ndarray, ramp: np.ndarray, promotable: np.ndarray,
                         screen: np.ndarray, argmin: int, rows: np.ndarray, lf: np.ndarray, grad_norm: np.ndarray,
                         d_bar: float, alpha_h: np.ndarray, b: float, lg: np.ndarray, u_nom: np.ndarray,
                         feas_tol: float, active_tol: float, few: bool, u_min: np.ndarray, u_max: np.ndarray,
                         u: np.ndarray, res: np.ndarray) -> tuple:
    """The intermittent filter's on step in one pass: the rows it promotes, then :func:`screened_closed_step`.

    :func:`~isf_robot.core.handover.promote_rows` (its arguments up to ``ramp``, which are its ``mask`` and
    ``weights``: written here), the promotion limited to ``promotable`` (no entries: every row may be promoted),
    then :func:`screened_closed_step` with the off margin ``c`` as the thresholds' floor (the other arguments as
    there). Returns its ``(n, code, slack, others hold, active)``.
    """
    promote_rows(xi, c, failing, ramp_on, ids, W, inw, rate, promote, ramp)
    if promotable.shape[0]:
        for i in range(promote.shape[0]):
            promote[i] = promote[i] and promotable[i]
    return screened_closed_step(xi, screen, c, promote, argmin, rows, lf, grad_norm, d_bar, alpha_h, ramp, b, lg,
                                u_nom, feas_tol, active_tol, few, u_min, u_max, u, res)
