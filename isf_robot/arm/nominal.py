"""Nominal controllers: the task the safety filter protects.

Both controllers output a commanded joint velocity ``u_nom`` (shape (n,), [rad/s]) for the
reduced-order model ``q_dot = u + d`` (the paper's ``x_dot = f(x, u) + d``, Section II, with ``x = q`` and
``f(x, u) = u``). They read the current state from ``MjData`` and need its kinematics up to date
(``mj_step1`` / ``mj_kinematics`` done).

* :class:`ReachingController`: task-space reaching through a sequence of end-effector goals,
  ``v = kp (p_goal - p_ee)`` (speed capped at ``max_ee_speed``), mapped to joint space with the
  damped least-squares inverse ``u = J^T (J J^T + lambda^2 I)^-1 v`` (J: the ee site's
  translational Jacobian restricted to the arm joints, shape (3, n)).
* :class:`JointPDController`: joint-space proportional control through a sequence of joint
  targets, ``u = kp (q_goal - q)``.

Both cap the joint speeds by scaling the whole command (direction kept), limit its rate of
change (``max_joint_acc``: a real task does not ask for velocity steps), count goals
reached, hold each goal for its dwell time and then move to the next (looping if asked). The
formulas are those of :mod:`isf_robot.arm.reaching_law`, which the compiled command calls too.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, ShapeError
from isf_robot.core.jit import direct

from . import kernels
from .goals import GoalSequence
from .reaching_law import cap_speed, ee_distance, rate_limit, reaching_command
from .scene import Scene

__all__ = ["NominalController", "GoalSequence", "ReachingController", "JointPDController"]


class NominalController(ABC):
    """A nominal joint-velocity controller ``u_nom = k_nom(t, q)``.

    Attributes:
        n: Number of arm joints (the command's length).
        goals: The goal bookkeeping (``goals.index``, ``goals.reached``).

    """

    n: int
    goals: GoalSequence

    @property
    def goal_index(self) -> int:
        """Index of the goal being pursued."""
        return self.goals.index

    @property
    def goals_reached(self) -> int:
        """Number of goal arrivals so far."""
        return self.goals.reached

    @property
    def goals_missed(self) -> int:
        """Number of goals given up after the timeout."""
        return self.goals.missed

    @property
    def goal_times(self) -> tuple[float, ...]:
        """Time [s] of every goal arrival so far, in order (``len == goals_reached``)."""
        return self.goals.arrivals

    _rate: _RateLimit

    def reset(self) -> None:
        """Start the task again (first goal, nothing reached, command at rest)."""
        self.goals.reset()
        self._rate.reset()

    def snapshot(self) -> Any:
        """The controller's state (goal bookkeeping, rate limit) for :meth:`restore`.

        A rollout (:class:`~isf_robot.arm.rollout.NominalRollout`) calls the controller at
        predicted states and puts it back as it was.
        """
        return dict(vars(self.goals)), self._rate.prev.copy(), self._rate.t_prev

    def restore(self, state: Any) -> None:
        """Return to a state taken by :meth:`snapshot`."""
        goals, prev, t_prev = state
        vars(self.goals).update(goals)
        self._rate.prev[:] = prev
        self._rate.t_prev = t_prev

    @abstractmethod
    def __call__(self, t: float, data: mujoco.MjData) -> np.ndarray:
        """The nominal command at time ``t`` [s]; shape (n,) [rad/s], a fresh array.

        Fresh, not a buffer the controller writes again: a step keeps its nominal command while the
        intermittent filter's rollout calls the controller at predicted states.
        """


class _RateLimit:
    """Limits the change of a command between calls: ``|u_k - u_{k-1}| <= a_max (t_k - t_{k-1})``.

    The whole change is scaled (its direction kept). ``a_max = inf`` disables it.
    """

    def __init__(self, n: int, a_max: float, prev: np.ndarray | None = None) -> None:
        if not a_max > 0:
            raise ConfigError(f"max_joint_acc must be > 0 [rad/s^2], got {a_max}")
        self.a_max = float(a_max)
        self.prev = np.zeros(n) if prev is None else prev  # (prev: a caller's buffer, shape (n,), zeros)
        self.t_prev: float | None = None

    def reset(self) -> None:
        self.prev[:] = 0.0
        self.t_prev = None

    def __call__(self, t: float, u: np.ndarray) -> np.ndarray:
        """``u`` limited (:func:`~isf_robot.arm.reaching_law.rate_limit`, in place)."""
        t_prev = self.t_prev
        rate_limit(u, self.prev, t_prev is not None, 0.0 if t_prev is None else t - t_prev, self.a_max)
        self.t_prev = t
        return u


def _max_acc(scene: Scene, value: float | None) -> float:
    if value is not None:
        return float(value)
    return float(scene.config.gains.max_joint_acc)


class ReachingController(NominalController):
    """Task-space reaching by damped least squares through a sequence of ee goals.

    Args:
        scene: The scene (arm joints, ee site, default goals and gains).
        goals: Goal positions [m], shape (g, 3); default the scene's.
        dwell: Dwell per goal [s], shape (g,); default the scene's.
        kp: Task-space gain [1/s]; default ``[gains] task_kp``.
        damping: DLS damping lambda [m]; default ``[gains] dls_damping``.
        max_ee_speed: Cap on the commanded ee speed [m/s].
        max_joint_speed: Cap on the joint speeds [rad/s] (the command is scaled as a whole).
        tolerance: Goal tolerance [m]; default ``[task] tolerance``.
        loop: Loop over the goals; default ``[task] loop``.
        max_joint_acc: Limit on the change of the command [rad/s^2] (the whole change is
            scaled; the first command is zero: the arm starts at rest); default
            ``[gains] max_joint_acc`` or 10. ``inf`` disables it.
        timeout: Give up a goal not reached within this time [s]; default
            ``[gains] goal_timeout`` or 4 s.
        jit: Use the compiled command of :mod:`isf_robot.arm.kernels` when it is available (an
            ee site, contiguous dofs; ``False``: numpy). The same formulas either way.

    """

    def __init__(
        self,
        scene: Scene,
        goals: np.ndarray | None = None,
        dwell: Sequence[float] | np.ndarray | None = None,
        *,
        kp: float | None = None,
        damping: float | None = None,
        max_ee_speed: float | None = None,
        max_joint_speed: float | None = None,
        tolerance: float | None = None,
        loop: bool | None = None,
        max_joint_acc: float | None = None,
        timeout: float | None = None,
        jit: bool = True,
    ) -> None:
        if scene.arms:
            raise ConfigError(f"scene {scene.name!r} has {len(scene.arms)} arms: its nominal task is every arm's "
                              "(isf_robot.arm.team_nominal.TeamReaching; run it with isf_robot.arm.multi_arm, or "
                              "`isf-robot run`/`compare`/`render`)")
        gains, task = scene.config.gains, scene.config.task
        self.scene = scene
        self.n = scene.n_joints
        g = np.array(scene.goal_positions if goals is None else goals, dtype=float)
        if g.ndim != 2 or g.shape[1] != 3 or g.shape[0] < 1:
            raise ShapeError(f"goals must have shape (g, 3) with g >= 1, got {g.shape}")
        self.goal_positions = g
        dw = scene.goal_dwell if dwell is None else dwell
        if dwell is None and g.shape[0] != scene.goal_dwell.shape[0]:
            dw = np.zeros(g.shape[0])
        if timeout is None:
            timeout = gains.goal_timeout
        self.goals = GoalSequence(g.shape[0], dw, task.tolerance if tolerance is None else tolerance,
                                  task.loop if loop is None else loop, timeout)
        self.kp = float(gains.task_kp if kp is None else kp)
        self.damping = float(gains.dls_damping if damping is None else damping)
        self.max_ee_speed = float(gains.max_ee_speed if max_ee_speed is None else max_ee_speed)
        self.max_joint_speed = float(gains.max_joint_speed if max_joint_speed is None
                                     else max_joint_speed)
        for label, v in (("kp", self.kp), ("max_ee_speed", self.max_ee_speed),
                         ("max_joint_speed", self.max_joint_speed)):
            if not v > 0:
                raise ConfigError(f"ReachingController {label} must be > 0, got {v}")
        if not self.damping > 0:
            raise ConfigError(f"ReachingController damping must be > 0 [m], got {self.damping}")
        self._jac = np.zeros((3, scene.model.nv))
        dofs = np.asarray(scene.dof_adr)
        contiguous = dofs.size and np.array_equal(dofs, np.arange(dofs[0], dofs[0] + dofs.size))
        self._dofs = slice(int(dofs[0]), int(dofs[0]) + dofs.size) if contiguous else dofs
        # The compiled command (isf_robot.arm.kernels.step_kernels: the same formulas) works in one
        # buffer: the rate limit's previous command, a copy of it, the Jacobian (3, nv) and scratch.
        model, n, nv = scene.model, self.n, int(scene.model.nv)
        self._buf = np.zeros(2 * n + 3 * nv + 3)
        self._rate = _RateLimit(n, _max_acc(scene, max_joint_acc), prev=self._buf[:n])
        self._lam2 = self.damping ** 2
        use = contiguous and scene.ee_site_id >= 0 and getattr(model, "_address", 0) and jit
        k = kernels.step_kernels(n) if use else None
        self._reach = k["reach"] if k is not None else None
        self._reach_direct: tuple = (None, None)  # (the kernel, its code for the call's argument types)
        self._maddr, self._daddr = int(getattr(model, "_address", 0)), 0
        self._nv = nv
        self._data: mujoco.MjData | None = None
        self._binds: dict[int, tuple[mujoco.MjData, int, int]] = {}  # (id -> the data, its address, site_xpos')
        self._goals_seen: np.ndarray | None = None
        self._ptrs = np.zeros(2, dtype=np.int64)  # addresses: the goal positions, data.site_xpos
        self._dof0 = int(dofs[0]) if dofs.size else 0

    def ee_position(self, data: mujoco.MjData) -> np.ndarray:
        """End-effector position [m], shape (3,) (a view into ``data``)."""
        return self.scene.ee_position(data)

    def __call__(self, t: float, data: mujoco.MjData) -> np.ndarray:
        """DLS command toward the current goal; shape (n,) [rad/s] (a fresh array)."""
        if self._reach is not None and self._bound(data):
            return self._compiled(t)
        index = self.goals.index
        err = self.goal_positions[index] - self.scene.ee_position(data)
        dist = ee_distance(err)
        self.goals.update(t, dist)
        if self.goals.index != index:
            err = self.goal_positions[self.goals.index] - self.scene.ee_position(data)
            dist = ee_distance(err)
        self.scene.ee_jacobian(data, self._jac)
        u = reaching_command(err, dist, self._jac[:, self._dofs].tolist(), self.kp, self.max_ee_speed, self._lam2,
                             self.max_joint_speed, np.empty(self.n))
        return self._rate(t, u)

    def _bound(self, data: mujoco.MjData) -> bool:
        """Point the compiled command at ``data`` and the goal positions; ``False``: use numpy."""
        if data is not self._data:  # (another MjData: its addresses, kept for the few a run alternates between)
            hit = self._binds.get(id(data))
            if hit is None or hit[0] is not data:
                if len(self._binds) >= 4:
                    self._binds.clear()
                hit = self._binds[id(data)] = (data, int(data._address), data.site_xpos.ctypes.data)
            self._data, self._daddr = data, hit[1]
            self._ptrs[1] = hit[2]
        g = self.goal_positions
        if g is not self._goals_seen:
            ok = (type(g) is np.ndarray and g.dtype == np.float64 and g.flags.c_contiguous
                  and g.shape == (self.goals.n_goals, 3))
            self._goals_seen, self._ptrs[0] = (g, g.ctypes.data) if ok else (None, 0)
        return self._goals_seen is not None

    def _compiled(self, t: float) -> np.ndarray:
        """:meth:`__call__` by the compiled kernel (the same formulas, compiled)."""
        goals, rate, out = self.goals, self._rate, np.empty(self.n)
        index, t_prev = goals.index, rate.t_prev
        tf, tp, held = float(t), 0.0 if t_prev is None else float(t_prev), t_prev is not None  # (floats: direct code)
        rd = self._reach_direct
        if rd[0] is not self._reach:  # (its arrays are its own buffers: jit.direct)
            rd = self._reach_direct = (self._reach, direct(self._reach, (
                self._maddr, self._daddr, self._ptrs, self._buf, out, self.n, self._nv, self._dof0,
                self.scene.ee_site_id, index, False, tf, tp, held, rate.a_max, self.kp, self.max_ee_speed,
                self.max_joint_speed, self._lam2)))
        reach = rd[1]
        dist = reach(self._maddr, self._daddr, self._ptrs, self._buf, out, self.n, self._nv, self._dof0,
                     self.scene.ee_site_id, index, False, tf, tp, held, rate.a_max, self.kp, self.max_ee_speed,
                     self.max_joint_speed, self._lam2)
        goals.update(t, dist)
        if goals.index != index:  # a new goal: the command toward it (the rate limit's state put back)
            reach(self._maddr, self._daddr, self._ptrs, self._buf, out, self.n, self._nv, self._dof0,
                  self.scene.ee_site_id, goals.index, True, tf, tp, held, rate.a_max, self.kp, self.max_ee_speed,
                  self.max_joint_speed, self._lam2)
        rate.t_prev = t
        return out


class JointPDController(NominalController):
    """Joint-space proportional control through a sequence of joint targets.

    ``u = kp (q_goal - q)``, capped at ``max_joint_speed`` (scaled as a whole).

    Args:
        scene: The scene (arm joints, gains).
        targets: Joint targets [rad], shape (g, n).
        dwell: Dwell per target [s], shape (g,); default zeros.
        kp: Gain [1/s]; default ``[gains] joint_kp``.
        max_joint_speed: Cap [rad/s]; default ``[gains] max_joint_speed``.
        tolerance: Max-norm joint error [rad] below which a target counts as reached.
        loop: Loop over the targets.
        max_joint_acc: Limit on the change of the command [rad/s^2], as
            :class:`ReachingController`.

    """

    def __init__(
        self,
        scene: Scene,
        targets: np.ndarray,
        dwell: Sequence[float] | np.ndarray | None = None,
        *,
        kp: float | None = None,
        max_joint_speed: float | None = None,
        tolerance: float = 0.02,
        loop: bool = True,
        max_joint_acc: float | None = None,
    ) -> None:
        self.scene = scene
        self.n = scene.n_joints
        q = np.array(targets, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.n or q.shape[0] < 1:
            raise ShapeError(f"targets must have shape (g, {self.n}), got {np.shape(targets)}")
        self.targets = q
        self.goals = GoalSequence(q.shape[0], np.zeros(q.shape[0]) if dwell is None else dwell,
                                  tolerance, loop)
        gains = scene.config.gains
        self.kp = float(gains.joint_kp if kp is None else kp)
        self.max_joint_speed = float(gains.max_joint_speed if max_joint_speed is None
                                     else max_joint_speed)
        if not (self.kp > 0 and self.max_joint_speed > 0):
            raise ConfigError("JointPDController kp and max_joint_speed must be > 0")
        self._qadr = scene.qpos_adr
        self._rate = _RateLimit(self.n, _max_acc(scene, max_joint_acc))

    def __call__(self, t: float, data: mujoco.MjData) -> np.ndarray:
        """Proportional command toward the current target; shape (n,) [rad/s]."""
        index = self.goals.index
        err = self.targets[index] - data.qpos[self._qadr]
        self.goals.update(t, float(np.max(np.abs(err))))
        if self.goals.index != index:
            err = self.targets[self.goals.index] - data.qpos[self._qadr]
        return self._rate(t, cap_speed(self.kp * err, self.max_joint_speed))
