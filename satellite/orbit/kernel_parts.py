"""Compiled pieces of the fast arc integrator (imported only when numba is installed).

The truth right-hand side for a tabulated field (:class:`satellite.gravity.table.GravityTable`
with its fine boxes, :mod:`satellite.gravity.fine`) in a spinning body frame, the event
functions and their rate bounds (the formulas of :class:`satellite.control.triggers.BandTriggers`,
:class:`satellite.control.contact.ContactWatch` and the maneuver trigger of :mod:`satellite.control.policies`,
term for term), DOP853's interpolant at one point, and Brent's method on an event along it.
:mod:`satellite.orbit.arc_kernel` integrates arcs with them; :mod:`satellite.orbit.fast_arcs` packs the
arguments. Module-level functions, so numba's cache (``__pycache__``) serves later processes.

Packed parameters (float arrays, filled by :mod:`satellite.orbit.fast_arcs`):

* ``fp`` (field): body phase, spin rate, disturbance scale, GM, r_lo, 1/dr, 1/dang, r_in,
  r_out, n_r, r_hi, number of boxes; ``ext`` the table's padded coefficients; per box ``box_o``
  its corner and 1/step, ``box_n`` its node counts, ``coef[b]`` its coefficients (a typed list of flat C-order arrays).
* ``bp`` (band): r_centre, h_max, d_bar, accel bound A, r_inner, r_outer, half width,
  alpha gain, alpha slope bound.
* ``cp`` (contact): body phase, spin rate, cell size, n_lat, n_lon, max radius, min radius,
  slope, accel bound.
* ``tp`` (maneuver): |tau'| bound, |tau''| bound, h_max of the fit, then the coefficients of
  ``d tau / d s`` (lowest degree first).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.extending import register_jitable

from isf_robot.core.jit import watch_compiles
from satellite.gravity.table import bspline3, dbspline3, shell_continued

watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)

# the table's continuation beyond its radii: the plain functions of satellite.gravity.table, compiled here
# (numba's cache keys rhs on this file only: after editing them, clear satellite/__pycache__/*.nb*)
for _plain in (bspline3, dbspline3, shell_continued):
    register_jitable(_plain)

# event kinds
XI, H, RDOT, CONTACT, XITAU = 0, 1, 2, 3, 4

_RG = 3  # radial ghost coefficient layers of the table (gravity_table._RG)


@njit(cache=True, nogil=True, inline="always")
def _w(t):  # pragma: no cover (compiled)
    t2 = t * t
    t3 = t2 * t
    u = 1.0 - t
    return u * u * u / 6.0, (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0, (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0, t3 / 6.0


@njit(cache=True, nogil=True)
def rhs(t, y, out, fp, ext, box_o, box_n, coef):  # pragma: no cover (compiled)
    """Truth flow at ``(t, y)`` into ``out``.

    Within the table's radii the table (:func:`_table`); outside them the table's radial continuation
    (:func:`satellite.gravity.table.shell_continued`, the same function as the Python path's), the fine
    boxes and Kepler.
    """
    px, py, pz = y[0], y[1], y[2]
    th = fp[0] + fp[1] * t
    c = math.cos(th)
    s = math.sin(th)
    x = c * px + s * py
    yy = c * py - s * px
    z = pz
    r2 = x * x + yy * yy + z * z
    r = math.sqrt(r2)
    if fp[7] <= r <= fp[8]:
        ax, ay, az = _shell(x, yy, z, r, fp, ext)
    else:
        ax, ay, az = shell_continued(x, yy, z, ext, fp[4], fp[10], fp[5], fp[6], int(fp[9]))
    fx, fy, fz = _boxes(x, yy, z, fp, box_o, box_n, coef)
    ax += fx
    ay += fy
    az += fz
    kep = -fp[3] / (r2 * r)
    bx = ax + kep * x
    by = ay + kep * yy
    bz = az + kep * z
    kd = fp[2]
    if kd != 1.0:
        pr2 = px * px + py * py + pz * pz
        g = -fp[3] / (pr2 * math.sqrt(pr2))
        bx, by, bz = g * x + kd * (bx - g * x), g * yy + kd * (by - g * yy), g * pz + kd * (bz - g * pz)
    out[0] = y[3]
    out[1] = y[4]
    out[2] = y[5]
    out[3] = c * bx - s * by
    out[4] = s * bx + c * by
    out[5] = bz


@njit(cache=True, nogil=True)
def _shell(x, yy, z, r, fp, ext):  # pragma: no cover (compiled)
    """The table's shell B-spline (the non-Kepler part before the fine boxes) at a body-frame point within its radii."""
    u = (r - fp[4]) * fp[5]
    k = min(int(u), int(fp[9]) - 3)
    v = (math.asin(z / r) + 0.5 * math.pi) * fp[6] - 0.5
    i = int(math.floor(v))
    w = (math.atan2(yy, x) + math.pi) * fp[6] - 0.5
    j = int(math.floor(w))
    wa = _w(u - k)
    wb = _w(v - i)
    wc = _w(w - j)
    ax = 0.0
    ay = 0.0
    az = 0.0
    for cc in range(4):
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for aa in range(4):
            for bb in range(4):
                wab = wa[aa] * wb[bb]
                e = ext[k + _RG - 1 + aa, i + 1 + bb, j + 1 + cc]
                sx += wab * e[0]
                sy += wab * e[1]
                sz += wab * e[2]
        ax += wc[cc] * sx
        ay += wc[cc] * sy
        az += wc[cc] * sz
    return ax, ay, az


@njit(cache=True, nogil=True)
def _boxes(x, yy, z, fp, box_o, box_n, coef):  # pragma: no cover (compiled)
    """The fine boxes' correction (the sum over the boxes holding the point; zeros outside them)."""
    fx = 0.0
    fy = 0.0
    fz = 0.0
    for b in range(int(fp[11])):
        nx, ny, nz = box_n[b, 0], box_n[b, 1], box_n[b, 2]
        cb = coef[b]
        inv = box_o[b, 3]
        bu = (x - box_o[b, 0]) * inv
        bv = (yy - box_o[b, 1]) * inv
        bw = (z - box_o[b, 2]) * inv
        if not (1.0 <= bu < nx - 2 and 1.0 <= bv < ny - 2 and 1.0 <= bw < nz - 2):
            continue
        bi, bj, bk = int(bu), int(bv), int(bw)
        qa = _w(bu - bi)
        qb = _w(bv - bj)
        qc = _w(bw - bk)
        gx = 0.0
        gy = 0.0
        gz = 0.0
        for cc in range(4):
            sx = 0.0
            sy = 0.0
            sz = 0.0
            for aa in range(4):
                for bb in range(4):
                    wab = qa[aa] * qb[bb]
                    n = 3 * (((bi - 1 + aa) * ny + (bj - 1 + bb)) * nz + (bk - 1 + cc))
                    sx += wab * cb[n]
                    sy += wab * cb[n + 1]
                    sz += wab * cb[n + 2]
            gx += qc[cc] * sx
            gy += qc[cc] * sy
            gz += qc[cc] * sz
        fx += gx
        fy += gy
        fz += gz
    return fx, fy, fz


@njit(cache=True, nogil=True)
def interp(tq, t_old, h, y_old, F, out):  # pragma: no cover (compiled)
    """DOP853's interpolant (scipy's ``Dop853DenseOutput``) of one step at ``tq`` into ``out``."""
    x = (tq - t_old) / h
    for c in range(6):
        acc = 0.0
        for i in range(7):
            acc += F[6 - i, c]
            acc *= x if i % 2 == 0 else 1.0 - x
        out[c] = acc + y_old[c]


@njit(cache=True, nogil=True)
def _envelope(cp, env, bx, by, bz):  # pragma: no cover (compiled)
    r = math.sqrt(bx * bx + by * by + bz * bz)
    q = bz / r if r > 0 else bz
    lat = math.asin(min(max(q, -1.0), 1.0))
    lon = math.atan2(by, bx)
    d = cp[2]
    n_lat = int(cp[3])
    n_lon = int(cp[4])
    xx = min(max((lat + 0.5 * math.pi) / d - 0.5, 0.0), n_lat - 1.0)
    yq = (lon + math.pi) / d - 0.5
    yq = yq - n_lon * math.floor(yq / n_lon)
    i = min(int(math.floor(xx)), n_lat - 2) if n_lat > 1 else 0
    fl = math.floor(yq)
    j = int(fl) % n_lon
    fx = xx - i
    fy = yq - fl
    j1 = (j + 1) % n_lon
    i1 = min(i + 1, n_lat - 1)
    return (1 - fx) * ((1 - fy) * env[i, j] + fy * env[i, j1]) + fx * ((1 - fy) * env[i1, j] + fy * env[i1, j1])


@njit(cache=True, nogil=True)
def g_event(kind, par, t, y, bp, cp, env, tp):  # pragma: no cover (compiled)
    """The event function of ``kind`` at ``(t, y)``."""
    px, py, pz, vx, vy, vz = y[0], y[1], y[2], y[3], y[4], y[5]
    if kind == RDOT:
        return px * vx + py * vy + pz * vz
    r = math.sqrt(px * px + py * py + pz * pz)
    if kind == CONTACT:
        if r > cp[5]:
            return r - cp[5]
        th = cp[0] + cp[1] * t
        c, s = math.cos(th), math.sin(th)
        return r - _envelope(cp, env, c * px + s * py, c * py - s * px, pz)
    dr = r - bp[0]
    h = bp[1] - dr * dr
    if kind == H:
        return h - par
    lfh = -2.0 * dr * (px * vx + py * vy + pz * vz) / r
    if kind == XI:
        return lfh - 2.0 * abs(r - bp[0]) * bp[2] + bp[7] * h
    # XITAU: 0.5 (1 + tau'(h) LF h), tau' from the fit's polynomial in s = h / h_max, clamped
    sq = min(max(h / tp[2], 0.0), 1.0)
    acc = 0.0
    for m in range(len(tp) - 1, 2, -1):
        acc = acc * sq + tp[m]
    return 0.5 * (1.0 + (acc / tp[2]) * lfh)


@njit(cache=True, nogil=True)
def rate(kind, ya, yb, dt, bp, cp):  # pragma: no cover (compiled)
    """Bound on ``|dg/dt|`` over an interval of length ``dt`` with end states ``ya``, ``yb``."""
    ra = math.sqrt(ya[0] * ya[0] + ya[1] * ya[1] + ya[2] * ya[2])
    rb = math.sqrt(yb[0] * yb[0] + yb[1] * yb[1] + yb[2] * yb[2])
    va = math.sqrt(ya[3] * ya[3] + ya[4] * ya[4] + ya[5] * ya[5])
    vb = math.sqrt(yb[3] * yb[3] + yb[4] * yb[4] + yb[5] * yb[5])
    if kind == CONTACT:
        v = 0.5 * (va + vb)
        v = v + 0.5 * cp[8] * dt
        r_low = min(ra, rb) - 0.5 * v * dt
        if r_low > cp[5]:
            return v + 0.0
        return v + cp[7] * (v / max(r_low, cp[6]) + abs(cp[1]))
    a = bp[3]
    v = 0.5 * (va + vb) + 0.5 * a * dt
    b = v * v / bp[4] + a
    rda = abs(ya[0] * ya[3] + ya[1] * ya[4] + ya[2] * ya[5]) / ra
    rdb = abs(yb[0] * yb[3] + yb[1] * yb[4] + yb[2] * yb[5]) / rb
    p = min(v, 0.5 * (rda + rdb) + 0.5 * b * dt)
    d = min(bp[6], 0.5 * (abs(ra - bp[0]) + abs(rb - bp[0])) + 0.5 * p * dt)
    if kind == H:
        return 2.0 * d * p
    if kind == RDOT:
        return p * p + bp[5] * b
    lfh_rate = 2.0 * p * p + 2.0 * d * b
    if kind == XI:
        return lfh_rate + bp[8] * 2.0 * d * p + 2.0 * bp[2] * p
    return 0.0  # XITAU: see rate_tau


@njit(cache=True, nogil=True)
def rate_tau(ya, yb, dt, bp, tp):  # pragma: no cover (compiled)
    """Rate bound of the maneuver trigger (policies._xi_tau_rate)."""
    ra = math.sqrt(ya[0] * ya[0] + ya[1] * ya[1] + ya[2] * ya[2])
    rb = math.sqrt(yb[0] * yb[0] + yb[1] * yb[1] + yb[2] * yb[2])
    va = math.sqrt(ya[3] * ya[3] + ya[4] * ya[4] + ya[5] * ya[5])
    vb = math.sqrt(yb[3] * yb[3] + yb[4] * yb[4] + yb[5] * yb[5])
    a = bp[3]
    v = 0.5 * (va + vb) + 0.5 * a * dt
    b = v * v / bp[4] + a
    rda = abs(ya[0] * ya[3] + ya[1] * ya[4] + ya[2] * ya[5]) / ra
    rdb = abs(yb[0] * yb[3] + yb[1] * yb[4] + yb[2] * yb[5]) / rb
    p = min(v, 0.5 * (rda + rdb) + 0.5 * b * dt)
    d = min(bp[6], 0.5 * (abs(ra - bp[0]) + abs(rb - bp[0])) + 0.5 * p * dt)
    lfh = 2.0 * d * p
    return 0.5 * (tp[1] * lfh * lfh + tp[0] * (2.0 * p * p + 2.0 * d * b))


@njit(cache=True, nogil=True)
def g_rate(kind, ya, yb, dt, bp, cp, tp):  # pragma: no cover (compiled)
    """:func:`rate` or :func:`rate_tau` by kind."""
    if kind == XITAU:
        return rate_tau(ya, yb, dt, bp, tp)
    return rate(kind, ya, yb, dt, bp, cp)


@njit(cache=True, nogil=True)
def _g_along(kind, par, tq, t_old, h, y_old, F, tmp, bp, cp, env, tp):  # pragma: no cover (compiled)
    interp(tq, t_old, h, y_old, F, tmp)
    return g_event(kind, par, tq, tmp, bp, cp, env, tp)


@njit(cache=True, nogil=True)
def brent(kind, par, xa, xb, t_old, h, y_old, F, bp, cp, env, tp):  # pragma: no cover (compiled)
    """Zero of the event along the step's interpolant in ``[xa, xb]`` (Brent's method; 4 eps tolerances)."""
    tol = 4.0 * 2.220446049250313e-16
    tmp = np.empty(6)
    xpre, xcur = xa, xb
    fpre = _g_along(kind, par, xpre, t_old, h, y_old, F, tmp, bp, cp, env, tp)
    fcur = _g_along(kind, par, xcur, t_old, h, y_old, F, tmp, bp, cp, env, tp)
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    for _ in range(100):
        if fpre != 0.0 and fcur != 0.0 and ((fpre < 0.0) != (fcur < 0.0)):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = 0.5 * (tol + tol * abs(xcur))
        sbis = 0.5 * (xblk - xcur)
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry
            else:
                spre, scur = sbis, sbis
        else:
            spre, scur = sbis, sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0 else -delta
        fcur = _g_along(kind, par, xcur, t_old, h, y_old, F, tmp, bp, cp, env, tp)
    return xcur
