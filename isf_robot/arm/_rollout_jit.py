"""The kernels of the predictive off trigger's rollout (:mod:`isf_robot.arm.rollout`; only with numba).

Plain functions that :func:`~isf_robot.core.jit.compiled` compiles (:mod:`isf_robot.arm.kernels`
hands them out; its cache is keyed on every source file of this folder, so an edit of a kernel or
formula this calls compiles it again). MuJoCo's ``mj_kinematics`` and ``mj_comPos`` are called on the
raw addresses of the ``MjModel``/``MjData`` the bindings hold; :func:`closed_loop_points` calls the
reaching controller's kernel (``_kernels_step.reach``) and the collision kernel
(``_kernels_jit.near_packed_key``), :func:`team_points` each arm's reaching kernel and the collision kernel once per
point; :func:`closed_loop_predict` computes the command now (``reach``), calls it
and then the core's prediction pass (:func:`~isf_robot.core.robust.predict_pass`), so its cache is keyed on the
core's sources too (:func:`isf_robot.arm.rollout.predict_kernel`).
"""

from __future__ import annotations

import numpy as np
from numba import carray

from isf_robot.core.jit import formula
from isf_robot.core.robust import predict_pass

from ._kernels_jit import com_pos, f64p, i64p, kinematics, near_packed_key  # (loads libmujoco; ImportError without it)
from ._kernels_step import reach


@formula
def euler_step(ma, da, q, u, dt, qpos, qadr):  # pragma: no cover (compiled)
    """``q <- q + dt u``, ``qpos[qadr] = q``, then the kinematics."""
    for i in range(q.shape[0]):
        q[i] = q[i] + dt * u[i]
        qpos[qadr[i]] = q[i]
    kinematics(ma, da)
    com_pos(ma, da)


@formula
def place_obstacles(mp, mids, mpos, j):  # pragma: no cover (compiled)
    """Mocap body ``mids[r]`` at ``mpos[j, r]`` (``mp``: the scratch data's ``mocap_pos``), every ``r``."""
    for r in range(mids.shape[0]):
        for c in range(3):
            mp[mids[r], c] = mpos[j, r, c]


@formula
def point_rows(ma, da, pn, blk, rows, keys, res, npairs, cutoff, distmax, slack, eps, norms_in, lin,
               dhdt_in):  # pragma: no cover (compiled)
    """A point's rows (kinematics done): the collision kernel's into ``blk``/``rows``, their keys and ``res[:5]``.

    ``near_packed_key`` (tables ``pn``, no coherence bounds, mocap velocities ``lin``); each row's key into
    ``keys`` (a pair's index for the pair rows, ``npairs + i`` for the i-th row after them: the joint rows);
    ``res[:5]``: near pairs, h_min, dist_min, joint_min, touching. Returns whether witness points touch.
    """
    k, h_min, dist_min, jmin, touching, _ = near_packed_key(ma, da, pn, blk, rows, False, cutoff, distmax, slack, eps,
                                                            norms_in, lin, dhdt_in)
    res[0], res[1], res[2], res[3], res[4] = k, h_min, dist_min, jmin, 1.0 if touching else 0.0
    for i in range(k):
        keys[i] = rows[i]
    for i in range(keys.shape[0] - k):
        keys[k + i] = npairs + i
    return touching


