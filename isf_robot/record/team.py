"""Each arm's series in the recording of a team run (several arms sharing a workspace).

:class:`~isf_robot.record.arm.ArmRecorder` records a team as one robot (every arm drawn, the team's
series) and hands each block to :class:`TeamSeries`, which adds per arm ``<name>`` (escaped as an
entity path part):

* ``/arms/<name>/mode``: the arm's filter on (1) or off (0) (centrally filtered: the one filter's mode);
* ``/arms/<name>/correction_norm``: ``|u_i - u_nom,i|`` over the arm's own joints [rad/s];
* ``/arms/<name>/barrier_min``: the smallest barrier value ``dist - margin`` of the collision pairs the
  arm is part of (its obstacle pairs, its self pairs, its pairs with other arms), at the control tick [m]
  (pairs beyond the cut-off at ``cutoff - margin``);
* ``/replay/arms/<name>``: the arm's replay columns (``t``, ``dt``, ``on``, ``intervention_rate``
  ``= |u_i - u_nom,i|^2``, ``qp_solved``, ``min_barrier`` as ``barrier_min``), the inputs of
  :func:`~isf_robot.core.metrics.compute_metrics` as the arm's own figures take them, so replay gives each
  arm's duty cycle, switches, off periods and intervention as the run reported them;
* ``/world/arms/<name>/ee`` and ``/world/arms/<name>/goal``: the arm's end effector and the goal it pursues.

The block is a :class:`~isf_robot.arm.team_columns.TeamStepColumns` (``arm_on``, ``arm_qp``, ``arm_ee``,
``arm_goal``); which joints and collision pairs belong to which arm comes from the run's start info
(``arms``, ``arm_joints``, ``pair_arms``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import rerun as rr

from isf_robot.core.sums import row_sq_sums

from .buffer import TIMELINE
from .errors import RecordError
from .recorder import finite_scalars, value_columns
from .schema import ARM_STEPS, ARMS, WORLD, arm_path

__all__ = ["TeamSeries"]

ARM_COLOURS = ((70, 140, 255), (240, 120, 40), (60, 190, 90), (200, 70, 200), (230, 200, 40), (80, 200, 220))


class TeamSeries:
    """Per-arm series of a team run, derived from each block of steps (see the module docstring).

    Args:
        names: The arms' names.
        joints: Each arm's columns of the input, ``(start, stop)``.
        pair_arms: Each collision pair's arms ``(arm of geom 1, arm of geom 2)`` (-1: no arm), shape (k, 2).

    """

    def __init__(self, names: Sequence[str], joints: Sequence[Sequence[int]], pair_arms: Any) -> None:
        self.names = tuple(str(n) for n in names)
        if len(joints) != len(self.names):
            raise RecordError(f"a team's start info needs one (start, stop) per arm: {len(self.names)} arms, "
                              f"{len(joints)} joint ranges")
        self.joints = tuple(slice(int(a), int(b)) for a, b in joints)
        pa = np.asarray(pair_arms, dtype=int).reshape(-1, 2)
        # member[j, i]: pair j involves arm i
        self.member = np.stack([(pa == i).any(axis=1) for i in range(len(self.names))], axis=1) if len(pa) \
            else np.zeros((0, len(self.names)), dtype=bool)

    @classmethod
    def from_info(cls, info: Mapping[str, Any]) -> TeamSeries | None:
        """The series of a team run (start info with ``arms``), ``None`` for a run of one arm."""
        names = info.get("arms")
        if not names:
            return None
        return cls(names, info.get("arm_joints", ()), info.get("pair_arms", ()))

    def log_static(self, rec: rr.RecordingStream) -> None:
        """Series names and colours, and the markers of each arm's end effector and goal."""
        for i, name in enumerate(self.names):
            colour = [list(ARM_COLOURS[i % len(ARM_COLOURS)])]
            base = arm_path(ARMS, name)
            rec.log(f"{base}/mode", rr.SeriesLines(names=f"{name} filter on", colors=colour), static=True)
            rec.log(f"{base}/correction_norm", rr.SeriesLines(names=f"{name} |u - u_nom|", colors=colour),
                    static=True)
            rec.log(f"{base}/barrier_min", rr.SeriesLines(names=f"{name} min h of its pairs", colors=colour),
                    static=True)
            world = arm_path(f"{WORLD}/arms", name)
            rec.log(f"{world}/ee", rr.Points3D.from_fields(radii=[0.012], colors=colour, labels=[name]), static=True)
            rec.log(f"{world}/goal", rr.Points3D.from_fields(radii=[0.025], colors=colour), static=True)

    def columns(self, b: Any, n: int, h: np.ndarray, u: np.ndarray, u_nom: np.ndarray) -> list[dict[str, np.ndarray]]:
        """Each arm's columns of a block's first ``n`` rows (``h``: the collision pairs' barrier values, (n, k))."""
        if not hasattr(b, "arm_on"):
            raise RecordError("a team run's recorder needs each arm's columns (TeamStepColumns); the block has none")
        if self.member.shape[0] != h.shape[1]:
            raise RecordError(f"the block has {h.shape[1]} collision pairs, the run's start info "
                              f"{self.member.shape[0]}")
        out, goals = [], b.arm_goal  # (the goals made once for every arm)
        for i, cols in enumerate(self.joints):
            sel = self.member[:, i]
            hmin = h[:, sel].min(axis=1) if sel.any() else np.full(n, np.nan)
            out.append({
                "on": b.arm_on[:n, i].copy(), "qp_solved": b.arm_qp[:n, i].copy(),
                # in the metrics accumulator's order (sums.sq_sum per row): the arm's intervention adds up the same
                "intervention_rate": row_sq_sums(u[:, cols] - u_nom[:, cols]),
                "min_barrier": np.where(np.isfinite(hmin), hmin, np.nan),
                "ee": b.arm_ee[:n, i].copy(), "goal": goals[:n, i].copy(),
            })
        return out

    def send(self, stream: rr.RecordingStream, t: np.ndarray, dt: np.ndarray, b: Any, h: np.ndarray,
             u: np.ndarray, u_nom: np.ndarray) -> None:
        """Send every arm's series of a block (``t``, ``dt``, ``u``, ``u_nom``: the block's first rows, copied)."""
        n = len(t)
        idx = [rr.TimeColumn(TIMELINE, duration=t)]
        for name, a in zip(self.names, self.columns(b, n, h, u, u_nom)):
            base = arm_path(ARMS, name)
            stream.send_columns(arm_path(ARM_STEPS, name), indexes=idx, columns=value_columns(
                t=t, dt=dt, on=a["on"], intervention_rate=a["intervention_rate"], qp_solved=a["qp_solved"],
                min_barrier=a["min_barrier"]))
            stream.send_columns(f"{base}/mode", indexes=idx,
                                columns=rr.Scalars.columns(scalars=a["on"].astype(np.float64)))
            stream.send_columns(f"{base}/correction_norm", indexes=idx,
                                columns=rr.Scalars.columns(scalars=np.sqrt(a["intervention_rate"])))
            out = finite_scalars(t, a["min_barrier"])
            if out is not None:
                stream.send_columns(f"{base}/barrier_min", indexes=[rr.TimeColumn(TIMELINE, duration=out[0])],
                                    columns=out[1])
            world = arm_path(f"{WORLD}/arms", name)
            stream.send_columns(f"{world}/ee", indexes=idx, columns=rr.Points3D.columns(positions=a["ee"]))
            ok = np.all(np.isfinite(a["goal"]), axis=1)
            if ok.any():
                stream.send_columns(f"{world}/goal", indexes=[rr.TimeColumn(TIMELINE, duration=t[ok])],
                                    columns=rr.Points3D.columns(positions=a["goal"][ok]))
