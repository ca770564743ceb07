"""The compiled arc integrator: DOP853 steps with the certified event scan, in one numba call.

The same algorithm as :func:`satellite.orbit.events.integrate` driving scipy's ``DOP853`` (step-size
control, initial step, error estimate and interpolant of scipy's implementation, the scan and
its bisection of :func:`satellite.orbit.events.brackets`, Brent's method on the step's interpolant,
``solve_ivp``'s event conventions), with the right-hand side and the event functions of
:mod:`satellite.orbit.kernel_parts`. Its stage sums are loops, scipy's are BLAS calls, so step
decisions agree with the scipy path to rounding (event times to the integrator's tolerance). Imported only when numba is
installed (:mod:`satellite.orbit.fast_arcs`).

The method is the published one: Dormand and Prince's explicit Runge-Kutta pair of order 8(5,3)
with its dense output of order 7 and the step-size control and starting-step algorithm of Hairer,
Norsett and Wanner, *Solving Ordinary Differential Equations I* (2nd ed., Springer 1993), sections
II.4 and II.10. The coefficients are read from scipy at import (:mod:`satellite.orbit.fast_arcs`), and the
control's constants (safety 0.9, factors 0.2..10, error exponent -1/8) are the ones scipy's
``DOP853`` uses, so that both paths take the same steps; the loops here are written for this project.

:func:`arc` returns a status: 0 reached the end, 1 stopped by a terminal event, -1 the step
size underflowed (at the time returned in ``out_t``), -3 a scan overflowed its fixed buffers (the
caller integrates the arc in Python).
"""

from __future__ import annotations

import math

import numpy as np

from isf_robot.core.jit import watch_compiles
from satellite.compiled import kernel
from satellite.orbit.kernel_parts import brent, g_event, g_rate, interp, rhs

watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)

_MAX_GRID = 256
_STACK = 1024
_MAX_FOUND = 256


@kernel
def _norm(v, scale):  # pragma: no cover (compiled)
    s = 0.0
    for i in range(6):
        q = v[i] / scale[i]
        s += q * q
    return math.sqrt(s) / math.sqrt(6.0)


@kernel
def _stage(K, s, A, h, y, out):  # pragma: no cover (compiled)
    for c in range(6):
        acc = 0.0
        for m in range(s):
            acc += K[m, c] * A[s, m]
        out[c] = y[c] + acc * h


@kernel
def _dense(K, A, C, D, t_old, h, y_old, y_new, f_new, F, tmp, fp, ext, box_o, box_n, coef):  # pragma: no cover
    """The step's interpolant coefficients ``F`` (7, 6) (3 extra evaluations)."""
    for s in range(13, 16):
        _stage(K, s, A, h, y_old, tmp)
        rhs(t_old + C[s] * h, tmp, K[s], fp, ext, box_o, box_n, coef)
    for c in range(6):
        dy = y_new[c] - y_old[c]
        F[0, c] = dy
        F[1, c] = h * K[0, c] - dy
        F[2, c] = 2.0 * dy - h * (f_new[c] + K[0, c])
        for r in range(4):
            acc = 0.0
            for m in range(16):
                acc += D[r, m] * K[m, c]
            F[3 + r, c] = h * acc


@kernel
def _grow(a, n):  # pragma: no cover (compiled)
    shape = (max(2 * a.shape[0], n),) + a.shape[1:]
    b = np.empty(shape)
    b[: a.shape[0]] = a
    return b


@kernel
def _active(ga, gb, d):  # pragma: no cover (compiled)
    up = ga <= 0.0 <= gb
    down = ga >= 0.0 >= gb
    return (up and d > 0) or (down and d < 0) or ((up or down) and d == 0)


