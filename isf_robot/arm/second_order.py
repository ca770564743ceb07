"""Second-order (exponential) barriers of the arm on its full dynamics: the torque level's rows.

For a barrier ``h(q, t)`` of the velocity level (a collision pair or a joint limit, with
``J = dh/dq`` and ``dh/dt`` from :class:`~isf_robot.arm.collision.CollisionBarriers` and
:class:`~isf_robot.arm.joint_limits.JointLimitBarriers`), state ``x = (q, q_dot)`` and the arm
torques ``tau`` as input::

    phi = h_dot   = J q_dot + dh/dt
    psi           = phi + alpha_1 h                              (the barrier the filter keeps >= 0)
    psi_dot       = D phi + J q_ddot + alpha_1 phi
    q_ddot        = a0 + Minv tau + d                            (:mod:`isf_robot.arm.dynamics`)
    Lf psi        = D phi + J a0 + alpha_1 phi
    Lg psi        = J Minv
    |dpsi/dx|     = |J|

``D phi = d/ds phi(q + s q_dot, t + s)`` at ``s = 0`` with ``q_dot`` held: ``Jdot q_dot`` plus the
terms of the obstacle's motion (``d/dt (dh/dt)`` with the obstacle's acceleration, and the
change of ``dh/dt`` with ``q``). It is the forward difference of the velocity level's own rows
between the state and ``(q + eps q_dot, t + eps)`` (:class:`SecondOrderRows`): the curvature of the distance
between two geoms (witness points that slide, normals that turn) comes with it, where
``mj_jacDot`` at fixed witness points would miss it. Joint-limit rows have ``J`` constant and
``dh/dt = 0``, so ``D phi = 0``.

Robust term: the disturbance ``d`` enters ``q_ddot`` only (the unmodelled part of the
dynamics, in [rad/s^2]), and ``dpsi/dq_dot = J``; so ``|dpsi/dx|`` restricted to the disturbed
coordinates is ``|J|`` and the robust condition reads
``Lf psi + Lg psi tau - |J| d_bar >= -alpha(psi)`` (the core's rows, unchanged).

**Moving obstacles that reverse** (``approaching=True``, the torque level's setting): a moving obstacle's
part of ``h_dot``, ``dh/dt``, jumps when its velocity reverses at once (the ``linear_bounce`` paths), and with it
``psi``: no torque answers a jump. On panda_moving a bounce dropped the hand's ``psi`` from +0.28 to -0.25 m/s
with 2.7 cm left to the margin, and the arm crossed it (``RESULTS.md``, "Torque level"). With the option the rows
use ``phi = J q_dot - |dh/dt|`` (the obstacle's part taken as approaching whichever way it moves), which a
reversal leaves continuous and which is never above ``h_dot``, so ``psi >= 0`` still keeps ``h >= 0``; for an
approaching obstacle the rows are the exact ones. Static obstacles have ``dh/dt = 0``: their rows do not change.

``psi >= 0`` for all time keeps ``h >= 0`` when ``h >= 0`` at the start (``h_dot >= -alpha_1 h``).
An arm at rest starts with ``psi = alpha_1 h``. A pair beyond the broad-phase cut-off has
``h = cutoff - margin``, ``J = 0``, so ``psi = alpha_1 (cutoff - margin)``: when it enters the
cut-off, ``psi`` drops by the pair's approach speed; the cut-off must satisfy
``alpha_1 (cutoff - margin) >`` the fastest approach speed for ``psi`` to enter positive.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from isf_robot.core import ConfigError, LieData
from isf_robot.core.exceptions import IsfWarning
from isf_robot.core.jit import direct

from . import kernels
from .collision import CollisionBarriers
from .dynamics import DynamicsTerms
from .joint_limits import JointLimitBarriers
from .psi_law import obstacle_rate, phi_difference, phi_rows, psi_rows

__all__ = ["psi_lie", "SecondOrderRows", "ObstacleClock", "PROBE_REACH"]

_F64 = np.dtype(np.float64)

PROBE_REACH = 0.05
"""How far beyond the broad-phase cut-off [m] the difference of ``phi`` still sees a pair."""

ObstacleClock = Callable[[mujoco.MjData, float], np.ndarray | None]
"""``(data, t) -> mocap linear velocities (nmocap, 3) or None``: puts the moving obstacles where they
are at time ``t`` (writes ``data.mocap_pos``) and returns their velocities (``None``: static scene)."""


def psi_lie(h: np.ndarray, grad: np.ndarray, dhdt: np.ndarray, dphi: np.ndarray, q_dot: np.ndarray,
            terms: DynamicsTerms, alpha_1: float, names: tuple[str, ...] = (),
            grad_norm: np.ndarray | None = None, phi: np.ndarray | None = None) -> LieData:
    """The Lie data of ``psi = J q_dot + dh/dt + alpha_1 h`` on the full dynamics (module docstring).

    Args:
        h: Barrier values, shape (k,).
        grad: ``J = dh/dq``, shape (k, n).
        dhdt: ``dh/dt``, shape (k,).
        dphi: ``D phi`` (the rate of ``phi`` along the motion with ``q_dot`` held), shape (k,).
        q_dot: Joint velocities [rad/s], shape (n,).
        terms: The dynamics' terms at the state.
        alpha_1: The inner gain [1/s], > 0.
        names: Row names.
        grad_norm: ``|J|`` per row when known (the velocity level's rows carry it); ``None``: computed here.
        phi: ``phi`` per row when known (:func:`phi_rows` of these rows); ``None``: computed here.

    Returns:
        ``LieData(h=psi, lf=Lf psi, lg=Lg psi, grad_norm=|J|)``.

    """
    phi = phi_rows(grad, q_dot, dhdt) if phi is None else phi
    psi, lf, lg = psi_rows(h, grad, phi, dphi, terms.a0, terms.minv, alpha_1)
    return LieData._of(psi, lf, lg, np.linalg.norm(grad, axis=1) if grad_norm is None else grad_norm, names)


class SecondOrderRows:
    """The torque level's rows at a state: the velocity level's rows, their ``psi`` and its Lie data.

    Args:
        coll: The collision barriers (velocity level).
        joints: The joint-limit barriers.
        qpos_adr: The arm's qpos addresses, shape (n,) (hinge and slide joints: ``q_dot`` is the dof velocity).
        alpha_1: The inner gain of ``psi = h_dot + alpha_1 h`` [1/s], > 0.
        obstacles: Moving obstacles' clock (:data:`ObstacleClock`); ``None``: static obstacles.
        eps: Step of the forward difference of ``phi`` [s], > 0.
        approaching: ``phi = J q_dot - |dh/dt|`` (module docstring, "Moving obstacles that reverse"); default the
            exact ``phi = h_dot``.

    """

    def __init__(self, coll: CollisionBarriers, joints: JointLimitBarriers, qpos_adr: Sequence[int] | np.ndarray,
                 alpha_1: float, obstacles: ObstacleClock | None = None, eps: float = 1e-4,
                 approaching: bool = False) -> None:
        if not (np.isfinite(alpha_1) and alpha_1 > 0):
            raise ConfigError(f"alpha_1 must be a positive number [1/s], got {alpha_1}")
        if not (np.isfinite(eps) and eps > 0):
            raise ConfigError(f"eps must be a positive number [s], got {eps}")
        self.coll, self.joints = coll, joints
        self.qadr = np.asarray(qpos_adr, dtype=np.int64)
        self.alpha_1, self.eps = float(alpha_1), float(eps)
        self.obstacles = obstacles
        self.approaching = bool(approaching)
        self._scratch = mujoco.MjData(coll.model)
        # The same pairs with a cut-off a little further out for the differences: a pair near at the state stays
        # within it at q + eps q_dot (else its saturated value, with zero gradient, would make a false kink).
        with warnings.catch_warnings():  # (the pairs' warnings were given when ``coll`` was made)
            warnings.simplefilter("ignore", IsfWarning)
            self._probe = CollisionBarriers(coll.model, coll.pairs, coll.dof_adr, coll.cutoff + PROBE_REACH)
        self._at = np.full(coll.pairs.k, -1, dtype=np.int64)  # (pair -> its row in the probe's near pairs)
        live = self._probe.broadphase.live
        self._live_of = np.full(coll.pairs.k, -1, dtype=np.int64)  # (pair -> its row in the probe's live pairs)
        self._live_of[live] = np.arange(live.size)
        self._nmocap = coll.model.nmocap
        # The compiled difference and rows (kernels.second_order_kernels): the probe's packed kernel on the scratch.
        self._kargs = self._probe.packed_arguments(self._scratch)
        ks = kernels.second_order_kernels() if self._kargs is not None else None
        self._kernel, self._tick_kernel = (None, None) if ks is None else ks[:2]
        self._kqpos = (self._scratch.qpos, self.qadr)
        # The tick kernel's leading arguments where nothing moves (the probe's context, no obstacle velocities), and
        # the views of the data last given (binding attributes are new arrays at each access); q_dot by a slice when
        # the dofs are contiguous (a view: the same values as the index array's copy).
        moves = self.obstacles is not None or bool(self._nmocap)
        self._kfix = None if (self._kargs is None or moves) else (*self._kargs, *self._probe.packed_velocities(None))
        self._views: tuple = (None, None, None)
        dof = np.asarray(coll.dof_adr, dtype=np.int64)
        contiguous = dof.size and bool((np.diff(dof) == 1).all())
        self._dsel = slice(int(dof[0]), int(dof[0]) + dof.size) if contiguous else dof
        self._tick_direct: Callable[..., int] | None = None  # (the tick kernel without numba's dispatch: tick)

    def _shift_obstacles(self, data: mujoco.MjData, t: float) -> np.ndarray | None:
        """The scratch's mocap bodies as in ``data``, the moving ones at ``t + eps``; their velocities (or None)."""
        s = self._scratch
        if self._nmocap:
            s.mocap_pos[:] = data.mocap_pos
            s.mocap_quat[:] = data.mocap_quat
        return self.obstacles(s, t + self.eps) if self.obstacles is not None else None

    def phi_rate(self, data: mujoco.MjData, t: float, rows: np.ndarray, q_dot: np.ndarray,
                 phi: np.ndarray) -> np.ndarray:
        """``D phi`` of the collision pairs ``rows`` at the state in ``data`` (time ``t``), shape (len(rows),).

        The forward difference ``(phi(q + eps q_dot, t + eps) - phi) / eps``; ``phi``: the pairs' ``phi`` at the
        state (the tick's, :func:`phi_rows`). One evaluation of the rows per tick; the central difference took two
        for about the same figure (on 150 random states each of panda_pole and panda_moving with near pairs,
        10309 rows: apart by 5e-7 m/s^2 at the median, 5e-4 at the 99th percentile, 0.035 at most). With numba the
        shift, the kinematics, the probe's rows and the difference are one compiled call (``_second_order_jit``).

        Raises:
            ConfigError: A pair of ``rows`` is not within the probe's cut-off at the shifted state.

        """
        if rows.size == 0:
            return np.zeros(0)
        model, s, e = self.coll.model, self._scratch, self.eps
        lin = self._shift_obstacles(data, t)
        if self._kernel is not None:  # (shift, kinematics, rows and difference in one call; numpy below when it cannot)
            out = np.empty(rows.size)
            if self._kernel(*self._kargs, *self._probe.packed_velocities(lin), data.qpos, *self._kqpos, q_dot, e, rows,
                            phi, self._live_of, self.approaching, out) == 0:  # (_second_order_jit.DONE)
                return out
        else:
            s.qpos[:] = data.qpos
            s.qpos[self.qadr] = data.qpos[self.qadr] + e * q_dot
            mujoco.mj_kinematics(model, s)
            mujoco.mj_comPos(model, s)
        near = self._probe.near(s, lin)
        at = self._at
        at[near.rows] = np.arange(near.rows.size)
        sel = at[rows]
        at[near.rows] = -1
        if (sel < 0).any():  # (cannot happen within PROBE_REACH of the cut-off; said rather than assumed)
            raise ConfigError(f"pairs {rows[sel < 0].tolist()} left the probe's reach within eps = {e} s")
        dhdt = near.dhdt[sel]
        return phi_difference(phi_rows(near.grad[sel], q_dot, obstacle_rate(dhdt, self.approaching)), phi, e)

    def tick(self, data: mujoco.MjData, t: float, terms: DynamicsTerms, lin: np.ndarray | None = None, *,
             coherence: object = None, witness: bool = False) -> tuple:
        """The velocity level's tick rows and the torque level's Lie data at the state in ``data``.

        ``data`` has the kinematics of its state (after ``mj_step1``); ``lin``: the mocap velocities at ``t``.
        After the velocity level's rows, ``phi``, ``D phi`` (:meth:`phi_rate`) and the ``psi`` rows are one compiled
        call with numba (``_second_order_jit.psi_tick``: the formulas of :mod:`isf_robot.arm.psi_law`, which the
        numpy path calls too); the numpy path where it cannot (coinciding witness points at the shifted state). The
        call skips numba's dispatch (:func:`~isf_robot.core.jit.direct`) when ``Lg``, ``terms.minv`` and ``terms.a0``
        are C-ordered float64 (as the velocity level's rows and :class:`~isf_robot.arm.dynamics.ArmDynamics` make
        them; the rows' ``h``, ``lf`` and indices are the tick's own arrays, of the types its kernel gives them).

        Returns:
            ``(psi_lie, tick)``: the :func:`psi_lie` of every near pair then every joint limit, and
            the :class:`~isf_robot.arm.rows.TickRows` of the velocity level (``h``, ``dh/dq``,
            ``dh/dt`` in its ``lie``; the safety accounting's minima).

        """
        tick = self.coll.lie_rows(data, self.joints, lin, coherence=coherence, witness=witness)  # type: ignore[arg-type]
        lie, idx = tick[0], tick[1]
        # (no copies: the rows' arrays are the tick's own, never handed out again, and only read here)
        views = self._views
        if views[0] is not data:
            views = self._views = (data, data.qpos, data.qvel)
        q_dot = views[2][self._dsel]
        if self._tick_kernel is not None:  # (phi, D phi and the psi rows in one call; numpy below when it cannot)
            head = self._kfix
            if head is None:  # (moving obstacles: at t + eps on the scratch, their velocities)
                lin_e = self._shift_obstacles(data, t) if idx.size else None
                head = (*self._kargs, *self._probe.packed_velocities(lin_e))
            lg, minv = lie.lg, terms.minv
            k, n = lg.shape
            out = np.empty(k * (n + 2))  # (fresh: the filter may keep the rows)
            args = (*head, views[1], *self._kqpos, q_dot, self.eps, idx, self._live_of, self.approaching, lie.h, lg,
                    lie.lf, terms.a0, minv, self.alpha_1, out)
            kernel = self._tick_kernel
            a0 = terms.a0
            if (lg.dtype is _F64 and minv.dtype is _F64 and a0.dtype is _F64 and lg.flags.c_contiguous
                    and minv.flags.c_contiguous and a0.flags.c_contiguous):  # (the types held: direct)
                kernel = self._tick_direct
                if kernel is None:
                    kernel = self._tick_direct = direct(self._tick_kernel, args)
            if kernel(*args) == 0:  # (_second_order_jit.DONE)
                return LieData._of(out[:k], out[k: 2 * k], out[2 * k:].reshape(k, n), lie.grad_norm, lie.names), tick
        dhdt = obstacle_rate(lie.lf, self.approaching)
        phi = phi_rows(lie.lg, q_dot, dhdt)
        dphi = np.zeros(phi.shape[0])
        nc = idx.size
        dphi[:nc] = self.phi_rate(data, t, idx, q_dot, phi[:nc])
        return psi_lie(lie.h, lie.lg, dhdt, dphi, q_dot, terms, self.alpha_1, lie.names, lie.grad_norm, phi), tick
