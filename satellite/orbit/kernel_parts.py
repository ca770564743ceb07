"""Compiled pieces of the fast arc integrator (imported only when numba is installed and used).

The arcs call the run's formula functions themselves, compiled (:mod:`satellite.compiled`):

* the truth right-hand side: :func:`satellite.orbit.model.to_body`,
  :func:`satellite.gravity.table.table_acceleration`, :func:`satellite.orbit.model.truth_from_body`;
* the band's events and rate bounds: :func:`satellite.control.triggers.band_values`,
  :func:`~satellite.control.triggers.band_xi`, :func:`~satellite.control.triggers.band_rate`;
* the maneuver trigger: :func:`satellite.control.tau.tau_slope` and the core's
  :func:`isf_robot.core.triggers.xi_tau`;
* the contact watch: :func:`satellite.control.contact.contact_g` and
  :func:`~satellite.control.contact.contact_rate`.

Here: the dispatch by event kind, DOP853's interpolant at one point and Brent's method on an event
along it. :mod:`satellite.orbit.arc_kernel` integrates arcs with them; :mod:`satellite.orbit.fast_arcs`
packs the arguments. numba's on-disk cache keys each kernel on its own file: after editing a formula in
another module, clear ``satellite/**/__pycache__/*.nb*``.

Packed parameters (float arrays, filled by :mod:`satellite.orbit.fast_arcs`):

* ``fp`` (field): body phase, spin rate, disturbance scale, then the table's ``geom``
  (:attr:`satellite.gravity.table.GravityTable.geom`); ``ext`` the table's padded coefficients;
  ``box_o``, ``box_n``, ``coef`` the fine boxes (:meth:`satellite.gravity.fine.FineBoxes.packed`).
* ``bp`` (band): r_centre, h_max, d_bar, accel bound A, r_inner, r_outer, half width,
  alpha gain, alpha slope bound.
* ``cp`` (contact): body phase, spin rate, cell size, n_lat, n_lon, max radius, min radius,
  slope, accel bound.
* ``tp`` (maneuver): :attr:`satellite.control.tau.TauFit.packed`.
"""

from __future__ import annotations

import numpy as np

from satellite.compiled import kernel
from satellite.control.contact import contact_g, contact_rate
from satellite.control.tau import tau_slope
from satellite.control.triggers import CONTACT, RDOT, XI, XITAU, H, band_rate, band_values, band_xi, xi_tau
from satellite.gravity.table import table_acceleration
from satellite.orbit.model import to_body, truth_from_body

__all__ = ["rhs", "interp", "interp_many", "g_event", "g_rate", "brent", "XI", "H", "RDOT", "CONTACT", "XITAU"]


@kernel
def rhs(t, y, out, fp, ext, box_o, box_n, coef):  # pragma: no cover (compiled)
    """Truth flow at ``(t, y)`` into ``out`` (:meth:`satellite.orbit.model.OrbitModel.truth_rhs`'s formulas)."""
    c, s, qx, qy = to_body(fp[0] + fp[1] * t, y[0], y[1])
    bx, by, bz = table_acceleration(qx, qy, y[2], fp[3:], ext, box_o, box_n, coef)
    ax, ay, az = truth_from_body(c, s, qx, qy, y[2], bx, by, bz, fp[3], fp[2])
    out[0] = y[3]
    out[1] = y[4]
    out[2] = y[5]
    out[3] = ax
    out[4] = ay
    out[5] = az


@kernel
def interp(tq, t_old, h, y_old, F, out):  # pragma: no cover (compiled)
    """DOP853's interpolant (scipy's ``Dop853DenseOutput``) of one step at ``tq`` into ``out``."""
    x = (tq - t_old) / h
    for c in range(6):
        acc = 0.0
        for i in range(7):
            acc += F[6 - i, c]
            acc *= x if i % 2 == 0 else 1.0 - x
        out[c] = acc + y_old[c]


@kernel
def interp_many(tq, seg, ts, hs, y_old, F, out):  # pragma: no cover (compiled)
    """:func:`interp` at times ``tq`` (k,) in the segments ``seg`` (k,) of a dense output, into ``out`` (k, 6)."""
    for n in range(tq.shape[0]):
        s = seg[n]
        interp(tq[n], ts[s], hs[s], y_old[s], F[s], out[n])


@kernel
def g_event(kind, par, t, y, bp, cp, env, tp):  # pragma: no cover (compiled)
    """The event function of ``kind`` at ``(t, y)``."""
    if kind == RDOT:
        return y[0] * y[3] + y[1] * y[4] + y[2] * y[5]
    if kind == CONTACT:
        return contact_g(t, y[0], y[1], y[2], cp[0], cp[1], env, cp[2], int(cp[3]), int(cp[4]), cp[5])
    r, h, lfh = band_values(y, bp[0], bp[1])
    if kind == H:
        return h - par
    if kind == XI:
        return band_xi(lfh, r, bp[0], bp[2], bp[7] * h)
    return xi_tau(tau_slope(tp, h), lfh)  # XITAU


@kernel
def g_rate(kind, ya, yb, dt, bp, cp, tp):  # pragma: no cover (compiled)
    """Bound on ``|dg/dt|`` over an interval of length ``dt`` with end states ``ya``, ``yb``."""
    if kind == CONTACT:
        return contact_rate(ya, yb, dt, cp[8], cp[7], cp[6], cp[5], cp[1])
    return band_rate(kind, ya, yb, dt, bp[3], bp[4], bp[5], bp[6], bp[0], bp[8], bp[2], tp[0], tp[1])


@kernel
def _g_along(kind, par, tq, t_old, h, y_old, F, tmp, bp, cp, env, tp):  # pragma: no cover (compiled)
    interp(tq, t_old, h, y_old, F, tmp)
    return g_event(kind, par, tq, tmp, bp, cp, env, tp)


@kernel
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
