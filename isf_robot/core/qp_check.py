"""The check of a filter QP's answer: how far a command lies outside ``A u >= lb, u_min <= u <= u_max``.

:func:`answer_violation` is the one source of both figures :class:`~isf_robot.core.qp_solver.QPSolver`
judges an answer by (and of :meth:`~isf_robot.core.qp.FilterQP.max_violation`). A plain function written
as loops over the rows (what the compiled code runs fastest); :func:`~isf_robot.core.jit.compiled` compiles
this same function (one call per solve instead of a dozen numpy temporaries, which cost as much as the
solve itself on the torque level's 50-row problems). Compiled and as written agree to 1e-12 relative
(``tests/core/test_compiled_paths.py``; the row norms may be summed in another order than numpy's).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["answer_violation", "NO_BOUND"]

NO_BOUND = np.empty(0)
"""An absent input bound, as :func:`answer_violation` takes it (length 0)."""


def answer_violation(A: np.ndarray, res: np.ndarray, u: np.ndarray, u_nom: np.ndarray, u_min: np.ndarray,
                     u_max: np.ndarray) -> tuple:
    """``(violation, distance)`` of the command ``u``, whose row slacks are ``res = A u - lb``.

    * ``violation``: the largest constraint violation, rows and bounds,
      ``max(0, max_i -res_i, max_j (u_min - u)_j, max_j (u - u_max)_j)``, in the constraints' own units.
    * ``distance``: how far ``u`` lies outside the feasible set relative to the size of the problem:
      each violated row's distance to its half-space ``-res_i / |a_i|`` (a zero row: its absolute
      violation), the bounds' violations as they are, the largest divided by ``max(1, |u|_inf, |u_nom|_inf)``
      (a solver's rounding is relative to the iterates, so rows of 1e9 or 1e-9 are judged alike); 0 when
      ``u`` is feasible.

    ``u_min``, ``u_max``: the bounds, or :data:`NO_BOUND` (length 0) for none. A command whose sum is
    not finite (a NaN or inf entry, or so large that it overflows), or a slack that is NaN, is never
    judged feasible: ``(nan, inf)``.
    """
    total = 0.0
    for j in range(u.shape[0]):
        total += float(u[j])  # (Python floats as written: an overflow is inf, without a numpy warning)
    if not math.isfinite(total):
        return math.nan, math.inf
    viol = 0.0
    worst = 0.0
    m = A.shape[1]
    for i in range(res.shape[0]):
        r = res[i]
        if r < 0.0:
            if -r > viol:
                viol = -r
            nn = 0.0
            for j in range(m):
                nn += A[i, j] * A[i, j]
            d = -r / math.sqrt(nn) if nn > 0.0 else -r
            if d > worst:
                worst = d
        elif not r >= 0.0:  # NaN
            return math.nan, math.inf
    for j in range(u_min.shape[0]):
        e = u_min[j] - u[j]
        if e > viol:
            viol = e
        if e > worst:
            worst = e
    for j in range(u_max.shape[0]):
        e = u[j] - u_max[j]
        if e > viol:
            viol = e
        if e > worst:
            worst = e
    if worst == 0.0:
        return viol, 0.0
    size = 1.0
    for j in range(u.shape[0]):
        if abs(u[j]) > size:
            size = abs(u[j])
    for j in range(u_nom.shape[0]):
        if abs(u_nom[j]) > size:
            size = abs(u_nom[j])
    return viol, worst / size