@kernel
def _scan(kind, par, dirn, has_rate, first_only, a, b, ga, gb, ya, yb, h, F, min_dt, bp, cp, env, tp,
          br, nbr_max):  # pragma: no cover (compiled)
    """:func:`satellite.orbit.events.brackets` for one event on one step; brackets into ``br``.

    Returns ``(number of brackets, interior evaluations)``, the number -1 on a buffer overflow.
    """
    if _active(ga, gb, dirn):
        br[0, 0], br[0, 1] = a, b
        return 1, 0
    if not has_rate:
        return 0, 0
    if ga * gb > 0.0 and abs(ga) + abs(gb) > g_rate(kind, ya, yb, b - a, bp, cp, tp) * (b - a):
        return 0, 0
    need = g_rate(kind, ya, yb, b - a, bp, cp, tp) * (b - a) / max(abs(ga) + abs(gb), 1e-300)
    n = int(min(_MAX_GRID, max(2, math.ceil(need))))
    ts = np.linspace(a, b, n + 1)
    ys = np.empty((n + 1, 6))
    gs = np.empty(n + 1)
    ys[0], ys[n] = ya, yb
    gs[0], gs[n] = ga, gb
    for k in range(1, n):
        interp(ts[k], a, h, ya, F, ys[k])
        gs[k] = g_event(kind, par, ts[k], ys[k], bp, cp, env, tp)
    evals = n - 1
    st = np.empty((_STACK, 4))
    sy = np.empty((_STACK, 12))
    top = 0
    for k in range(n - 1, -1, -1):
        dtk = ts[k + 1] - ts[k]
        if gs[k] * gs[k + 1] > 0.0 and abs(gs[k]) + abs(gs[k + 1]) > g_rate(kind, ys[k], ys[k + 1], dtk, bp, cp,
                                                                               tp) * dtk:
            continue
        st[top, 0], st[top, 1], st[top, 2], st[top, 3] = ts[k], ts[k + 1], gs[k], gs[k + 1]
        sy[top, :6] = ys[k]
        sy[top, 6:] = ys[k + 1]
        top += 1
    nb = 0
    ym = np.empty(6)
    while top > 0:
        top -= 1
        a0, b0, g0, g1 = st[top, 0], st[top, 1], st[top, 2], st[top, 3]
        if _active(g0, g1, dirn):
            if nb >= nbr_max:
                return -1, evals
            br[nb, 0], br[nb, 1] = a0, b0
            nb += 1
            if first_only:
                break
            continue
        y0 = sy[top, :6].copy()
        y1 = sy[top, 6:].copy()
        if b0 - a0 <= min_dt or (g0 * g1 > 0.0 and abs(g0) + abs(g1) > g_rate(kind, y0, y1, b0 - a0, bp, cp, tp)
                                 * (b0 - a0)):
            continue
        if top + 2 > _STACK:
            return -1, evals
        m = 0.5 * (a0 + b0)
        interp(m, a, h, ya, F, ym)
        gm = g_event(kind, par, m, ym, bp, cp, env, tp)
        evals += 1
        st[top, 0], st[top, 1], st[top, 2], st[top, 3] = m, b0, gm, g1
        sy[top, :6] = ym
        sy[top, 6:] = y1
        top += 1
        st[top, 0], st[top, 1], st[top, 2], st[top, 3] = a0, m, g0, gm
        sy[top, :6] = y0
        sy[top, 6:] = ym
        top += 1
    return nb, evals


