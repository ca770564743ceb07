"""The kernels of the nominal and act phases (:mod:`isf_robot.arm.kernels`; only with numba).

Plain functions that :func:`~isf_robot.core.jit.compiled` compiles (:mod:`isf_robot.arm.kernels`
hands them out). What is here is what only compiled code can do: MuJoCo's C functions (``mj_mulM``,
``mj_jacSite``) on the raw addresses of the ``MjModel``/``MjData`` the bindings hold, and the
arrays a kernel works on passed as one int64 array of their addresses (a numba call costs about
0.1-0.6 us per array argument, more than the kernels' own work): the callers keep the arrays
alive and never reallocate them (see :class:`~isf_robot.arm.lowlevel.VelocityTracker` and
:class:`~isf_robot.arm.nominal.ReachingController`). The control laws are the functions of
:mod:`isf_robot.arm.tracking_law` and :mod:`isf_robot.arm.reaching_law`, which the numpy paths call too.
"""

from __future__ import annotations

import numpy as np
from numba import carray

from isf_robot.core.jit import formula

from ._kernels_jit import f64p, jac_site, monitor, mul_m  # (importing it loads libmujoco; ImportError without it)
from .reaching_law import ee_distance, rate_limit, reaching_command
from .tracking_law import command_feedforward, desired_acceleration, motor_ctrl, reference_error, tracking_error

# -- the tracker (VelocityTracker.apply), its buffer: rows of n, then two of nv, then scalars ----
U, REF, AFF, KD, KP, INVG, LO, HI = range(8)
"""Rows of the tracker's buffer (n values each): command, reference, feedforward, gains, limits."""
ROWS = 8
"""Rows of n before the two of nv."""


@formula
def track_apply(ma, da, p, buf, n, nv):  # pragma: no cover (compiled)
    """VelocityTracker.apply: the torques for the held command (one physics step), the law around ``mj_mulM``."""
    q, qd, ctrl = carray(f64p(p[0]), n), carray(f64p(p[1]), n), carray(f64p(p[2]), n)
    bias, passive = carray(f64p(p[3]), n), carray(f64p(p[4]), n)
    dof0 = p[5]
    acc_full = buf[ROWS * n: ROWS * n + nv]
    tau_full = buf[ROWS * n + nv: ROWS * n + 2 * nv]
    dt, emax = buf[ROWS * n + 2 * nv], buf[ROWS * n + 2 * nv + 1]
    for i in range(n):
        u = buf[U * n + i]
        err = reference_error(buf[REF * n + i], u, dt, q[i], emax)
        buf[REF * n + i] = q[i] + err
        acc_full[dof0 + i] = desired_acceleration(u, qd[i], err, buf[KD * n + i], buf[KP * n + i], buf[AFF * n + i])
    mul_m(ma, da, tau_full.ctypes.data, acc_full.ctypes.data)
    for i in range(n):
        ctrl[i] = motor_ctrl(tau_full[dof0 + i], bias[i], passive[i], 0.0, buf[INVG * n + i], buf[LO * n + i],
                             buf[HI * n + i])


def track_step(ma, da, p, buf, n, nv, cmd, inv_period, feedforward):  # pragma: no cover (compiled)
    """Tracking error of the held command, then set_command(cmd) and apply; returns ``|qd - u_held|``."""
    err = tracking_error(carray(f64p(p[1]), n), buf[U * n: U * n + n])
    for i in range(n):
        buf[AFF * n + i] = command_feedforward(cmd[i], buf[U * n + i], inv_period) if feedforward else 0.0
        buf[U * n + i] = cmd[i]
    track_apply(ma, da, p, buf, n, nv)
    return err


def monitor_apply(ma, da, rows, g1, g2, margin, thresh, bound, p, buf, n, nv):  # pragma: no cover (compiled)
    """A physics sub-step's safety check (``_kernels_jit.monitor``), then the tracker's apply, in one call."""
    step_h = monitor(ma, da, rows, g1, g2, margin, thresh, bound)
    track_apply(ma, da, p, buf, n, nv)
    return step_h


# -- the reaching controller (ReachingController.__call__) -------------------------------------
@formula
def reach(ma, da, p, nb, out, n, nv, dof0, site, index, restore, t, t_prev, has_prev, a_max,
          kp, max_ee, max_js, lam2):  # pragma: no cover (compiled)
    """The DLS command toward goal ``index``, speed-capped and rate-limited, into ``out``.

    ``p``: addresses of the goal positions (g, 3) and of ``site_xpos``; ``nb``: the controller's
    buffer (the rate limit's previous command, a copy of it, the Jacobian and scratch). The rate
    limit's previous command becomes ``out`` (``restore``: first put back the copy, for a second
    call at the same tick). Returns the distance to the goal.
    """
    goal = carray(f64p(p[0] + index * 24), 3)
    ee = carray(f64p(p[1] + site * 24), 3)
    prev = nb[0:n]
    backup = nb[n: 2 * n]
    jac = nb[2 * n: 2 * n + 3 * nv]  # (3, nv), row-major
    err = nb[2 * n + 3 * nv: 2 * n + 3 * nv + 3]
    if restore:
        prev[:] = backup
    else:
        backup[:] = prev
    for i in range(3):
        err[i] = goal[i] - ee[i]
    dist = ee_distance(err)
    jac_site(ma, da, jac.ctypes.data, 0, np.int32(site))
    reaching_command(err, dist, jac.reshape((3, nv))[:, dof0: dof0 + n], kp, max_ee, lam2, max_js, out)
    rate_limit(out, prev, has_prev, t - t_prev, a_max)
    return dist