@formula
def closed_loop_points(ma, da, q, v0, e, decay, t, dt, qpos, qadr, rp, nb, outs, vs, n, nv, dof0, site, index, t_prev,
                  a_max, kp, max_ee, max_js, lam2, pn, blks, rows, keys, npairs, res, cutoff, distmax, slack, eps,
                  norms_in, lin, dhdt_in, mp_addr, nmocap, mids, mpos, lins):  # pragma: no cover (compiled)
    """The reaching controller's closed loop rolled forward, in one call: both levels' rollout points.

    Per point ``j`` (time ``t + (j + 1) dt``): the obstacles' places, the Euler step ``q <- q + dt v`` with the
    previous joint velocity ``v`` (``v0`` first), the reaching controller's command ``v_ref`` into ``outs[j]``
    (``reach``, buffer ``nb``, addresses ``rp``), the tracking error ``e <- e decay`` (in place) and the joint
    velocity ``vs[j] = v_ref + e``, the collision kernel's rows into ``blks[j]``/``rows[j]``
    (``near_packed_key``, tables ``pn``, no coherence bounds), and each row's key into ``keys[j]`` (a pair's
    index for the pair rows, ``npairs + i`` for the i-th row after them: the joint rows).
    The velocity level tracks its command (no error, ``vs`` is ``outs``:
    :class:`~isf_robot.arm.rollout.NominalRollout`); the torque level's computed torque leaves an error that
    decays as ``exp(-kd s)`` (:class:`~isf_robot.arm.torque_rollout.TorqueRollout`, after its first point).
    ``res[j]``: near pairs, h_min, dist_min, joint_min, touching, goal distance. Returns the points done:
    it stops after a point with touching witness points (which the caller hands to the general path).
    Moving obstacles: before each point's kinematics, mocap body ``mids[r]`` is put at ``mpos[j, r]``
    (the scratch data's ``mocap_pos`` at address ``mp_addr``, ``nmocap`` rows), and the collision
    kernel reads the mocap velocities ``lins[j]`` (no rows: ``lin`` at every point).

    The per-point rows of the outputs and the controller's buffer are views of raw aliases of the arrays
    (``carray``, which own no memory): a view of an argument itself takes and drops a reference count, an atomic
    operation, some forty times a point in all (6 % of the call on panda_pole).
    """
    if not (nb.flags.c_contiguous and outs.flags.c_contiguous and vs.flags.c_contiguous and blks.flags.c_contiguous
            and res.flags.c_contiguous and rows.flags.c_contiguous and keys.flags.c_contiguous):
        raise ValueError("closed_loop_points: its output and buffer arrays must be C-contiguous (read as C aliases)")
    v = v0
    mp = carray(f64p(mp_addr), (max(nmocap, 1), 3))
    nb, outs, vs = carray(f64p(nb.ctypes.data), nb.shape), carray(f64p(outs.ctypes.data), outs.shape), \
        carray(f64p(vs.ctypes.data), vs.shape)  # (the arguments are alive for the call: the aliases stay valid)
    blks, res = carray(f64p(blks.ctypes.data), blks.shape), carray(f64p(res.ctypes.data), res.shape)
    rows, keys = carray(i64p(rows.ctypes.data), rows.shape), carray(i64p(keys.ctypes.data), keys.shape)
    for j in range(outs.shape[0]):
        tj = t + (j + 1) * dt
        place_obstacles(mp, mids, mpos, j)  # (the obstacles' place first: the kinematics below read it)
        euler_step(ma, da, q, v, dt, qpos, qadr)
        res[j, 5] = reach(ma, da, rp, nb, outs[j], n, nv, dof0, site, index, False, tj, t_prev, True, a_max, kp,
                          max_ee, max_js, lam2)
        t_prev = tj
        for i in range(n):
            e[i] = e[i] * decay
            vs[j, i] = outs[j, i] + e[i]
        v = vs[j]
        if point_rows(ma, da, pn, blks[j], rows[j], keys[j], res[j], npairs, cutoff, distmax, slack, eps,
                      norms_in, lins[j] if lins.shape[0] else lin, dhdt_in):
            return j + 1
    return outs.shape[0]



def team_points(ma, da, q, v0, t, dt, qpos, qadr, rps, nbs, arm_i, arm_f, nv, outs, pn, blks, rows, keys, npairs, res,
                cutoff, distmax, slack, eps, norms_in, lin, dhdt_in, mp_addr, nmocap, mids, mpos,
                lins):  # pragma: no cover (compiled)
    """The closed loop of several arms' reaching controllers (a team's nominal) rolled forward, in one call.

    As :func:`closed_loop_points` at the velocity level (no tracking error: the joint velocity is the command),
    with every arm's command at each point: arm ``a``'s reaching controller (``reach``, its addresses ``rps[a]``,
    buffer ``nbs[a]``, ``arm_i[a]``: its joints, first dof, end-effector site, goal index and first column of
    the team's command; ``arm_f[a]``: the time of its rate limit's previous command, then its ``a_max``, ``kp``,
    ``max_ee``, ``max_js`` and ``lam2``) into ``outs[j]``'s columns from that first column. One Euler step of
    every joint, one kinematics and one collision kernel call per point (:func:`point_rows`). ``res[j, 5]``: the
    largest goal distance of the arms. Returns the points done (it stops after a point with touching witness points).
    """
    v = v0
    mp = carray(f64p(mp_addr), (max(nmocap, 1), 3))
    for j in range(outs.shape[0]):
        tj = t + (j + 1) * dt
        place_obstacles(mp, mids, mpos, j)  # (the obstacles' place first: the kinematics below read it)
        euler_step(ma, da, q, v, dt, qpos, qadr)
        far = 0.0
        for a in range(arm_i.shape[0]):
            n, c0 = arm_i[a, 0], arm_i[a, 4]
            t_prev = arm_f[a, 0] if j == 0 else t + j * dt  # (the previous point's time, as the loop makes it)
            dist = reach(ma, da, rps[a], nbs[a], outs[j, c0: c0 + n], n, nv, arm_i[a, 1], arm_i[a, 2], arm_i[a, 3],
                         False, tj, t_prev, True, arm_f[a, 1], arm_f[a, 2], arm_f[a, 3], arm_f[a, 4], arm_f[a, 5])
            far = max(far, dist)
        res[j, 5] = far
        v = outs[j]
        if point_rows(ma, da, pn, blks[j], rows[j], keys[j], res[j], npairs, cutoff, distmax, slack, eps,
                      norms_in, lins[j] if lins.shape[0] else lin, dhdt_in):
            return j + 1
    return outs.shape[0]

