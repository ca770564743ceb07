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
distance are needed (the central differences of the tick's rows are not repeated at every point). A pair
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
scratch ``MjData``; the filter runs a rollout at most once every ``predict_every`` control steps, and
only while it is on with every ``Xi_on`` above the margin.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from isf_robot.core import ConfigError, LieData

from .collision import CollisionBarriers
from .joint_limits import JointLimitBarriers
from .scene import Scene

__all__ = ["TorqueRollout"]


class TorqueRollout:
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
        if not (math.isfinite(horizon) and horizon > 0):
            raise ConfigError(f"rollout horizon must be > 0 [s], got {horizon}")
        if not (math.isfinite(control_period) and control_period > 0):
            raise ConfigError(f"rollout control period must be > 0 [s], got {control_period}")
        if points is None:
            points = max(1, int(math.ceil(float(horizon) / float(control_period) - 1e-9)))
        if int(points) != points or points < 1:
            raise ConfigError(f"rollout points must be a whole number >= 1, got {points}")
        for name, v in (("kd", kd), ("alpha_1", alpha_1)):
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"torque rollout {name} must be a positive number [1/s], got {v}")
        if not (callable(getattr(nominal, "snapshot", None)) and callable(getattr(nominal, "restore", None))):
            raise ConfigError("the predictive off trigger needs a nominal controller with snapshot() and restore()")
        self.scene, self.nominal, self.coll, self.joints = scene, nominal, coll, joints
        self.offset, self.horizon, self.alpha_1 = float(time_offset), float(horizon), float(alpha_1)
        self.dt = max(float(control_period), float(horizon) / int(points))
        self.n = max(1, int(math.ceil(float(horizon) / self.dt - 1e-9)))
        self.decay = math.exp(-float(kd) * self.dt)
        self.moving = len(scene.config.moving) > 0
        self.approaching = bool(approaching)
        self._data = mujoco.MjData(scene.model)
        self._qadr = np.asarray(scene.qpos_adr, dtype=np.int64)
        self._dofs = np.asarray(scene.dof_adr, dtype=np.int64)
        self._kc = coll.pairs.k
        self._joint_keys = self._kc + np.arange(len(joints.names), dtype=np.int64)
        self._names = np.array([*coll.pairs.names, *joints.names], dtype=object)  # (a row's name by its key)
        self._at = np.full(self._names.size, -1, dtype=np.int64)  # (key -> its row at the next point; -1: absent)
        self._u0 = np.zeros(self._dofs.size)
        self.calls = 0

    def _psi(self, v: np.ndarray, lin: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(keys, psi, |J|)`` of every row at the state in the scratch data with joint velocities ``v``.

        Keys: a near pair's index, then ``k_c + i`` for joint limit ``i`` (the same row at every point).
        """
        lie, idx = self.coll.lie_rows(self._data, self.joints, lin)[:2]
        keys = np.concatenate((np.asarray(idx, dtype=np.int64), self._joint_keys))
        dhdt = -np.abs(lie.lf) if self.approaching else lie.lf
        psi = lie.lg @ v + dhdt + self.alpha_1 * lie.h
        return keys, psi, np.array(lie.grad_norm, dtype=float)

    def __call__(self, t: float, x: Any,
                 first: np.ndarray | None = None) -> Sequence[tuple[float, LieData, np.ndarray]]:
        """Points ``s = 0, dt, ..., (n - 1) dt`` ahead of ``t`` from the state in ``x`` (the episode's MjData)."""
        if first is not None:
            raise ConfigError("maneuvers by shooting are not available at the torque level (give shoot = 0)")
        if not isinstance(x, mujoco.MjData):
            raise ConfigError("TorqueRollout needs the episode's MjData as the state x of step_lie")
        m, d, scene, dt = self.scene.model, self._data, self.scene, self.dt
        d.qpos[:] = x.qpos
        if m.nmocap:
            d.mocap_pos[:] = x.mocap_pos
            d.mocap_quat[:] = x.mocap_quat
        q = x.qpos[self._qadr].copy()
        q_dot = x.qvel[self._dofs].copy()
        saved = self.nominal.snapshot()
        self.calls += 1
        rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        try:
            e = None
            for j in range(self.n + 1):
                s = j * dt
                lin = None
                if self.moving:
                    scene.set_moving_obstacles(d, t + s + self.offset)
                    lin = scene.mocap_velocities(t + s + self.offset)[0]
                d.qpos[self._qadr] = q
                mujoco.mj_kinematics(m, d)
                mujoco.mj_comPos(m, d)
                v_ref = np.array(self.nominal(t + s, d), dtype=float)
                e = q_dot - v_ref if e is None else e * self.decay
                v = v_ref + e
                rows.append(self._psi(v, lin))
                q = q + dt * v
        finally:
            self.nominal.restore(saved)
        out = []
        at, m = self._at, self._u0.size
        for j in range(self.n):
            (k0, p0, g0), (k1, p1, _) = rows[j], rows[j + 1]
            at[k1] = np.arange(k1.size)  # (the rows present at both points, in point j's order: ascending keys)
            nxt = at[k0]
            at[k1] = -1
            i0 = np.flatnonzero(nxt >= 0)
            i1 = nxt[i0]
            h0 = p0[i0]
            lie = LieData._of(h0, (p1[i1] - h0) / dt, np.zeros((i0.size, m)), g0[i0],
                              tuple(self._names[k0[i0]].tolist()))
            out.append((j * dt, lie, self._u0))
        return out
