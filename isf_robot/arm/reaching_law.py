"""The nominal controllers' command law, one plain function per formula (:mod:`isf_robot.arm.nominal`).

:class:`~isf_robot.arm.nominal.ReachingController` maps the end-effector error ``e = p_goal - p_ee``
[m] to joint velocities by damped least squares, and both nominal controllers cap the command's
speed and its rate of change::

    v   = kp e, scaled to |v| <= v_max                       (ee_gain: the factor on e)
    u   = J^T (J J^T + lambda^2 I)^-1 v                       (damped_least_squares, J of shape (3, n))
    u  <- u min(1, u_max / max_i |u_i|)                       (cap_speed: direction kept)
    u  <- u_prev + (u - u_prev) min(1, a_max dt / max_i |u_i - u_prev,i|)   (rate_limit)

The numpy path of the controllers and the compiled kernel (``_kernels_step``: MuJoCo's site
Jacobian, then these functions) call the same source (:func:`~isf_robot.core.jit.formula`).
"""

from __future__ import annotations

import math

from isf_robot.core.jit import formula

__all__ = ["ee_distance", "ee_gain", "damped_least_squares", "peak_abs", "peak_change", "cap_speed", "rate_limit",
           "reaching_command"]


@formula
def ee_distance(err):  # type: ignore[no-untyped-def]
    """``|e|`` [m] of the end-effector error, shape (3,)."""
    return math.sqrt(err[0] * err[0] + err[1] * err[1] + err[2] * err[2])


@formula
def ee_gain(dist, kp, max_ee):  # type: ignore[no-untyped-def]
    """The factor ``g`` of ``v = g e``: ``kp`` [1/s], or ``max_ee / dist`` where ``kp dist`` exceeds ``max_ee``."""
    return kp if kp * dist <= max_ee else max_ee / dist


@formula
def damped_least_squares(jac, v, lam2, out):  # type: ignore[no-untyped-def]
    """``out = J^T (J J^T + lam2 I)^-1 v`` for ``J`` of shape (3, n), ``v`` (3,), ``lam2 > 0``; returns ``out``.

    ``J J^T + lam2 I`` is symmetric positive definite: solved by its Cholesky factor, written out.
    ``jac`` is indexed ``jac[r][k]``: an array, or (the plain path, faster in Python) its ``tolist()``.
    """
    j0, j1, j2 = jac[0], jac[1], jac[2]
    n = len(j0)
    a00 = a01 = a02 = a11 = a12 = a22 = 0.0
    for k in range(n):
        a, b, c = j0[k], j1[k], j2[k]
        a00 += a * a
        a01 += a * b
        a02 += a * c
        a11 += b * b
        a12 += b * c
        a22 += c * c
    l00 = math.sqrt(a00 + lam2)
    l10, l20 = a01 / l00, a02 / l00
    l11 = math.sqrt(a11 + lam2 - l10 * l10)
    l21 = (a12 - l20 * l10) / l11
    l22 = math.sqrt(a22 + lam2 - l20 * l20 - l21 * l21)
    z0 = v[0] / l00  # L z = v, then L^T y = z
    z1 = (v[1] - l10 * z0) / l11
    z2 = (v[2] - l20 * z0 - l21 * z1) / l22
    y2 = z2 / l22
    y1 = (z1 - l21 * y2) / l11
    y0 = (z0 - l10 * y1 - l20 * y2) / l00
    for k in range(n):
        out[k] = j0[k] * y0 + j1[k] * y1 + j2[k] * y2
    return out


@formula
def peak_abs(u):  # type: ignore[no-untyped-def]
    """``max_i |u_i|``: NaN if some ``u_i`` is NaN, 0 for an empty ``u``."""
    peak = 0.0
    for k in range(len(u)):
        a = abs(u[k])
        if not a <= peak:  # (a NaN is taken, and nothing replaces it)
            peak = a
            if a != a:
                break
    return peak


@formula
def peak_change(u, prev):  # type: ignore[no-untyped-def]
    """``max_i |u_i - prev_i|``: NaN if some term is NaN, 0 for empty vectors."""
    peak = 0.0
    for k in range(len(u)):
        a = abs(u[k] - prev[k])
        if not a <= peak:
            peak = a
            if a != a:
                break
    return peak


@formula
def cap_speed(u, limit):  # type: ignore[no-untyped-def]
    """Scale ``u`` as a whole so that ``max_i |u_i| <= limit`` (direction kept), in place; returns ``u``."""
    peak = peak_abs(u)
    if peak > limit:
        f = limit / peak
        for k in range(u.shape[0]):
            u[k] *= f
    return u


@formula
def rate_limit(u, prev, has_prev, dt, a_max):  # type: ignore[no-untyped-def]
    """Limit the change from ``prev``: ``max_i |u_i - prev_i| <= a_max max(dt, 0)``, in place; ``prev`` becomes ``u``.

    The whole change is scaled (direction kept); without a previous command (``has_prev`` false) the
    command is zero (the arm starts at rest). ``a_max = inf``: no limit.
    """
    if a_max != math.inf:
        if has_prev:
            step = max(dt, 0.0) * a_max
            peak = peak_change(u, prev)
            if peak > step:
                f = step / peak
                for k in range(u.shape[0]):
                    u[k] = prev[k] + (u[k] - prev[k]) * f
        else:
            u[:] = 0.0
    prev[:] = u
    return u


@formula
def reaching_command(err, dist, jac, kp, max_ee, lam2, max_js, out):  # type: ignore[no-untyped-def]
    """The reaching command before its rate limit, into ``out`` (n,): ``v = ee_gain e``, DLS, speed cap.

    ``jac`` as :func:`damped_least_squares` takes it. (The DLS map is linear: it maps ``e``, and the
    result is scaled by the gain.)
    """
    damped_least_squares(jac, err, lam2, out)
    gain = ee_gain(dist, kp, max_ee)
    for k in range(out.shape[0]):
        out[k] *= gain
    return cap_speed(out, max_js)