def closed_loop_predict(ma, da, q, v0, e, decay, t, dt, qpos, qadr, rp, nb, outs, vs, n, nv, dof0, site, index, t_prev,
                        a_max, kp, max_ee, max_js, lam2, pn, blks, rows, keys, npairs, res, cutoff, distmax, slack, eps,
                        norms_in, lin, dhdt_in, mp_addr, nmocap, mids, mpos, lins, nb0, dx, xsite, rpx, lg, nj, o_lf,
                        o_gn, gain, d_bar, k, xi, fails, nfail, seen, out):  # pragma: no cover (compiled)
    """The command now, :func:`closed_loop_points` from it and ``Xi_on`` at the points, in one call.

    First ``q`` is read from ``qpos`` (the scratch data, loaded with the episode's positions) and the buffer ``nb``
    from the controller's ``nb0``. The command now: the reaching controller's at time ``t`` on the episode's data
    (address ``dx``, its ``site_xpos`` at ``xsite``; ``rpx`` takes the addresses as ``rp`` holds them) toward goal
    ``index``, rate-limited from the command of ``t_prev``, into ``v0``: what
    :meth:`~isf_robot.arm.nominal.ReachingController.__call__` computes when its goal stays (the caller
    checks that). The other arguments up to ``lins`` are :func:`closed_loop_points`' (it runs from ``v0``, with
    the rate limit's previous command that of ``t``); the blocks ``blks`` hold each point's ``h`` (its first
    ``K = keys.shape[1]`` entries), ``Lf h`` (from ``o_lf``) and ``|dh/dq|`` (from ``o_gn``), ``lg`` is their
    ``Lg h`` (n, K, nv) and ``nj`` the joint rows after each point's pairs. The prediction pass with
    ``alpha(h) = gain h`` (``gain > 0``) and ``d_bar`` on the commands ``outs``: each point's rows to ``k``, then
    ``xi``, ``fails``, ``nfail``, ``seen`` (cleared first) and ``out`` as :func:`predict_pass` writes them.
    Returns ``(done, bad, xi_min, found)``: the points done (-1 after a point with touching witness points: no
    pass, ``bad = -1``) and :func:`predict_pass`'s answer.
    """
    for i in range(q.shape[0]):
        q[i] = qpos[qadr[i]]
    nb[:] = nb0
    rpx[0], rpx[1] = rp[0], xsite
    reach(ma, dx, rpx, nb, v0, n, nv, dof0, site, index, False, t, t_prev, True, a_max, kp, max_ee, max_js, lam2)
    done = closed_loop_points(ma, da, q, v0, e, decay, t, dt, qpos, qadr, rp, nb, outs, vs, n, nv, dof0, site, index,
                              t, a_max, kp, max_ee, max_js, lam2, pn, blks, rows, keys, npairs, res, cutoff,
                              distmax, slack, eps, norms_in, lin, dhdt_in, mp_addr, nmocap, mids, mpos, lins)
    if done < outs.shape[0] or res[done - 1, 4] != 0.0:
        return -1, -1, np.inf, 0
    m = keys.shape[1]
    for j in range(done):
        k[j] = int(res[j, 0]) + nj
    seen[:] = False
    bad, low, found = predict_pass(blks[:, o_lf: o_lf + m], lg, outs, blks[:, o_gn: o_gn + m], d_bar, blks[:, :m],
                                   gain, np.zeros((0, 0)), k, xi, fails, nfail, keys, seen, out)
    return done, bad, low, found
