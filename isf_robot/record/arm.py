"""Rerun content of an arm run (observer of :class:`isf_robot.arm.ArmSimulation`).

Logged, besides the base recorder's replay columns, mode and events:

* ``/world/bodies/...``: the MuJoCo scene's geometry once, solid (capsules, spheres,
  ellipsoids, boxes, cylinders, planes, meshes as meshes): the visible groups plus every robot
  and obstacle geom of the start info whatever its group, and the moving bodies' poses per step
  (arm links and moving obstacles), as the loop kept them at each control tick.
  The robot's geoms turn orange while the filter is on (their colour is sent at each switch).
* ``/world/goals`` (static, every goal), ``/world/goal`` (the goal pursued), ``/world/ee``,
  ``/world/ee_trail`` (the end effector's path over the last ``trail_s`` seconds).
* ``/world/witness``: witness segments of the closest pairs (up to ``closest``) within the cut-off.
* ``/plots/barrier/min`` (true geometry, every physics step), ``/plots/barrier/filter_min``
  (the barriers the filter sees), ``/plots/barrier/pairs/<pair>`` (each pair while it is
  among the closest; a ``Clear`` at the first step it is not, so no line joins the gaps),
  ``/plots/barrier/zero``; ``/plots/xi/min`` (``min Xi_on``) with ``/plots/xi/zero`` and
  ``/plots/xi/c`` (the on and off thresholds).
* ``/plots/command/correction_norm``: ``|u - u_nom|`` [rad/s];
  ``/plots/joints/correction``: ``u - u_nom`` per joint; ``/plots/joints/command/nominal`` and
  ``/plots/joints/command/filtered``: ``u_nom`` and ``u`` per joint [rad/s].

A team run (start info with ``arms``: :class:`~isf_robot.arm.multi_arm.MultiArmSimulation`) adds each
arm's series and replay columns (``/arms/<name>/...``, ``/replay/arms/<name>``, :mod:`isf_robot.record.team`)
and opens on the team layout (:func:`~isf_robot.record.blueprints.team_blueprint`, a tab per arm).

Replay row: ``t``, ``dt``, ``on``, ``|u - u_nom|^2``, ``qp_solved`` from the record, and
``min_barrier`` the true-geometry minimum of ``dist - margin`` (each pair's own margin) over the step's
physics steps: the smaller of the tick's collision barriers (``h[:n_collision]``) and the loop's minimum over
the other physics steps (``true_min``), exact below the far pairs' floor (the least ``cutoff - margin``), which
is also what the run's ``min_barrier`` takes there. The loop also checks the state after the last
step without a step record; when that final check is the run's minimum, it is logged as one
extra row ``/replay/terminal``.

Cost: the arm loop writes each step into a block of columns
(:class:`~isf_robot.arm.step_columns.StepColumns`, a row of array writes per step) and hands the
block to :meth:`ArmRecorder.on_steps` every ``capacity`` steps; the recorder derives every entity
from those arrays and sends each once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np
import rerun as rr

from isf_robot.core.sums import row_sq_sums, sq_sum

from .arm_columns import closest_witness, goal_columns, norm_columns, strip_array, witness_columns
from .blueprints import arm_blueprint, camera_for, team_blueprint
from .buffer import TIMELINE, Channel
from .errors import RecordError
from .mjgeometry import MujocoDrawing
from .recorder import RerunRecorder, any_values, finite_scalars, value_columns
from .schema import STEPS, TERMINAL, command_unit
from .team import TeamSeries

__all__ = ["ArmRecorder"]


class ArmRecorder(RerunRecorder):
    """Observer of the arm loop: scene, barriers, triggers, mode, commands, witness segments.

    Args:
        stream: The recording stream.
        closest: How many collision pairs (those with the smallest h at each step) get their
            own barrier series and witness segments.
        capacity: Steps per block the arm loop hands over (:attr:`block_steps`);
            :func:`~isf_robot.record.options.open_recorder` takes :attr:`FILE_CAPACITY` for a file
            alone, :attr:`LIVE_CAPACITY` when a viewer watches live.
        close_on_finish: Close the stream in ``on_finish``.
        trail_s: Length of the end effector's trail [s] (0: none).

    """

    kind = "arm"
    CONTEXT_KEYS = ("closest", "capacity", "trail_s")
    INFO_OBJECTS = ("model", "data")
    FILE_CAPACITY = 16384
    """Steps per block when the recording goes to a file only: each block costs about 60 sends of ~0.5 ms whatever
    its size (4 us per step at 8192 steps, 2 us at 16384), and holds about 30 MB (a Panda scene)."""
    LIVE_CAPACITY = 512
    """Steps per block when a viewer watches live (about a second of a 500 Hz run between updates)."""
    TRAIL_POINTS = 25
    """Most points per trail strip (the trail is subsampled to this)."""

    def __init__(
        self,
        stream: rr.RecordingStream,
        *,
        closest: int = 3,
        capacity: int = 2048,
        close_on_finish: bool = True,
        trail_s: float = 2.0,
    ) -> None:
        super().__init__(stream, capacity=capacity, close_on_finish=close_on_finish)
        self.closest = int(closest)
        self.trail_s = float(trail_s)
        if not (self.trail_s >= 0 and math.isfinite(self.trail_s)):
            raise RecordError(f"trail_s must be a finite number >= 0, got {trail_s!r}")
        self.drawing: MujocoDrawing | None = None
        self.c = math.nan
        self._running_min = math.inf
        self._n_collision = 0
        self._pair_paths: dict[int, str] = {}
        self._pair_member: dict[int, bool] = {}
        self._trail_tail = np.zeros((0, 3))
        self._names: tuple[str, ...] = ()
        self.team: TeamSeries | None = None
        self._derived = self._derived_entities()

    @property
    def block_steps(self) -> int:
        """Steps per block the arm loop hands to :meth:`on_steps` (the buffer's capacity)."""
        return self.buffer.capacity

    def _setup(self, info: Mapping[str, Any]) -> None:
        """Geometry and the collision rows' count from the run's start info (``model``, ``n_collision``)."""
        model = info.get("model")
        if model is None:
            raise RecordError("ArmRecorder needs the arm loop's start info (model, pair_margins); "
                              "got keys: " + ", ".join(sorted(info)))
        robot = np.asarray(info.get("robot_geom_ids", ()), dtype=int).reshape(-1)
        obstacles = np.asarray(info.get("obstacle_geom_ids", ()), dtype=int).reshape(-1)
        try:
            self.drawing = MujocoDrawing(model, include=np.concatenate((robot, obstacles)).tolist(),
                                         tinted=robot.tolist())
        except ValueError as exc:
            raise RecordError(f"start info: {exc}") from None
        self._n_collision = int(info.get("n_collision", np.size(info.get("pair_margins", ()))))
        c = info.get("c")
        self.c = float(c) if isinstance(c, (int, float)) else math.nan
        self.team = TeamSeries.from_info(info)

    def versions(self) -> dict[str, str]:
        """isf_robot, rerun and MuJoCo versions."""
        return {**super().versions(), "mujoco": str(mujoco.__version__)}

    def make_step_channel(self) -> Channel | None:
        """None: the arm loop hands whole blocks of columns to :meth:`on_steps` instead."""
        return None

    def _derived_entities(self) -> tuple[tuple[str, Any], ...]:
        """Every time-series entity, built from a block of step columns (see :meth:`_send_batch`)."""
        return (
            (STEPS, self._replay_columns),
            *self.step_plots(),
            ("/plots/command/correction_norm", norm_columns),
            ("/plots/joints/correction", lambda t, a: (t, rr.Scalars.columns(scalars=a["u"] - a["u_nom"]))),
            ("/plots/joints/command/nominal", lambda t, a: (t, rr.Scalars.columns(scalars=a["u_nom"]))),
            ("/plots/joints/command/filtered", lambda t, a: (t, rr.Scalars.columns(scalars=a["u"]))),
            ("/plots/barrier/filter_min", lambda t, a: finite_scalars(t, a["h_filter"])),
            ("/plots/xi/min", lambda t, a: finite_scalars(t, a["xi"])),
            ("/world/ee", lambda t, a: (t, rr.Points3D.columns(positions=a["ee"]))),
            ("/world/goal", goal_columns),
            ("/plots/barrier/pairs", self._pair_columns),
            ("/plots/thresholds", self._threshold_columns),
            ("/world/ee_trail", self._trail_columns),
        )

    def _send_block(self, b: Any) -> None:
        """Send every entity of a block of steps in columns (one ``send_columns`` call each).

        ``b`` is a :class:`~isf_robot.arm.step_columns.StepColumns` of the arm loop: its first
        ``len(b)`` rows are copied where they are sent as they are (the loop reuses its arrays for the next
        block, and the stream may encode the columns after ``send_columns`` returns); ``h`` is only read
        here (every column sent is made from it), so it is not copied. The time column of the block's
        steps is made once and sent with every entity that has a row at each step.
        """
        n = len(b)
        if n == 0:
            return
        t = b.t[:n].copy()
        u, u_nom = b.u[:n].copy(), b.u_nom[:n].copy()
        a = {
            "t": t, "dt": np.full(n, float(b.dt)), "on": b.on[:n].copy(), "qp_solved": b.qp_solved[:n].copy(),
            # in the metrics accumulator's written order (sums.sq_sum per row), so the sums match
            "intervention_rate": row_sq_sums(u - u_nom),
            "true_min": b.true_min[:n].copy(), "h_filter": b.h_min[:n].copy(), "xi": b.xi_min[:n].copy(),
            "h": b.h[:n], "u_nom": u_nom, "u": u, "ee": b.ee_pos[:n].copy(), "goal": b.goal_pos[:n].copy(),
            # each row's collision pairs, the smallest h first (as the step record's ``closest``)
            "order": np.argsort(b.h[:n, :self._n_collision], axis=1),
        }
        if not self._names:
            self._names = tuple(b.names)
        stream = self.stream
        idx = [rr.TimeColumn(TIMELINE, duration=t)]  # (every step's: made once, sent with each entity of every step)
        for path, fn in self._derived:
            out = fn(t, a)
            if out is not None and len(out[0]):
                stream.send_columns(path, indexes=idx if out[0] is t else [rr.TimeColumn(TIMELINE, duration=out[0])],
                                    columns=out[1])
        stream.send_columns("/world/witness", indexes=idx,
                            columns=witness_columns(*closest_witness(b, n, a["order"][:, :min(self.closest, 3)])))
        if self.team is not None:
            self.team.send(stream, t, a["dt"], b, a["h"][:, :self._n_collision], u, u_nom)
        assert self.drawing is not None
        self.drawing.send_poses(stream, t, b.body_pos[:n], b.body_quat[:n], index=idx[0])
        self.drawing.send_tint(stream, t, a["on"])
        self.steps += n

    def _min_barrier(self, a: dict[str, np.ndarray]) -> np.ndarray:
        """Per-step true-geometry minimum of ``dist - margin`` (tick values and physics substeps)."""
        nc = self._n_collision
        tick = a["h"][:, :nc].min(axis=1) if nc else np.full(a["t"].shape, np.inf)
        out = np.minimum(tick, a["true_min"])
        out[~np.isfinite(out)] = np.nan
        return out

    def _replay_columns(self, t: np.ndarray, a: dict[str, np.ndarray]) -> tuple[np.ndarray, Any]:
        mb = self._min_barrier(a)
        a["min_barrier"] = mb  # for the derived plots that follow
        if np.any(np.isfinite(mb)):
            self._running_min = min(self._running_min, float(np.nanmin(mb)))
        return t, value_columns(t=a["t"], dt=a["dt"], on=a["on"], intervention_rate=a["intervention_rate"],
                                qp_solved=a["qp_solved"], min_barrier=mb)

    def _pair_columns(self, t: np.ndarray, a: dict[str, np.ndarray]) -> None:
        """Each pair's barrier at the steps where it is among the closest, a Clear where it stops being.

        (``None``: sent here.) The Clear at the first step after each run of membership breaks
        the viewer's line, so no straight segment joins values across the gap.
        """
        nc = self._n_collision
        m = min(self.closest, nc)
        if m <= 0:
            return None
        h = a["h"][:, :nc]
        n = h.shape[0]
        member = np.zeros((n, nc), dtype=bool)
        member[np.arange(n)[:, None], a["order"][:, :m]] = True
        prev = np.empty_like(member)
        prev[1:] = member[:-1]
        prev[0] = False
        for j, was in self._pair_member.items():
            prev[0, j] = was
        gaps_all = prev & ~member
        seen = np.flatnonzero(member.any(axis=0) | gaps_all.any(axis=0)).tolist()
        # (the block's times as the time column holds them, [ns], converted once: each pair's rows are taken from it)
        t_ns = (t * 1e9).astype("timedelta64[ns]")
        last = member[-1]
        for j in seen:
            self._pair_member[j] = bool(last[j])
            path = self._pair_path(j)
            rows = np.flatnonzero(member[:, j])
            gaps = np.flatnonzero(gaps_all[:, j])
            if rows.size:
                self.stream.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=t_ns[rows])],
                                         columns=rr.Scalars.columns(scalars=h[rows, j]))
            if gaps.size:
                self.stream.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=t_ns[gaps])],
                                         columns=rr.Clear.columns(is_recursive=[False] * int(gaps.size)))
        return None

    def _pair_path(self, j: int) -> str:
        path = self._pair_paths.get(j)
        if path is None:
            name = self._names[j] if j < len(self._names) else f"pair{j}"
            path = f"/plots/barrier/pairs/{rr.escape_entity_path_part(name)}"
            self.stream.log(path, rr.SeriesLines(names=name), static=True)
            self._pair_paths[j] = path
        return path

    def _threshold_columns(self, t: np.ndarray, a: dict[str, np.ndarray]) -> None:
        """Constant lines at h = 0, Xi_on = 0 and Xi_on = c, at the block's first and last step."""
        ends = np.array([t[0], t[-1]])
        idx = [rr.TimeColumn(TIMELINE, duration=ends)]
        lines = [("/plots/barrier/zero", 0.0), ("/plots/xi/zero", 0.0)]
        if math.isfinite(self.c):
            lines.append(("/plots/xi/c", self.c))
        for path, value in lines:
            self.stream.send_columns(path, indexes=idx, columns=rr.Scalars.columns(scalars=[value, value]))
        return None

    def _trail_columns(self, t: np.ndarray, a: dict[str, np.ndarray]) -> tuple[np.ndarray, Any] | None:
        """The end effector's path over the last ``trail_s`` seconds at each step (subsampled)."""
        dt = a["dt"]
        if self.trail_s <= 0 or not len(t) or not dt[0] > 0:
            return None
        k = max(2, int(round(self.trail_s / float(dt[0]))) + 1)
        stride = max(1, -(-k // self.TRAIL_POINTS))
        pts = np.concatenate((self._trail_tail, a["ee"]))
        off = len(self._trail_tail)
        # step i's strip: the points j, j - stride, j - 2 stride, ... >= max(0, j - k + 1) (j = off + i), in order
        n = len(t)
        head = min(n, max(0, k - 1 - off))  # (the run's first steps: strips shorter than the others)
        j = off + np.arange(head)
        lengths = np.empty(n, dtype=np.int64)
        lengths[:head] = j // stride + 1
        full = (k - 1) // stride + 1
        lengths[head:] = full
        start = np.cumsum(lengths[:head]) - lengths[:head]
        pos = np.arange(int(lengths[:head].sum())) - np.repeat(start, lengths[:head])  # position within its strip
        idx_head = np.repeat(j, lengths[:head]) - (np.repeat(lengths[:head], lengths[:head]) - 1 - pos) * stride
        # (the others, all of ``full`` points: one broadcast)
        idx = (np.arange(off + head, off + n)[:, None] - stride * np.arange(full - 1, -1, -1)).reshape(-1)
        if head:
            idx = np.concatenate((idx_head, idx))
        self._trail_tail = pts[-(k - 1):].copy()
        strips = strip_array(np.take(pts.astype(np.float32), idx, axis=0), lengths)  # (take: 4x a fancy index)
        return t, rr.LineStrips3D.columns(strips=strips).partition([1] * n)

    # -- static --------------------------------------------------------------------------
    def start_content(self, info: Mapping[str, Any]) -> None:
        """Geometry, goals, plot styles, and the default layout framed on the arm's workspace."""
        self._setup(info)
        assert self.drawing is not None
        rec = self.stream
        rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self.drawing.log_static(rec)
        goals = info.get("goals")
        goals = np.asarray(goals if goals is not None else np.zeros((0, 3)), dtype=float).reshape(-1, 3)
        if goals.size:
            rec.log("/world/goals", rr.Points3D(goals, radii=0.015, colors=[[60, 200, 90]],
                                                labels=[f"goal {i + 1}" for i in range(len(goals))]), static=True)
        rec.log("/world/goal", rr.Points3D.from_fields(radii=[0.025], colors=[[40, 240, 80]]), static=True)
        rec.log("/world/ee", rr.Points3D.from_fields(radii=[0.012], colors=[[240, 240, 240]]), static=True)
        rec.log("/world/ee_trail", rr.LineStrips3D.from_fields(radii=[0.004], colors=[[90, 170, 255]]),
                static=True)
        rec.log("/world/witness", rr.LineStrips3D.from_fields(radii=[0.004], colors=[[255, 40, 200]]), static=True)
        joints = [str(j) for j in info.get("joint_names", ())]
        rec.log("/plots/joints/correction", rr.SeriesLines(names=[f"{j}" for j in joints]), static=True)
        rec.log("/plots/joints/command/nominal", rr.SeriesLines(names=[f"{j} nominal" for j in joints],
                                                                widths=[1.0] * len(joints)), static=True)
        rec.log("/plots/joints/command/filtered", rr.SeriesLines(names=[f"{j} filtered" for j in joints],
                                                                 widths=[2.0] * len(joints)), static=True)
        rec.log("/plots/command/correction_norm", rr.SeriesLines(names="|u - u_nom|", colors=[[240, 150, 40]]),
                static=True)
        rec.log("/plots/barrier/filter_min", rr.SeriesLines(names="min h (filter)", colors=[[240, 150, 40]]),
                static=True)
        grey = [[150, 150, 150]]
        rec.log("/plots/barrier/zero", rr.SeriesLines(names="h = 0", colors=grey, widths=[1.0]), static=True)
        rec.log("/plots/xi/min", rr.SeriesLines(names="min Xi_on", colors=[[80, 160, 255]]), static=True)
        rec.log("/plots/xi/zero", rr.SeriesLines(names="0 (on below)", colors=grey, widths=[1.0]), static=True)
        rec.log("/plots/xi/c", rr.SeriesLines(names=f"c = {self.c:g} (off above)", colors=[[60, 200, 90]],
                                              widths=[1.0]), static=True)
        rec.log("/run/arm", any_values(geoms_drawn=self.drawing.geoms_drawn,
                                         geom_ids_drawn=np.asarray(self.drawing.drawn_ids, dtype=np.int64),
                                         geoms_skipped=",".join(self.drawing.geoms_skipped)), static=True)
        centre, radius = self.drawing.workspace()
        eye, target = camera_for(centre, radius)
        duration = info.get("duration")
        span = float(duration) if isinstance(duration, (int, float)) else None
        if self.team is not None:
            self.team.log_static(rec)
            blueprint = team_blueprint(self.team.names, eye, target, span, c=self.c)
        else:
            blueprint = arm_blueprint(eye, target, span, c=self.c, unit=command_unit(info))
        rec.send_blueprint(blueprint, make_active=True, make_default=True)

    # -- per step ------------------------------------------------------------------------
    def on_steps(self, block: Any) -> None:
        """Send a block of the arm loop's steps (:class:`~isf_robot.arm.step_columns.StepColumns`)."""
        self._send_block(block)

    def on_step(self, record: Any) -> None:
        """Not taken: the arm loop hands this recorder whole blocks of steps (:meth:`on_steps`)."""
        raise RecordError("ArmRecorder takes the arm loop's blocks of steps (on_steps), not single step records; "
                          "attach it to ArmSimulation(observers=[...])")

    def replay_row(self, record: Any) -> tuple[float, float, bool, float, bool, float]:
        """``(t, dt, on, |u - u_nom|^2, qp_solved, true-geometry min barrier)`` of one record.

        (The recorder computes the same values in batch at each flush; this is the reference.)
        """
        d = np.asarray(record.u, dtype=float) - np.asarray(record.u_nom, dtype=float)
        nc = self._n_collision
        tick = float(record.h[:nc].min()) if nc else math.inf
        hmin = min(tick, float(record.true_min))
        if not math.isfinite(hmin):
            hmin = math.nan
        return (float(record.t), float(record.dt), bool(record.on), sq_sum(d), bool(record.qp_solved), hmin)

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
