"""The torque nominal's closed loop rolled forward, for the torque level's predictive off trigger.

At the torque level the filter's rows are ``psi = h_dot + alpha_1 h`` (:mod:`isf_robot.arm.second_order`)
and ``Xi_on`` of a row is ``psi_dot + alpha(psi) - |J| d_bar`` with ``psi_dot`` under the nominal torque.
The nominal (:mod:`isf_robot.arm.torque_nominal`) is computed torque on the filter's model, so, within
the torque limits and without disturbance, its closed loop is::

    q_ddot = v_ref_dot + kd (v_ref - q_dot)      i.e.   e = q_dot - v_ref  decays as  e(s) = e(0) exp(-kd s)

with ``v_ref(t, q)`` the velocity level's reaching command. :class:`TorqueRollout` integrates it from
the episode's state (``q_{j+1} = q_j + dt (v_ref,j + e_j)``, ``e_{j+1} = e_j exp(-kd dt)``: the error's decay
is exact at any step), computes every row's ``psi`` at each predicted state from the velocity level's
rows there (``psi = J q_dot + dh/dt + alpha_1 h``, :meth:`~isf_robot.arm.collision.CollisionBarriers.lie_rows`)
and hands the core, per point ``s_j``, the rows present at both ``s_j`` and ``s_j + dt`` with

    h = psi_j,   Lf = (psi_{j+1} - psi_j) / dt,   Lg = 0

so that the core's ``Xi_on`` (:func:`~isf_robot.core.robust.robust_slack`) at the point is the rate of
``psi`` along the nominal's own motion, plus ``alpha(psi) - |J| d_bar``: no second derivatives of the
distance are needed (the difference of the tick's rows is not repeated at every point). A pair
entering or leaving the broad-phase cut-off between two points has no rate there (its ``psi`` jumps from
the far value ``alpha_1 (cutoff - margin)`` by its approach speed): it counts from the next point on.
With ``approaching`` the moving obstacles' part of ``phi`` is ``-|dh/dt|``, as in the filter's rows
(:class:`~isf_robot.arm.second_order.SecondOrderRows`).

The step is the control period (``horizon / T`` points, 130 on the shipped scenes): the forward difference
is the rate of ``psi`` over ``dt``, and ``Xi_on`` at ``s_j`` pairs it with ``psi`` at the start of the step, so a
coarse step reads a falling ``psi`` late. With the velocity level's ``horizon / 10`` (26 ms), on panda_shelf
(seeds 0-2, 8 s) the predicted ``Xi_on`` at the off switches was above the tick's own by 0.10 on average (at
most 0.43); with one point per control period by 0.03 (at most 0.33), and fewer off periods end early
(``RESULTS.md``, "Torque level").

Cost per rollout: ``points + 1`` evaluations of the reaching command, the kinematics and the rows on a
scratch ``MjData``. With numba, while the goal cannot change over the horizon and the nominal is the
:class:`~isf_robot.arm.nominal.ReachingController` with its compiled command, every point after the first is
one compiled call (``_rollout_jit.closed_loop_points``: the obstacles' places, the Euler step, the kinematics, the
controller's kernel, the error's decay, the collision kernel), as the velocity level's
:class:`~isf_robot.arm.rollout.NominalRollout` does; otherwise each point's Euler step and kinematics are one
call and its rows :meth:`~isf_robot.arm.collision.CollisionBarriers.lie_rows`. The rows' ``psi`` go in a table
(point, row key): the compiled points' by one more compiled call (``_second_order_jit.psi_points``), the others'
by a few array operations, with the formulas of :mod:`isf_robot.arm.psi_law` either way; the pairing of
consecutive points is a few array operations over all points (flat indices), and the points go to the core
stacked (:class:`~isf_robot.core.intermittent.StackedPoints`: one pass of ``predict``). The paths agree to
rounding (``tests/arm/test_torque_rollout.py``). Measured on panda_pole from its home state (130 points, a
shared 2-core machine, 2026-11-28): rollout and ``predict`` 1.6 ms (2.35 ms with numpy gathers of the compiled
points' rows; 8.5 ms point by point with a list of points). The filter runs a rollout at most once every
``predict_every`` control steps, and only while it is on with every ``Xi_on`` above the margin.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from isf_robot.core import ConfigError, LieData
from isf_robot.core.intermittent import StackedPoints
from isf_robot.core.jit import compiled

from . import kernels
from .collision import CollisionBarriers
from .joint_limits import JointLimitBarriers
from .psi_law import obstacle_rate, psi_value
from .rollout import ScratchRollout, obstacle_tracks
from .scene import Scene

__all__ = ["TorqueRollout", "pack_points"]


class TorqueRollout(ScratchRollout):
    """``rollout(t, data) -> [(s, lie, u), ...]``: the torque nominal's closed loop, as ``psi`` rows (module docstring).

    Args:
        scene: The scene (the filter's model).
        nominal: The velocity-level reaching controller the torque nominal tracks (with ``snapshot()`` and
            ``restore()``: put back after each rollout).
        coll: The collision barriers.
        joints: The joint-limit barriers.
        control_period: The control period [s].
        time_offset: The episode's time offset [s] (the moving obstacles' clock).
        horizon: Prediction horizon [s], > 0.
        kd: The torque nominal's velocity gain [1/s], > 0.
        alpha_1: The inner gain of ``psi`` [1/s], > 0.
        points: Largest number of predicted points; the step is ``max(control period, horizon / points)``;
            ``None`` (default): one point per control period (module docstring).
        approaching: The rows' ``phi = J q_dot - |dh/dt|`` (the filter's rows at the torque level); default ``h_dot``.

    """

    def __init__(self, scene: Scene, nominal: Any, coll: CollisionBarriers, joints: JointLimitBarriers,
                 control_period: float, time_offset: float, horizon: float, kd: float, alpha_1: float,
                 points: int | None = None, approaching: bool = False) -> None:
        if not (math.isfinite(control_period) and control_period > 0):
            raise ConfigError(f"rollout control period must be > 0 [s], got {control_period}")
        for name, v in (("kd", kd), ("alpha_1", alpha_1)):
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"torque rollout {name} must be a positive number [1/s], got {v}")
        if points is None:  # (one per control period; a horizon that is not a positive number: the base says so)
            ok = math.isfinite(horizon) and horizon > 0
            points = max(1, int(math.ceil(float(horizon) / float(control_period) - 1e-9))) if ok else 1
        super().__init__(scene, nominal, coll, joints, control_period, time_offset, horizon, points)
        self._whole = self._whole_kernel()
        ks = kernels.second_order_kernels()
        self._psi_points = ks[2] if ks is not None else None  # (the psi of the whole kernel's points)
        self.alpha_1 = float(alpha_1)
        self.decay = math.exp(-float(kd) * self.dt)
        self.approaching = bool(approaching)
        self._dofs = np.asarray(scene.dof_adr, dtype=np.int64)
        self._joint_keys = coll.pairs.k + np.arange(len(joints.names), dtype=np.int64)
        self._names = np.array([*coll.pairs.names, *joints.names], dtype=object)  # (a row's name by its key)
        self._key_names = tuple(self._names.tolist())
        self._s = [j * self.dt for j in range(self.n)]  # (the points' times ahead)
        self._zeros: tuple = (np.zeros((0, 0, 0)),)  # (Lg and u of every point: zero blocks, made once per size)
        self._pack = compiled(pack_points)  # (ISF_ROBOT_JIT is read here)

    def __call__(self, t: float, x: Any,
                 first: np.ndarray | None = None) -> Sequence[tuple[float, LieData, np.ndarray]]:
        """Points ``s = 0, dt, ..., (n - 1) dt`` ahead of ``t`` from the state in ``x`` (the episode's MjData).

        Handed over stacked (:class:`~isf_robot.core.intermittent.StackedPoints`: ``predict`` reads every point in
        one pass; a point's :class:`LieData` is made only when asked for, its ``Lg`` a read-only zero block).
        """
        if first is not None:
            raise ConfigError("maneuvers by shooting are not available at the torque level (give shoot = 0)")
        m, d, dt, n, K = self.scene.model, self._load(x), self.dt, self.n, self._names.size
        q = x.qpos[self._qadr]  # (index arrays: copies already)
        q_dot = x.qvel[self._dofs]
        if self.moving:  # (the obstacles' places and velocities at every point's time, in one pass)
            mpos, lins = obstacle_tracks(self.scene, [t + j * dt + self.offset for j in range(n + 1)])
        coll, joints, jk, step, qpos = self.coll, self.joints, self._joint_keys, self._step, d.qpos
        keys: list[np.ndarray] = []  # (per point made here, as lgv, lf, h, gn; put in the tables after the loop)
        lgv: list[np.ndarray] = []
        lf: list[np.ndarray] = []
        h: list[np.ndarray] = []
        gn: list[np.ndarray] = []
        psi, g, present = np.empty((n + 1, K)), np.empty((n + 1, K)), np.zeros((n + 1, K), dtype=bool)
        saved = self.nominal.snapshot()
        self.calls += 1
        try:
            e: np.ndarray | None = None
            v = q_dot  # (the velocity at the point; made at point 0 before its first use)
            for j in range(n + 1):
                lin = None
                if self.moving:  # (the obstacles' place first: the kinematics below read it)
                    d.mocap_pos[self._mids] = mpos[j]
                    lin = lins[j]
                if j and step is not None:
                    step(*self._addr, q, v, dt, qpos, self._qadr)  # (q + dt v into qpos, then the kinematics)
                else:
                    if j:
                        q = q + dt * v
                    d.qpos[self._qadr] = q
                    mujoco.mj_kinematics(m, d)
                    mujoco.mj_comPos(m, d)
                v_ref = np.array(self.nominal(t + j * dt, d), dtype=float)
                e = q_dot - v_ref if e is None else e * self.decay
                v = v_ref + e
                lie, idx = coll.lie_rows(d, joints, lin)[:2]
                keys += (idx, jk)  # (a near pair's index, then k_c + i for joint limit i)
                lgv.append(lie.lg @ v)
                lf.append(lie.lf)
                h.append(lie.h)
                gn.append(lie.grad_norm)
                if j == 0 and self._whole is not None and self._psi_points is not None and self._compiled(
                        t, q, v, e, v_ref, mpos if self.moving else None, lins if self.moving else None, psi, g,
                        present):  # (the other points in one compiled call, when it can)
                    break
        finally:
            self.nominal.restore(saved)
        rows = np.array([a.size for a in lgv])  # (the points made here)
        where = (np.repeat(np.arange(rows.size), rows), np.concatenate(keys))
        phi = np.concatenate(lgv) + obstacle_rate(np.concatenate(lf), self.approaching)
        psi[where], g[where], present[where] = psi_value(phi, np.concatenate(h), self.alpha_1), np.concatenate(gn), True
        return self._points(psi, g, present)

    def _compiled(self, t: float, q: np.ndarray, v: np.ndarray, e: np.ndarray, v_ref: np.ndarray,
                  mpos: np.ndarray | None, lins: np.ndarray | None, psi: np.ndarray, gn: np.ndarray,
                  present: np.ndarray) -> bool:
        """Points ``1 .. n`` in compiled calls (``_rollout_jit.closed_loop_points``, ``_second_order_jit.psi_points``).

        Taken after point 0 (``q``, ``v``, ``e`` and the command ``v_ref`` there) while :meth:`_steady`, as
        :meth:`NominalRollout._compiled <isf_robot.arm.rollout.NominalRollout._compiled>`. Fills rows ``1 .. n`` of
        the tables ``psi``, ``gn`` (``|J|``: the collision kernel's, which it computes with joint rows) and
        ``present``; ``False``: the loop goes on (``q``, ``e`` and the controller's state as before this call), also
        after a point whose witness points coincide.
        """
        n = self.n
        if not self._steady(t):
            return False
        moving = mpos is not None and lins is not None
        got = self._run_whole(t, q, v, e, self.decay, v_ref, np.ascontiguousarray(mpos[1:]) if moving else None,
                              lins[1:].reshape(n, -1) if moving else None, command=False)
        if got is None:  # (the loop from point 1)
            return False
        c, blk, _, _, keys, res, _, vs = got
        self._psi_points(blk, keys, res, vs, len(self.joints.names), c[7], c[8], c[10], c[11], self.alpha_1,
                         self.approaching, psi, gn, present)
        return True

    def _points(self, psi: np.ndarray, gn: np.ndarray, present: np.ndarray) -> StackedPoints:
        """Per point ``j < n`` the rows present at ``j`` and ``j + 1`` (ascending keys): ``h = psi_j``, the rate."""
        n, K, dt, mu = self.n, self._names.size, self.dt, self._dofs.size
        h, lf, g, keys = np.zeros((n, K)), np.zeros((n, K)), np.zeros((n, K)), np.zeros((n, K), dtype=np.int64)
        rows = np.empty(n, dtype=np.int64)
        self._pack(psi, gn, present, dt, h, lf, g, keys, rows)
        if self._zeros[0].shape != (n, K, mu):
            lg0, u0 = np.zeros((n, K, mu)), np.zeros((n, mu))
            ro = lg0.view()
            ro.flags.writeable = False  # (the points' Lg: views that cannot write into the block)
            self._zeros = (lg0, u0, ro)
        lg0, u0, ro = self._zeros
        kl = rows.tolist()
        names = self._names

        def point(j: int) -> LieData:
            k = kl[j]
            return LieData._of(h[j, :k], lf[j, :k], ro[j, :k], g[j, :k], tuple(names[keys[j, :k]].tolist()))

        return StackedPoints._of(self._s, u0, rows, kl, h, lf, lg0, g, point, None, keys, self._key_names)


def pack_points(psi: np.ndarray, gn: np.ndarray, present: np.ndarray, dt: float, h: np.ndarray, lf: np.ndarray,
                g: np.ndarray, keys: np.ndarray, rows: np.ndarray) -> None:
    """Per point ``j < n`` the rows present at ``j`` and ``j + 1``, ascending keys, packed to the front of row ``j``.

    From the ``(n + 1, K)`` tables ``psi``, ``gn`` (``|J|``) and ``present`` of :meth:`TorqueRollout.__call__`: into
    the ``(n, K)`` tables (zeros beyond each point's rows), ``h = psi_j``, ``lf = (psi_{j+1} - psi_j) / dt``,
    ``g = gn_j`` and the row's key; ``rows[j]`` the count. A plain function of loops, compiled by
    :func:`~isf_robot.core.jit.compiled` (one call instead of a dozen numpy passes per rollout).
    """
    n, K = h.shape
    for j in range(n):
        c = 0
        for key in range(K):
            if present[j, key] and present[j + 1, key]:
                h0 = psi[j, key]
                h[j, c] = h0
                lf[j, c] = (psi[j + 1, key] - h0) / dt
                g[j, c] = gn[j, key]
                keys[j, c] = key
                c += 1
        rows[j] = c
