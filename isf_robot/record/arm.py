"""Rerun content of an arm run (observer of :class:`isf_robot.arm.ArmSimulation`).

Logged, besides the base recorder's replay columns, mode and events:

* ``/world/bodies/...``: the MuJoCo scene's geometry once (capsules, spheres, ellipsoids,
  boxes, cylinders, planes, meshes) and the moving bodies' poses per step (arm links and
  moving obstacles), by forward kinematics of the record's ``q`` and mocap poses.
* ``/world/goals`` (static, every goal), ``/world/goal`` (the goal pursued), ``/world/ee``.
* ``/world/witness``: witness segments of the pairs within the cut-off.
* ``/plots/barrier/min`` (true geometry, every physics step), ``/plots/barrier/filter_min``
  (the barriers the filter sees), ``/plots/barrier/pairs/<pair>`` (each pair while it is
  among the closest three), ``/plots/xi/min`` (``min Xi_on``).
* ``/plots/command/nominal`` and ``/plots/command/filtered``: one series per joint [rad/s].

Replay row: ``t``, ``dt``, ``on``, ``|u - u_nom|^2``, ``qp_solved`` from the record, and
``min_barrier`` the true-geometry minimum of ``dist - margin`` over the step's physics steps:
the record's ``barrier_min`` when the loop provides it, else ``dist_min - margin`` (exact when
every collision pair has the same margin, which :attr:`ArmRecorder.exact_min_barrier` says).
The loop also checks the state after the last step without a step record; when that final
check is the run's minimum, it is logged as one extra row ``/replay/terminal``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import rerun as rr

from .errors import RecordError
from .mjgeometry import MujocoDrawing
from .recorder import RerunRecorder
from .schema import TERMINAL

__all__ = ["ArmRecorder"]


def _witness_columns(rows: list[np.ndarray]) -> Any:
    strips = [seg for w in rows for seg in w]
    lengths = [len(w) for w in rows]
    return rr.LineStrips3D.columns(strips=strips if strips else np.zeros((0, 2, 3))).partition(lengths)


class ArmRecorder(RerunRecorder):
    """Observer of the arm loop: scene, barriers, triggers, mode, commands, witness segments.

    Args:
        stream: The recording stream.
        scene: The :class:`isf_robot.arm.Scene` being simulated (geometry, joint addresses,
            margins).
        closest: How many closest pairs get their own barrier series (at most what the
            record lists).
        capacity: Rows buffered per channel.
        close_on_finish: Close the stream in ``on_finish``.

    """

    kind = "arm"
    CONTEXT_KEYS = ("scene", "closest", "capacity")

    def __init__(
        self,
        stream: rr.RecordingStream,
        *,
        scene: Any,
        closest: int = 3,
        capacity: int = 2048,
        close_on_finish: bool = True,
    ) -> None:
        if scene is None or not hasattr(scene, "model"):
            raise RecordError("ArmRecorder needs scene= (an isf_robot.arm.Scene)")
        super().__init__(stream, capacity=capacity, close_on_finish=close_on_finish)
        self.scene = scene
        self.closest = int(closest)
        self.drawing = MujocoDrawing(scene.model)
        self.margins = self._margins(scene)
        uniform = self.margins.size == 0 or bool(np.all(self.margins == self.margins[0]))
        self.exact_min_barrier = uniform
        self._margin = float(self.margins.max()) if self.margins.size else 0.0
        self._running_min = math.inf
        buf = self.buffer
        self._poses = buf.add("/world/bodies", self.drawing.pose_channel(stream, buf.capacity))
        n = int(scene.n_joints)
        self._u_nom = buf.scalars("/plots/command/nominal", n)
        self._u = buf.scalars("/plots/command/filtered", n)
        self._hfilt = buf.scalars("/plots/barrier/filter_min")
        self._xi = buf.scalars("/plots/xi/min")
        self._ee = buf.channel("/world/ee", {"positions": ((3,), np.float64)},
                               lambda positions: rr.Points3D.columns(positions=positions))
        self._goal = buf.channel("/world/goal", {"positions": ((3,), np.float64)},
                                 lambda positions: rr.Points3D.columns(positions=positions))
        self._witness = buf.ragged("/world/witness", _witness_columns)
        self._pairs: dict[str, Any] = {}
        self._name_index: dict[str, int] = {}
        self._names: tuple[str, ...] = ()

    @staticmethod
    def _margins(scene: Any) -> np.ndarray:
        try:
            from isf_robot.arm.barriers import CollisionBarriers

            return np.asarray(CollisionBarriers.from_scene(scene).pairs.margin, dtype=float)
        except Exception:  # scene without collision pairs: no margin to subtract
            return np.zeros(0)

    # -- static --------------------------------------------------------------------------
    def start_content(self, info: Mapping[str, Any]) -> None:
        """Geometry, goals, plot styles."""
        rec = self.stream
        rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self.drawing.log_static(rec)
        goals = info.get("goals")
        goals = np.asarray(goals if goals is not None else getattr(self.scene, "goal_positions", np.zeros((0, 3))),
                           dtype=float).reshape(-1, 3)
        if goals.size:
            rec.log("/world/goals", rr.Points3D(goals, radii=0.015, colors=[[60, 200, 90]],
                                                labels=[f"goal {i}" for i in range(len(goals))]), static=True)
        rec.log("/world/goal", rr.Points3D.from_fields(radii=[0.025], colors=[[40, 240, 80]]), static=True)
        rec.log("/world/ee", rr.Points3D.from_fields(radii=[0.012], colors=[[240, 240, 240]]), static=True)
        rec.log("/world/witness", rr.LineStrips3D.from_fields(radii=[0.003], colors=[[255, 40, 200]]), static=True)
        joints = [str(j) for j in info.get("joint_names", getattr(self.scene, "joint_names", ()))]
        rec.log("/plots/command/nominal", rr.SeriesLines(names=[f"{j} nominal" for j in joints],
                                                         widths=[1.0] * len(joints)), static=True)
        rec.log("/plots/command/filtered", rr.SeriesLines(names=[f"{j} filtered" for j in joints],
                                                          widths=[2.0] * len(joints)), static=True)
        rec.log("/plots/barrier/filter_min", rr.SeriesLines(names="min h (filter)", colors=[[240, 150, 40]]),
                static=True)
        rec.log("/plots/xi/min", rr.SeriesLines(names="min Xi_on"), static=True)
        rec.log("/run/arm", rr.AnyValues(exact_min_barrier=self.exact_min_barrier,
                                         geoms_drawn=self.drawing.geoms_drawn,
                                         geoms_skipped=",".join(self.drawing.geoms_skipped)), static=True)

    # -- per step ------------------------------------------------------------------------
    def replay_row(self, record: Any) -> tuple[float, float, bool, float, bool, float]:
        """``(t, dt, on, |u - u_nom|^2, qp_solved, true-geometry min barrier)``."""
        d = np.asarray(record.u, dtype=float) - np.asarray(record.u_nom, dtype=float)
        hmin = getattr(record, "barrier_min", None)
        if hmin is None:
            dist = float(record.dist_min)
            hmin = dist - self._margin if math.isfinite(dist) else float("nan")
        hmin = float(hmin)
        if hmin < self._running_min:
            self._running_min = hmin
        return (float(record.t), float(record.dt), bool(record.on), float(d @ d), bool(record.qp_solved), hmin)

    def step_content(self, t: float, record: Any) -> None:
        """Poses, commands, barrier and trigger series, witness segments, goal."""
        self.drawing.push_state(t, self.scene.qpos_adr, record.q, record.mocap_pos, record.mocap_quat)
        self._u_nom.push(t, record.u_nom)
        self._u.push(t, record.u)
        self._hfilt.push(t, float(record.h_min))
        xi = float(record.xi_min)
        if math.isfinite(xi):
            self._xi.push(t, xi)
        self._ee.push(t, record.ee_pos)
        goal = np.asarray(record.goal_pos, dtype=float)
        if np.all(np.isfinite(goal)):
            self._goal.push(t, goal)
        w = np.asarray(record.witness, dtype=float)
        self._witness.push(t, w[np.all(np.isfinite(w), axis=(1, 2))] if w.size else np.zeros((0, 2, 3)))
        if record.names is not self._names:
            self._names = record.names
            self._name_index = {n: i for i, n in enumerate(record.names)}
        h = record.h
        for name in record.closest[: self.closest]:
            ch = self._pairs.get(name)
            if ch is None:
                path = f"/plots/barrier/pairs/{rr.escape_entity_path_part(name)}"
                ch = self.buffer.scalars(path)
                self.stream.log(path, rr.SeriesLines(names=name), static=True)
                self._pairs[name] = ch
            ch.push(t, float(h[self._name_index[name]]))

    def describe_event(self, event: Any) -> str:
        """``t = 1.234 s: filter on (#3, Xi_on = -0.001) after 0.82 s off``."""
        kind = getattr(event, "kind", "?")
        dur = getattr(event, "duration_s", None)
        before = "off" if kind == "on" else "on"
        extra = "" if dur is None else f" after {float(dur):.4g} s {before}"
        return (f"t = {float(event.t):.4f} s: filter {kind} (#{getattr(event, 'index', '?')}, "
                f"Xi_on = {float(getattr(event, 'xi_min', float('nan'))):.4g}){extra}")

    def finish_content(self, summary: Mapping[str, Any]) -> None:
        """Log the final state's barrier when the loop's last check (no step record) set the minimum."""
        final = summary.get("min_barrier")
        if final is not None and isinstance(final, (int, float)) and float(final) < self._running_min:
            t_end = float(summary.get("duration_s", 0.0))
            self.stream.send_columns(TERMINAL, indexes=[rr.TimeColumn("sim_time", duration=[t_end])],
                                     columns=rr.AnyValues.columns(t=[t_end], min_barrier=[float(final)]))
