"""The robust barrier condition and its promoted form, each formula once.

The paper's eqs. barr_cond, filter_inc, trigger:filter_on and greedy_cond. For a barrier ``h`` with
Lie data ``Lf h`` (drift, ``dh/dt`` included), ``Lg h`` and ``|dh/dx|``:

* the robust slack under a command ``u`` is ``Xi = Lf h + Lg h u - |dh/dx| d_bar + alpha(h)``
  (:func:`robust_slack`): the on trigger's value ``Xi_on`` at ``u = u_nom``, the greedy impulsive
  trigger ``Xi`` with ``Lg h u = 0``;
* a filter row asks ``Lf h + Lg h u - |dh/dx| d_bar >= level``, i.e. ``Lg h u >= lb`` with
  ``lb = level - Lf h + |dh/dx| d_bar`` (:func:`row_lower`); the robust condition has
  ``level = -alpha(h)``, a promoted row ``level = b`` (the safety-promoting filter), and during the
  hand-over a promoted row ramps from the robust level to ``b`` (:func:`promotion_level`).

The formulas are plain functions of floats that also take numpy arrays (elementwise); marked with
:func:`~isf_robot.core.jit.formula`, the compiled passes below compile these same functions into
themselves. The passes (:func:`xi_pass`, :func:`row_bounds`) are written in numpy's array style, so
each runs as it is in Python and, through :func:`~isf_robot.core.jit.compiled`, as one compiled
call; the two agree to rounding (the order of the sums in ``Lg h u`` may differ: about 1e-15
relative). :func:`predict_pass` is written as loops over each point's rows (what its compiled call,
a compiled rollout's, runs fastest; as written it gives the same numbers, slowly); marked a formula too,
the arm's compiled rollout compiles it into its own call (``isf_robot.arm._rollout_jit.closed_loop_predict``).
"""

from __future__ import annotations

import math

import numpy as np

from .jit import formula

__all__ = ["robust_slack", "row_lower", "promotion_level", "xi_pass", "row_bound", "row_bounds", "predict_pass"]


@formula
def robust_slack(lf, lg_u, grad_norm, d_bar, alpha_h):  # noqa: ANN001, ANN201 (floats or arrays)
    """``Xi = Lf h + Lg h u - |dh/dx| d_bar + alpha(h)``: the robust condition's slack under ``u`` [h/s].

    ``lg_u``: ``Lg h u`` (0 for an impulsive flow: the greedy trigger). Floats or arrays (elementwise).
    """
    return ((lf + lg_u) - grad_norm * d_bar) + alpha_h


@formula
def row_lower(level, lf, grad_norm, d_bar):  # noqa: ANN001, ANN201
    """The bound ``lb`` of the filter row ``Lg h u >= lb`` that asks ``Lf h + Lg h u - |dh/dx| d_bar >= level``.

    ``level = -alpha(h)``: the robust condition (then ``Xi = Lg h u - lb``); ``level = b``: promoted.
    """
    return (level - lf) + grad_norm * d_bar


@formula
def promotion_level(alpha_h: float, b: float, w: float) -> float:
    """A promoted row's level: ``b`` (eq. filter_inc) once fully promoted (``w >= 1``).

    While the row's hand-over weight ``w`` ramps up from 0, ``max(-alpha(h), w b + (1 - w)(-alpha(h)))``:
    from the robust condition's level toward ``b``, never below the robust level. (Inside the unsafe
    set, ``h < 0``, ``-alpha(h)`` can exceed ``b``; a fully promoted row still asks ``b``, as the paper's
    promoting filter does: demanding the robust recovery rate there made the planar_moving scene's
    infeasible steps 3.5x as many.)
    """
    if w >= 1.0:
        return b
    r = -alpha_h
    x = w * b + (1.0 - w) * r
    return x if x > r else r


