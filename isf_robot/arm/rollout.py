"""The nominal controller rolled forward on the reduced model, for the predictive off trigger.

The intermittent filter's predictive off trigger (:class:`~isf_robot.core.intermittent.OffPredictor`)
asks, before switching off, what the nominal controller would do alone: :class:`NominalRollout`
integrates the reduced model ``q_dot = u_nom(t, q)`` (the paper's ``x_dot = f(x, u) + d`` of Section II with
``x = q``, ``f(x, u) = u`` and ``d = 0``) by explicit Euler from the episode's current joint positions,
moves the moving obstacles along their paths, and returns
the barrier rows (the collision pairs within the cut-off and the joint limits, as the simulation
builds them) with the nominal command at each predicted point. The core computes ``Xi_on`` at
those points with the filter's own ``alpha`` and ``d_bar``.

Cost per rollout, bounded: ``points`` (default at most 10) evaluations of the nominal controller,
of the kinematics and of the barriers on a scratch ``MjData``; the filter runs at most one rollout
every ``predict_every`` control steps, and only while it is on with every ``Xi_on`` above the margin.
The nominal controller's own state (goal bookkeeping, rate limit) is saved before and restored
after, so a rollout changes nothing in the episode.

With numba (:mod:`isf_robot.arm._rollout_jit`), while the goal cannot change over the horizon
(:meth:`~isf_robot.arm.goals.GoalSequence.steady`) and the nominal is the :class:`ReachingController`
with its compiled command, all points are one compiled call (the moving obstacles' places, Euler step,
kinematics, the controller's kernel, the collision kernel with the mocap velocities), and the points are
handed over stacked
(:class:`~isf_robot.core.intermittent.StackedPoints`: the blocks' arrays, each point's Lie data read from
its block only when asked for, so ``predict`` evaluates every point in one compiled pass). A team's nominal
(:class:`~isf_robot.arm.team_nominal.TeamReaching`) takes the same way while every arm's goal is steady
(:class:`~isf_robot.arm.team_rollout.TeamPoints`: each arm's compiled command at every point); otherwise
each point's Euler step and kinematics are one call and its rows
:meth:`~isf_robot.arm.collision.CollisionBarriers.lie_rows`. Every path computes the numpy loop's
points with the same formulas (equal to rounding). The off trigger asks :meth:`NominalRollout.prediction`
first: on the one-call path, the command now, the points and their ``Xi_on`` (the core's
:func:`~isf_robot.core.robust.predict_pass`) in one compiled call (``_rollout_jit.closed_loop_predict``) into
outputs kept on the rollout, so no points, arrays or Lie data are made and the controller is neither called nor
put back (2026-11-28, panda_pole: about 50 us per rollout and prediction repeated in a loop, 84 us through the
stacked points; in the episode, where the rollout's code and data are cold, about 64 us against 100, of which
the kernel's work is about 42: the kinematics 10, the controller's command 3, the collision pairs 22).
Measured on panda_pole (10 points, process time, 2026-11-23): about 120 us per rollout outside the loop in one
call (190 us point by point), mostly the collision kernel's distance calls.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import Any, cast

import mujoco
import numpy as np

from isf_robot.core import ConfigError, LieData, Linear
from isf_robot.core.class_k import ClassK
from isf_robot.core.intermittent import Prediction, StackedPoints, pass_prediction
from isf_robot.core.jit import compiled

from . import kernels, narrow
from .collision import CollisionBarriers
from .joint_limits import JointLimitBarriers
from .nominal import ReachingController
from .paths import path_track
from .scene import Scene
from .team_rollout import TeamPoints

__all__ = ["NominalRollout", "ScratchRollout", "MAX_POINTS", "obstacle_tracks"]

_NO_IDS, _NO_POS, _NO_LINS = np.zeros(0, np.int64), np.zeros((0, 0, 3)), np.zeros((0, 0))

MAX_POINTS = 10
"""Default largest number of predicted points per rollout (the integration step grows with the horizon)."""


def obstacle_tracks(scene: Scene, times: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """The moving obstacles' places (n, p, 3) and every mocap body's linear velocity (n, nmocap, 3) at ``times``.

    Places in the order of ``scene.moving_mocap_ids``; through :func:`~isf_robot.arm.paths.path_track` (a track's
    numbers are those of each time alone: ``Scene.set_moving_obstacles``/``mocap_velocities``, one call per time).
    """
    ts = np.array(times, dtype=float)
    mids = scene.moving_mocap_ids
    mpos, lins = np.empty((ts.size, len(mids), 3)), np.zeros((ts.size, int(scene.model.nmocap), 3))
    for r, mv in enumerate(scene.config.moving):
        pos, vel = path_track(mv.path, ts)
        mpos[:, r] = pos
        lins[:, mids[r]] = vel
    return mpos, lins


def predict_kernel() -> Any:
    """``_rollout_jit.closed_loop_predict`` compiled (``None`` without the compiled kernels).

    It compiles the core's :func:`~isf_robot.core.robust.predict_pass` into itself, so its disk cache is keyed on
    the core's sources as well as this folder's (:func:`~isf_robot.core.jit.stamp_sources`). ``None`` also under
    ``ISF_ROBOT_JIT=cached`` while numba's cache does not hold it.
    """
    if kernels.rollout_kernels() is None:
        return None
    from isf_robot.core import robust

    from . import _rollout_jit

    fn = compiled(_rollout_jit.closed_loop_predict, (os.path.dirname(robust.__file__),))
    return fn if hasattr(fn, "py_func") else None  # (ISF_ROBOT_JIT=cached before it is compiled: the points' path)


class ScratchRollout:
    """What a rollout of a nominal from the episode's state holds: the part its two kinds share.

    :class:`NominalRollout` and :class:`~isf_robot.arm.torque_rollout.TorqueRollout`: the checked arguments, the
    step and the number of points, a scratch ``MjData`` loaded from the episode's (:meth:`_load`), the compiled
    Euler step where the kernels run.

    Args:
        scene: The scene.
        nominal: The nominal controller (with ``snapshot()``/``restore()``: put back after each rollout).
        coll: The collision barriers (their rows at the predicted states).
        joints: The joint-limit barriers.
        control_period: The control period [s].
        time_offset: The episode's time offset [s] (moving obstacles' clock).
        horizon: Prediction horizon [s], > 0.
        points: Largest number of predicted points; the step is ``max(control period, horizon / points)``.

    """

    def __init__(self, scene: Scene, nominal: Any, coll: CollisionBarriers, joints: JointLimitBarriers,
                 control_period: float, time_offset: float, horizon: float, points: int) -> None:
        if not (math.isfinite(horizon) and horizon > 0):
            raise ConfigError(f"rollout horizon must be > 0 [s], got {horizon}")
        if int(points) != points or points < 1:
            raise ConfigError(f"rollout points must be a whole number >= 1, got {points}")
        if not (callable(getattr(nominal, "snapshot", None)) and callable(getattr(nominal, "restore", None))):
            raise ConfigError("the predictive off trigger (horizon > 0) needs a nominal controller with "
                              "snapshot() and restore() (isf_robot.arm.NominalController has them)")
        self.scene, self.nominal = scene, nominal
        self.coll, self.joints = coll, joints
        self.offset = float(time_offset)
        self.dt = max(float(control_period), float(horizon) / int(points))
        self.n = max(1, int(math.ceil(float(horizon) / self.dt - 1e-9)))
        self.horizon = float(horizon)
        self.moving = len(scene.config.moving) > 0
        self._data = mujoco.MjData(scene.model)
        self._qadr = np.ascontiguousarray(scene.qpos_adr, dtype=np.int64)
        self._kernels = kernels.rollout_kernels() if getattr(scene.model, "_address", 0) else None
        self._step = self._kernels[0] if self._kernels is not None else None  # (q + dt u and the kinematics)
        self._addr = (int(getattr(scene.model, "_address", 0)), int(getattr(self._data, "_address", 0)))
        self._nmocap = int(scene.model.nmocap)
        self._mids = np.ascontiguousarray(scene.moving_mocap_ids, dtype=np.int64) if self.moving else _NO_IDS
        self._mp_addr = int(self._data.mocap_pos.ctypes.data)  # (a kernel writes the moving obstacles' places there)
        self._ctx: tuple | None = None  # (the collision kernel's context on the scratch data: made once)
        self.calls = 0

    def _whole_kernel(self) -> Any:
        """The whole-rollout kernel (:func:`~isf_robot.arm.kernels.rollout_kernels`' second), or ``None``.

        The kernel when every point can be one call: the reaching controller with its compiled command on this
        model, and the compiled collision kernel.
        """
        nom, ks = self.nominal, self._kernels
        reach = (type(nom) is ReachingController and nom._reach is not None  # (its compiled command)
                 and nom.scene.model is self.scene.model)
        return ks[1] if ks is not None and reach and self.coll._kernel is not None else None

    def _steady(self, t: float, first: float | None = None, controllers: Sequence[Any] | None = None) -> bool:
        """Whether the points after ``t`` can be one compiled call.

        For each of ``controllers`` (default the nominal itself; a team's: every arm's reaching controller): the
        goal index cannot change over the horizon, from ``first`` (default the first point, ``t + dt``) to its end
        (:meth:`GoalSequence.steady`: the kernel holds it; the goal bookkeeping is put back after the rollout
        anyway), the controller has a previous command (its rate limit) and its compiled command is bound to the
        scratch data; and the collision kernel computes ``dh/dt``.
        """
        coll = self.coll
        if coll._any_moving and not coll._kdhdt:
            return False
        start, end = t + self.dt if first is None else first, t + self.n * self.dt
        return all(c._rate.t_prev is not None and c.goals.steady(start, end) and c._bound(self._data)
                   for c in ((self.nominal,) if controllers is None else controllers))

    def _load(self, x: Any) -> mujoco.MjData:
        """The scratch data with the episode's positions and mocap bodies (``x``: the episode's ``MjData``)."""
        if not isinstance(x, mujoco.MjData):
            raise ConfigError(f"{type(self).__name__} needs the episode's MjData as the state x of step_lie")
        d = self._data
        d.qpos[:] = x.qpos
        if self._nmocap:
            d.mocap_pos[:] = x.mocap_pos
            d.mocap_quat[:] = x.mocap_quat
        return d

    def _context(self) -> tuple:
        """The collision kernel's context on the scratch data (without bounds: the same tables for every rollout)."""
        c = self._ctx
        if c is None:
            c = self._ctx = self.coll._kernel_context(self._data, None, self.joints)
        return c

    def _whole_args(self, t: float, q: np.ndarray, v0: np.ndarray, e: np.ndarray, decay: float,
                    mpos: np.ndarray | None, lins: np.ndarray | None, c: tuple, outs: np.ndarray, vs: np.ndarray,
                    blk: np.ndarray, rows: np.ndarray, keys: np.ndarray, res: np.ndarray,
                    nb: np.ndarray | None = None) -> tuple:
        """The arguments of ``_rollout_jit.closed_loop_points`` (see :meth:`_run_whole`) with these outputs.

        ``nb``: the controller's buffer to use (``None``: its own).
        """
        nom, coll = self.nominal, self.coll
        rate = nom._rate
        mp, ls, lin, dl = self._moving_args(mpos, lins)
        return (*self._addr, q, v0, e, decay, t, self.dt, self._data.qpos, self._qadr, nom._ptrs,
                nom._buf if nb is None else nb, outs, vs, v0.size, nom._jac.shape[1], nom._dof0, nom.scene.ee_site_id,
                nom.goals.index, rate.t_prev, rate.a_max, nom.kp, nom.max_ee_speed, nom.max_joint_speed, nom._lam2,
                c[4], blk, rows, keys, len(coll.pairs.names), res, coll.cutoff, c[14], c[15], narrow._EPS_DIST, c[13],
                lin, dl, self._mp_addr, self._nmocap, self._mids, mp, ls)

    def _moving_args(self, mpos: np.ndarray | None, lins: np.ndarray | None) -> tuple:
        """The kernels' moving-obstacle arguments ``(places, velocities, lin, dhdt_in)`` for ``mpos``/``lins``.

        ``None``: no moving obstacle; the velocities are handed over only where the collision kernel makes
        ``dh/dt`` (else ``lin`` at every point, the empty one).
        """
        coll = self.coll
        mp, ls, lin, dl = _NO_POS, _NO_LINS, coll._knolin, 0
        if mpos is not None and lins is not None:
            mp, ls = mpos, lins
            if coll._any_moving:
                lin, dl = ls[0], coll._kdhdt
        return mp, ls if dl else _NO_LINS, lin, dl

    def _run_whole(self, t: float, q: np.ndarray, v0: np.ndarray, e: np.ndarray, decay: float, prev: np.ndarray,
                   mpos: np.ndarray | None, lins: np.ndarray | None, command: bool) -> tuple | None:
        """The points after ``t`` in one compiled call (:meth:`_whole_kernel`: ``_rollout_jit.closed_loop_points``).

        From ``q`` with the joint velocity ``v0`` and the tracking error ``e`` (decaying by ``decay`` per point);
        ``command``: the joint velocity is the command itself (the velocity level: no error). ``mpos``/``lins``:
        each point's obstacle places and mocap velocities (``None``: no moving obstacle).
        Returns ``(kernel context, blocks, gradients, rows, keys, res, commands, velocities)``; ``None`` after a
        point whose witness points coincide (the general loop's case): ``q``, ``e`` and the controller's state as
        before the call (the kernel's only change to the controller is the rate limit's last command: ``prev``).
        """
        coll, n = self.coll, self.n
        c = self._context()
        blk, g, rows = coll._point_outputs(c, n)
        keys = np.empty((n, c[7]), dtype=np.int64)
        nq = v0.size
        outs, res, q0, e0 = np.empty((n, nq)), np.empty((n, 6)), q.copy(), e.copy()
        vs = outs if command else np.empty((n, nq))
        done = self._whole(*self._whole_args(t, q, v0, e, decay, mpos, lins, c, outs, vs, blk, rows, keys, res))
        if done < n or res[n - 1, 4]:  # (touching witness points)
            self.nominal._rate.prev[:] = prev
            q[:], e[:] = q0, e0
            return None
        return c, blk, g, rows, keys, res, outs, vs