@kernel
def arc(t0, t1, y0, rtol, atol, max_step, min_dt, keep_dense, kinds, pars, dirs, terms, rated,
        fp, ext, box_o, box_n, coef, bp, cp, env, tp, A, B, C, E3, E5, D):  # pragma: no cover (compiled)
    """Integrate one arc (see the module docstring).

    Returns ``(status, out_t, ts, ys, hs, Fs, ev_t, ev_i, ev_y, nfev, scan_points)``: step points
    ``ts`` (n,) and states ``ys`` (n, 6); per segment the full step's length ``hs`` and
    interpolant ``Fs`` (n - 1, 7, 6) (empty unless ``keep_dense``); the located events in time
    order (times, event indices, states).
    """
    n_ev = len(kinds)
    cap = 64
    ts = np.empty(cap)
    ys = np.empty((cap, 6))
    hs = np.empty(cap)
    Fs = np.empty((cap if keep_dense else 1, 7, 6))
    ev_t = np.empty(16)
    ev_i = np.empty(16)
    ev_y = np.empty((16, 6))
    n_found = 0
    K = np.empty((16, 6))
    F = np.empty((7, 6))
    y = y0.copy()
    f = np.empty(6)
    tmp = np.empty(6)
    y_new = np.empty(6)
    f_new = np.empty(6)
    scale = np.empty(6)
    err = np.empty(6)
    nfev = 0
    scan = 0
    empty = (np.empty(0), np.empty(0), np.empty((0, 6)), np.empty(0), np.empty((0, 7, 6)))
    rhs(t0, y, f, fp, ext, box_o, box_n, coef)
    nfev += 1
    # initial step (scipy's select_initial_step, error estimator order 7)
    interval = abs(t1 - t0)
    for c in range(6):
        scale[c] = atol + abs(y[c]) * rtol
    d0 = _norm(y, scale)
    d1 = _norm(f, scale)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, interval)
    for c in range(6):
        tmp[c] = y[c] + h0 * f[c]
    rhs(t0 + h0, tmp, f_new, fp, ext, box_o, box_n, coef)
    nfev += 1
    for c in range(6):
        err[c] = f_new[c] - f[c]
    d2 = _norm(err, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    h_abs = min(100.0 * h0, h1, interval, max_step)
    g = np.empty(n_ev)
    g_new = np.empty(n_ev)
    for e in range(n_ev):
        g[e] = g_event(kinds[e], pars[e], t0, y, bp, cp, env, tp)
    ts[0] = t0
    ys[0] = y
    n = 1
    t = t0
    status = -9
    br = np.empty((_MAX_FOUND, 2))
    found_t = np.empty(_MAX_FOUND)
    found_i = np.empty(_MAX_FOUND, dtype=np.int64)
    while status == -9:
        # -- one DOP853 step (scipy's RungeKutta._step_impl) --------------------------------
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h_abs > max_step:
            h_abs = max_step
        elif h_abs < min_step:
            h_abs = min_step
        accepted = False
        rejected = False
        while not accepted:
            if h_abs < min_step:
                return -1, t, empty[0], empty[2], empty[0], empty[4], empty[0], empty[1], empty[2], nfev, scan
            t_new = t + h_abs
            if t_new - t1 > 0:
                t_new = t1
            h = t_new - t
            h_abs = abs(h)
            K[0] = f
            for s in range(1, 12):
                _stage(K, s, A, h, y, tmp)
                rhs(t + C[s] * h, tmp, K[s], fp, ext, box_o, box_n, coef)
            nfev += 11
            for c in range(6):
                acc = 0.0
                for m in range(12):
                    acc += K[m, c] * B[m]
                y_new[c] = y[c] + h * acc
            rhs(t + h, y_new, f_new, fp, ext, box_o, box_n, coef)
            nfev += 1
            K[12] = f_new
            e5 = 0.0
            e3 = 0.0
            for c in range(6):
                sc = atol + max(abs(y[c]), abs(y_new[c])) * rtol
                a5 = 0.0
                a3 = 0.0
                for m in range(13):
                    a5 += K[m, c] * E5[m]
                    a3 += K[m, c] * E3[m]
                a5 /= sc
                a3 /= sc
                e5 += a5 * a5
                e3 += a3 * a3
            e5 = math.sqrt(e5) ** 2  # scipy squares np.linalg.norm
            e3 = math.sqrt(e3) ** 2
            if e5 == 0.0 and e3 == 0.0:
                error_norm = 0.0
            else:
                error_norm = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * 6.0)
            if error_norm < 1:
                if error_norm == 0:
                    factor = 10.0
                else:
                    factor = min(10.0, 0.9 * error_norm ** (-1.0 / 8.0))
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                accepted = True
            else:
                h_abs *= max(0.2, 0.9 * error_norm ** (-1.0 / 8.0))
                rejected = True
        t_old = t
        finished = t_new - t1 >= 0
        have_F = False
        if keep_dense:
            _dense(K, A, C, D, t_old, h, y, y_new, f_new, F, tmp, fp, ext, box_o, box_n, coef)
            nfev += 3
            have_F = True
        # -- the scan (satellite.orbit.events.integrate) ------------------------------------------
        n_f = 0
        for e in range(n_ev):
            g_new[e] = g_event(kinds[e], pars[e], t_new, y_new, bp, cp, env, tp)
        if t_new > t_old:
            for e in range(n_ev):
                needs = _active(g[e], g_new[e], dirs[e]) or (
                    rated[e] and not (g[e] * g_new[e] > 0.0 and abs(g[e]) + abs(g_new[e])
                                      > g_rate(kinds[e], y, y_new, t_new - t_old, bp, cp, tp) * (t_new - t_old)))
                if not needs:
                    continue
                if not have_F:
                    _dense(K, A, C, D, t_old, h, y, y_new, f_new, F, tmp, fp, ext, box_o, box_n, coef)
                    nfev += 3
                    have_F = True
                nb, ev = _scan(kinds[e], pars[e], dirs[e], rated[e], terms[e], t_old, t_new, g[e], g_new[e], y,
                               y_new, h, F, min_dt, bp, cp, env, tp, br, _MAX_FOUND - n_f)
                scan += ev
                if nb < 0:
                    return -3, t, empty[0], empty[2], empty[0], empty[4], empty[0], empty[1], empty[2], nfev, scan
                for q in range(nb):
                    root = brent(kinds[e], pars[e], br[q, 0], br[q, 1], t_old, h, y, F, bp, cp, env, tp)
                    # insert in (time, index) order
                    p = n_f
                    while p > 0 and (found_t[p - 1] > root or (found_t[p - 1] == root and found_i[p - 1] > e)):
                        found_t[p] = found_t[p - 1]
                        found_i[p] = found_i[p - 1]
                        p -= 1
                    found_t[p] = root
                    found_i[p] = e
                    n_f += 1
        stop = -1
        for q in range(n_f):
            if terms[found_i[q]]:
                stop = q
                break
        if stop >= 0:
            n_f = stop + 1
        if n_found + n_f > len(ev_t):
            ev_t = _grow(ev_t, n_found + n_f)
            ev_i = _grow(ev_i, n_found + n_f)
            ev_y = _grow(ev_y, n_found + n_f)
        for q in range(n_f):
            ev_t[n_found] = found_t[q]
            ev_i[n_found] = found_i[q]
            interp(found_t[q], t_old, h, y, F, ev_y[n_found])
            n_found += 1
        t_end = t_new
        if stop >= 0:
            status = 1
            t_end = found_t[stop]
            interp(t_end, t_old, h, y, F, tmp)
        elif finished:
            status = 0
        for e in range(n_ev):
            g[e] = g_new[e]
        if stop >= 0 and n > 1 and ts[n - 1] == t_end:
            break  # a terminal event at the step's start: no empty segment (as solve_ivp)
        if n >= ts.shape[0]:
            ts = _grow(ts, n + 1)
            ys = _grow(ys, n + 1)
            hs = _grow(hs, n + 1)
            if keep_dense:
                Fs = _grow(Fs, n + 1)
        if keep_dense:
            Fs[n - 1] = F
        hs[n - 1] = h
        ts[n] = t_end
        ys[n] = tmp if stop >= 0 else y_new
        n += 1
        # advance the solver's own state (the full step, as scipy does)
        t = t_new
        y[:] = y_new
        f[:] = f_new
    return (status, t, ts[:n].copy(), ys[:n].copy(), hs[: n - 1].copy(),
            Fs[: n - 1].copy() if keep_dense else empty[4], ev_t[:n_found].copy(), ev_i[:n_found].copy(),
            ev_y[:n_found].copy(), nfev, scan)