@formula
def xi_pass(lf: np.ndarray, lg: np.ndarray, u: np.ndarray, grad_norm: np.ndarray, d_bar: float, h: np.ndarray,
            gain: float, av: np.ndarray, screen: np.ndarray, xi: np.ndarray, rows: np.ndarray) -> tuple:
    """Every row's ``Xi`` under ``u`` (written to ``xi``) and what a filter step reads of it, in one pass.

    ``alpha(h)``: ``av``; with ``gain > 0`` (a linear class-K function) ``gain h``, written to ``av``
    first. ``screen``: no thresholds (no entries), one for every row, or one per row. Returns ``(sum,
    min, argmin, kept)``: with thresholds, the ``kept`` rows with ``xi`` below theirs are written to
    ``rows`` (ascending); -1 without. At least one row.
    """
    if gain > 0.0:
        av[:] = gain * h
    xi[:] = robust_slack(lf, lg @ u, grad_norm, d_bar, av)
    arg = np.argmin(xi)
    kept = -1
    if screen.shape[0]:
        below = np.flatnonzero(xi < screen)
        kept = below.shape[0]
        rows[:kept] = below
    return np.sum(xi), xi[arg], arg, kept


@formula
def row_bound(i: int, lf: np.ndarray, grad_norm: np.ndarray, d_bar: float, alpha_h: np.ndarray,
              promote: np.ndarray, ramp: np.ndarray, b: float) -> float:
    """The bound ``lb`` of filter row ``i``: robust, or promoted where ``promote[i]`` (ramped by ``ramp[i]``).

    ``promote``/``ramp``: no entries (none promoted / every weight 1) or one per row of the data.
    """
    level = -alpha_h[i]
    if promote.shape[0] and promote[i]:
        level = promotion_level(alpha_h[i], b, ramp[i] if ramp.shape[0] else 1.0)
    return row_lower(level, lf[i], grad_norm[i], d_bar)


@formula
def row_bounds(rows: np.ndarray, lf: np.ndarray, grad_norm: np.ndarray, d_bar: float, alpha_h: np.ndarray,
               promote: np.ndarray, ramp: np.ndarray, b: float) -> np.ndarray:
    """:func:`row_bound` of each row of ``rows``."""
    lb = np.empty(rows.shape[0])
    for j in range(rows.shape[0]):
        lb[j] = row_bound(rows[j], lf, grad_norm, d_bar, alpha_h, promote, ramp, b)
    return lb


@formula
def predict_pass(lf: np.ndarray, lg: np.ndarray, u: np.ndarray, grad_norm: np.ndarray, d_bar: float,
                 h: np.ndarray, gain: float, alpha_h: np.ndarray, k: np.ndarray, xi: np.ndarray, fails: np.ndarray,
                 nfail: np.ndarray, keys: np.ndarray, seen: np.ndarray, out: np.ndarray) -> tuple:
    """``Xi_on`` at every predicted point, stacked: point ``j``'s ``k[j]`` rows in row ``j`` of the (n, K) arrays.

    ``lg`` (n, K, m), ``u`` (n, m); ``alpha(h)``: ``alpha_h``, or ``gain h`` with ``gain > 0``. Writes
    ``xi``, and each point's rows with ``Xi_on <= 0`` to ``fails[j, :nfail[j]]`` (ascending). With
    ``keys`` (n, K) (no rows: none), the failing rows' keys, each once, go to ``out`` (``seen``: False,
    one entry per key). Returns ``(bad, xi_min, keys found)``: ``bad`` the first point whose values
    are not finite (-1: none; the pass stops there), ``xi_min`` the least value before it; keys found
    -1 when a key lies outside ``seen``.
    """
    n, m = lg.shape[0], lg.shape[2]
    low = math.inf
    for j in range(n):  # (loops over the rows each point has: no (n, K) temporaries)
        kj = k[j]
        nfail[j] = 0
        if kj == 0:
            continue
        total, lo = 0.0, math.inf
        for i in range(kj):
            lg_u = 0.0
            for q in range(m):  # (Lg h u summed in the order of q)
                lg_u += lg[j, i, q] * u[j, q]
            x = robust_slack(lf[j, i], lg_u, grad_norm[j, i], d_bar, gain * h[j, i] if gain > 0.0 else alpha_h[j, i])
            xi[j, i] = x
            total += x
            lo = min(lo, x)
        if not math.isfinite(total):
            return j, low, 0
        if lo < low:
            low = lo
        if lo <= 0.0:
            nb = 0
            for i in range(kj):
                if xi[j, i] <= 0.0:
                    fails[j, nb] = i
                    nb += 1
            nfail[j] = nb
    found = 0
    if keys.shape[0]:
        for j in range(n):
            for i in fails[j, :nfail[j]]:
                key = keys[j, i]
                if key < 0 or key >= seen.shape[0]:
                    return -1, low, -1
                if not seen[key]:
                    seen[key] = True
                    out[found] = key
                    found += 1
    return -1, low, found