class NominalRollout(ScratchRollout):
    """``rollout(t, data) -> [(s, lie, u_nom), ...]``: the nominal rolled forward on its own scratch ``MjData``.

    Arguments as :class:`ScratchRollout` (``points`` defaults to :data:`MAX_POINTS`).
    """

    def __init__(self, scene: Scene, nominal: Any, coll: CollisionBarriers, joints: JointLimitBarriers,
                 control_period: float, time_offset: float, horizon: float, points: int = MAX_POINTS) -> None:
        super().__init__(scene, nominal, coll, joints, control_period, time_offset, horizon, points)
        self._s = tuple((j + 1) * self.dt for j in range(self.n))  # (the points' times ahead, as the loop makes them)
        self._whole = self._whole_kernel()  # (with no tracking error: the velocity is the command)
        self._team = TeamPoints.of(self) if self._whole is None else None  # (a team's nominal: every arm's command)
        self._no_error = np.zeros(self._qadr.size)  # (stays 0: 0 * decay 0)
        self._qpos = self._data.qpos  # (a view of the scratch data: the kernel writes through it)
        qa = self._qadr
        contiguous = qa.size and bool((np.diff(qa) == 1).all())
        self._qsel = slice(int(qa[0]), int(qa[0]) + qa.size) if contiguous else qa  # (a slice: a cheaper copy)
        self._kn: tuple = (None, None, ())
        self._fused = predict_kernel() if self._whole is not None else None  # (points and Xi_on in one call)
        self._scratch: tuple | None = None  # (the one call's outputs, made once: see prediction)
        self._xbind: tuple = (None, 0, 0)  # (the episode's data, its address and site_xpos address)

    def _rows(self, data: mujoco.MjData, lin: np.ndarray | None) -> LieData:
        """The filter's rows at the state in ``data`` (kinematics done), ``lin``: the mocap velocities or ``None``."""
        return self.coll.lie_rows(data, self.joints, lin)[0]  # (lie(rows(...)) in one pass, as the simulation's rows)

    def _compiled(self, t: float, q: np.ndarray, u: np.ndarray,
                  first: np.ndarray) -> Sequence[tuple[float, LieData, np.ndarray]] | None:
        """Every point in one compiled call (``_rollout_jit.closed_loop_points``, no tracking error): the loop's.

        Taken while :meth:`_steady`. ``None``: the general loop runs
        (the controller's state as before this call, ``q`` unchanged), also after a point whose witness
        points coincide (the numpy narrow phase's case).
        """
        team = self._team
        if u.shape != q.shape or u.ndim != 1 or not (self._steady(t) if team is None else team.steady(t)):
            return None
        mpos, lins = self._tracks(t) if self.moving else (None, None)  # (each point's obstacle places, velocities)
        if team is None:
            got = self._run_whole(t, q, first, self._no_error, 0.0, u, mpos, lins, command=True)
        else:
            got = team.run(t, q, first, mpos, lins)
        if got is None:  # (the general loop from the start)
            return None
        return self._stacked(*got[:7])

    def _stacked(self, c: tuple, blk: np.ndarray, g: np.ndarray, rows: np.ndarray, keys: np.ndarray, res: np.ndarray,
                 outs: np.ndarray) -> StackedPoints:
        """The points of a compiled call's outputs (context ``c``, blocks, gradients, rows, keys, res, commands)."""
        coll, joints, n = self.coll, self.joints, self.n
        m = c[7]

        def point(j: int) -> LieData:  # (point j's Lie data, read from its block as the simulation's tick reads it)
            return coll._block_lie(c, blk[j], g[j], rows[j], int(res[j, 0]), joints)[0]

        s = self._s
        if not c[13]:  # (no gradient norms in the blocks: each point's are made from its gradients)
            return [(s[j], point(j), outs[j]) for j in range(n)]
        o_gn, o_lf = c[10], c[11]  # (the block layout _block_lie reads: h, lf and |dh/dq| at these offsets)
        k = res[:, 0].astype(np.int64)  # (each point's pairs, then the joints' rows)
        k += c[9]
        kl = k.tolist()
        pair_names, joint_names, nj = coll.pairs.names, joints.names, len(joints.names)

        def row_names(j: int, idx: list[int]) -> list[str]:  # (point j's names: its pairs', then the joints')
            cj, rj = int(res[j, 0]), rows[j]
            return [pair_names[rj[i]] if i < cj else joint_names[i - cj] if i < cj + nj else str(i) for i in idx]

        return StackedPoints._of(s, outs, k, kl, blk[:, :m], blk[:, o_lf: o_lf + m], g, blk[:, o_gn: o_gn + m], point,
                                 row_names, keys, self._key_names(pair_names, joint_names))  # (its layout: unchecked)

    def prediction(self, t: float, x: Any, alpha: ClassK, d_bar: float) -> Prediction | None:
        """``predict(self(t, x), alpha, d_bar)`` with the command now, the points and their ``Xi_on`` in one call.

        The off trigger's question (:class:`~isf_robot.core.intermittent.OffPredictor`), in
        ``_rollout_jit.closed_loop_predict``: the reaching controller's command at ``t`` (its compiled kernel, as
        its call computes it while the goal stays), the points of :meth:`_compiled` and
        :func:`~isf_robot.core.robust.predict_pass` over them, into outputs kept on the rollout (no points are
        handed out, so nothing keeps them) and a copy of the controller's buffer (the controller is not called:
        nothing to put back). ``None`` (the caller rolls out and predicts): without the compiled kernels, for a
        class-K function other than :class:`~isf_robot.core.Linear`, before the controller's first command, when
        the goal could change from ``t`` to the horizon (:meth:`GoalSequence.steady`, from ``t`` itself: the
        controller's update at ``t`` included), where :meth:`_compiled` would not run, and after a point whose
        witness points coincide; the controller and the episode as before.
        """
        if self._fused is None or type(alpha) is not Linear:
            return None
        nom = self.nominal
        c = self._context()
        self._load(x)
        if not c[13] or not self._steady(t, t):  # (the goal steady from t itself: the command at t is computed too)
            return None
        sc = self._scratch
        if sc is None:
            sc = self._scratch = self._outputs(c)
        q, u, nb, rpx, outs, blk, g, rows, keys, res, k, xi, fails, nfail, seen, out = sc
        xb = self._xbind
        if xb[0] is not x:  # (the episode's data: its address and site_xpos', kept)
            xb = self._xbind = (x, int(x._address), x.site_xpos.ctypes.data)
        mpos, lins = self._tracks(t) if self.moving else (None, None)  # (each point's obstacle places, velocities)
        done, bad, xi_lo, found = self._fused(  # (q from the scratch data, nb a copy of the controller's buffer)
            *self._whole_args(t, q, u, self._no_error, 0.0, mpos, lins, c, outs, outs, blk, rows, keys, res, nb),
            nom._buf, xb[1], xb[2], rpx, g, c[9], c[11], c[10], cast(Linear, alpha).gain, float(d_bar), k, xi, fails,
            nfail, seen, out)
        if done < 0:  # (touching witness points: the general loop's case)
            return None
        self.calls += 1
        return pass_prediction(self._s, k, xi, fails, bad, xi_lo, nfail, found, out,
                               self._key_names(self.coll.pairs.names, self.joints.names))

    def _outputs(self, c: tuple) -> tuple:
        """The outputs of :meth:`prediction`'s call for context ``c``.

        The joint positions, the command, the controller's buffer and addresses, the points' and the prediction
        pass's arrays.
        """
        n, nq, m = self.n, self._qadr.size, c[7]
        blk, g, rows = self.coll._point_outputs(c, n)
        keys, fails = np.empty((n, m), dtype=np.int64), np.empty((n, m), dtype=np.int64)
        nk = len(self.coll.pairs.names) + len(self.joints.names)
        return (np.empty(nq), np.empty(nq), np.empty_like(self.nominal._buf), np.zeros(2, np.int64), np.empty((n, nq)),
                blk, g, rows, keys, np.empty((n, 6)), np.empty(n, np.int64), np.empty((n, m)), fails,
                np.empty(n, np.int64), np.zeros(nk, np.bool_), np.empty(n * m, np.int64))

    def _tracks(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The moving obstacles' places (n, p, 3) and every mocap body's velocity (n, nmocap * 3) at the points' times.

        The times ``t + s + offset`` of the loop's points (:func:`obstacle_tracks`).
        """
        mpos, lins = obstacle_tracks(self.scene, [t + s + self.offset for s in self._s])
        return mpos, lins.reshape(len(self._s), self._nmocap * 3)

    def _key_names(self, pairs: tuple[str, ...], joints: tuple[str, ...]) -> tuple[str, ...]:
        """The names of the rows' keys (the pairs', then the joints'), kept while those names are the same objects."""
        kn = self._kn
        if kn[0] is not pairs or kn[1] is not joints:
            kn = self._kn = (pairs, joints, (*pairs, *joints))
        return kn[2]

    def __call__(self, t: float, x: Any,
                 first: np.ndarray | None = None) -> Sequence[tuple[float, LieData, np.ndarray]]:
        """Predicted points ``t + s``, ``s = dt, 2 dt, ..., n dt``, from the state in ``x`` (the episode's MjData).

        ``first``: the command over the first Euler step ``[t, t + dt]`` instead of the nominal's (a
        candidate maneuver's, :mod:`isf_robot.core.shooting`); the nominal takes over from ``t + dt``.
        """
        m, d, scene = self.scene.model, self._load(x), self.scene
        q = x.qpos[self._qsel].copy()
        saved = self.nominal.snapshot()
        out: list[tuple[float, LieData, np.ndarray]] = []
        self.calls += 1
        step, (ma, da), qpos, qadr, dt = self._step, self._addr, self._qpos, self._qadr, self.dt
        try:
            u = np.array(self.nominal(t, x), dtype=float)  # the command now (the controller's next call)
            if first is not None:
                first = np.array(first, dtype=float)
                if first.shape != u.shape:
                    raise ConfigError(f"rollout: the first command has shape {first.shape}, the nominal's {u.shape}")
            if self._whole is not None or self._team is not None:
                pts = self._compiled(t, q, u, u if first is None else first)
                if pts is not None:
                    return pts
            if first is not None:
                u = first
            for j in range(1, self.n + 1):
                s = j * dt
                lin = None
                if self.moving:  # (the obstacles' place first: the kinematics below read it)
                    scene.set_moving_obstacles(d, t + s + self.offset)
                    lin = scene.mocap_velocities(t + s + self.offset)[0]
                if step is not None and u.shape == q.shape and u.ndim == 1:
                    step(ma, da, q, u, dt, qpos, qadr)  # q + dt u into qpos, then the kinematics, in one call
                else:
                    q = q + dt * u
                    d.qpos[qadr] = q
                    mujoco.mj_kinematics(m, d)
                    mujoco.mj_comPos(m, d)
                u = np.array(self.nominal(t + s, d), dtype=float)
                out.append((s, self._rows(d, lin), u))
        finally:
            self.nominal.restore(saved)
        return out
