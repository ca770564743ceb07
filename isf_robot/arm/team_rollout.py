"""The team's nominal rolled forward in one compiled call: every arm's reaching controller at each point.

A scene with several arms runs :class:`~isf_robot.arm.team_nominal.TeamReaching` (one
:class:`~isf_robot.arm.nominal.ReachingController` per arm, the commands stacked). Its rollout
(:class:`~isf_robot.arm.rollout.NominalRollout`) takes :class:`TeamPoints` where it can: all points in one call of
``_rollout_jit.team_points`` (per point: the moving obstacles' places, one Euler step of every joint, the
kinematics, each arm's compiled reaching command with its own addresses, buffer, joints, end effector, goal
and rate limit, then the collision kernel once), as the one-arm rollout does with ``closed_loop_points``. The
same formulas as the loop of points (equal to rounding). Taken while every arm's goal is steady over the horizon
(:meth:`~isf_robot.arm.goals.GoalSequence.steady`), every arm has a previous command and its compiled command is
bound to the scratch data; otherwise the loop runs. The arms' controllers are not touched: the kernel works on
copies of their buffers.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from isf_robot.core.jit import compiled

from . import kernels, narrow
from .nominal import ReachingController
from .team_nominal import TeamReaching

__all__ = ["TeamPoints"]


def team_kernel() -> Any:
    """``_rollout_jit.team_points`` compiled, or ``None``.

    ``None`` without the compiled kernels, and under ``ISF_ROBOT_JIT=cached`` while numba's cache does not hold it.
    """
    if kernels.rollout_kernels() is None:
        return None
    from . import _rollout_jit

    fn = compiled(_rollout_jit.team_points, (os.path.dirname(_rollout_jit.__file__),))
    return fn if hasattr(fn, "py_func") else None


class TeamPoints:
    """The compiled points of a team's rollout ``ro`` (a :class:`~isf_robot.arm.rollout.NominalRollout`).

    Made by :meth:`of`; holds every arm's fixed tables (joints, first dof, site, first column, gains) and scratch
    copies of their buffers.
    """

    def __init__(self, ro: Any, arms: list[ReachingController], starts: list[int], kernel: Any) -> None:
        self.ro, self.arms, self.kernel = ro, arms, kernel
        a = len(arms)
        self.arm_i = np.array([[c.n, c._dof0, c.scene.ee_site_id, 0, s] for c, s in zip(arms, starts)], dtype=np.int64)
        self.arm_f = np.array([[0.0, c._rate.a_max, c.kp, c.max_ee_speed, c.max_joint_speed, c._lam2] for c in arms])
        self.rps = np.zeros((a, 2), dtype=np.int64)
        self.nbs = np.zeros((a, max(c._buf.size for c in arms)))
        self.nv = int(ro.scene.model.nv)

    @classmethod
    def of(cls, ro: Any) -> TeamPoints | None:
        """The team's compiled points for rollout ``ro``, or ``None`` (not a team, or no compiled kernels).

        Every arm's controller must be a :class:`ReachingController` with its compiled command on the rollout's
        model, its columns a slice of the team's command, and the collision kernel compiled.
        """
        nom = ro.nominal
        if type(nom) is not TeamReaching or ro._kernels is None or ro.coll._kernel is None:
            return None
        starts = []
        for c, sl in zip(nom.arms, nom.slices):
            if not (type(c) is ReachingController and c._reach is not None and c.scene.model is ro.scene.model
                    and isinstance(sl, slice) and sl.step in (None, 1) and sl.stop - sl.start == c.n):
                return None
            starts.append(int(sl.start))
        kernel = team_kernel()
        return None if kernel is None else cls(ro, list(nom.arms), starts, kernel)

    def steady(self, t: float) -> bool:
        """Whether the points after ``t`` can be one call: :meth:`ScratchRollout._steady` for every arm."""
        return self.ro._steady(t, controllers=self.arms)  # type: ignore[no-any-return]

    def run(self, t: float, q: np.ndarray, v0: np.ndarray, mpos: np.ndarray | None,
            lins: np.ndarray | None) -> tuple | None:
        """The points after ``t`` from ``q`` with the joint velocity ``v0``, in one call (``_rollout_jit.team_points``).

        Returns ``(kernel context, blocks, gradients, rows, keys, res, commands)`` as
        :meth:`ScratchRollout._run_whole`; ``None`` after a point whose witness points coincide (``q`` as before).
        """
        ro = self.ro
        coll, n = ro.coll, ro.n
        c = ro._context()
        blk, g, rows = coll._point_outputs(c, n)
        keys = np.empty((n, c[7]), dtype=np.int64)
        outs, res, q0 = np.empty((n, v0.size)), np.empty((n, 6)), q.copy()
        rps, nbs, arm_i, arm_f = self.rps, self.nbs, self.arm_i, self.arm_f
        for a, ctl in enumerate(self.arms):  # (each arm's state and settings now, as the one-arm path reads them)
            rps[a] = ctl._ptrs
            nbs[a, :ctl._buf.size] = ctl._buf
            arm_i[a, 3] = ctl.goals.index
            arm_f[a] = (ctl._rate.t_prev, ctl._rate.a_max, ctl.kp, ctl.max_ee_speed, ctl.max_joint_speed, ctl._lam2)
        mp, ls, lin, dl = ro._moving_args(mpos, lins)
        done = self.kernel(*ro._addr, q, v0, t, ro.dt, ro._data.qpos, ro._qadr, rps, nbs, arm_i, arm_f, self.nv, outs,
                           c[4], blk, rows, keys, len(coll.pairs.names), res, coll.cutoff, c[14], c[15],
                           narrow._EPS_DIST, c[13], lin, dl, ro._mp_addr, ro._nmocap, ro._mids, mp, ls)
        if done < n or res[n - 1, 4]:  # (touching witness points)
            q[:] = q0
            return None
        return c, blk, g, rows, keys, res, outs
