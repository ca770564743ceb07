"""What a run of the arm simulation reports: per-step records for observers and the summary.

:class:`ArmStepRecord` is what observers (e.g. the Rerun recorder) receive at every control
step; :class:`RunResult` is the summary of an episode (its metric fields come from
:class:`isf_robot.core.MetricsAccumulator`); :class:`FilterParams` the resolved filter
parameters. Re-exported by :mod:`isf_robot.arm.sim`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from isf_robot.core import DutyCycleMetrics, FilterSpec, FilterStats, SwitchEvent
from isf_robot.core.chatter import chatter_advice
from isf_robot.core.spec import PARAMETERS
from isf_robot.core.strategies import strategy_info

__all__ = ["ArmStepRecord", "FilterParams", "RunResult", "INTERMITTENT_KEYS"]

INTERMITTENT_KEYS = tuple(p.name for p in PARAMETERS if p.intermittent and p.name not in ("c", "b"))
"""Keys of :meth:`FilterParams.as_dict` that only an intermittent strategy uses."""



@dataclass(frozen=True, eq=False)
class ArmStepRecord:
    """What an observer sees of one control step (built only when an observer is attached).

    Arrays are copies owned by the record. k is the number of barriers (collision pairs
    first, then joint-limit rows), n the number of arm joints.

    Attributes:
        t: Time at the start of the step [s].
        dt: Control period [s].
        q: Arm joint positions [rad], shape (n,).
        qd: Arm joint velocities [rad/s], shape (n,).
        u: Applied command [rad/s], shape (n,).
        u_nom: Nominal command [rad/s], shape (n,).
        on: Filter mode in this step (cbf: a constraint active).
        h_min: Smallest barrier value at ``t`` over all k barriers.
        xi_min: Smallest ``Xi_on`` of the barriers the filter saw (inf for ``nominal``).
        true_min: Smallest barrier value ``dist - margin`` [m] of the collision pairs on the true
            geometry (each pair's own margin) over the physics steps of this control step.
        qp_solved: Whether a QP was solved in this step.
        h: Barrier values, shape (k,) ([m] for pairs, [rad] for joint limits).
        names: Barrier names, length k (the same tuple every step).
        closest: Names of the (up to) three collision pairs with the smallest h, closest first.
        witness: Witness points of the pairs within the cut-off [m], shape (a, 2, 3)
            (on the robot geom, on the other geom).
        witness_names: Names of those pairs, length a.
        mocap_pos: Mocap body positions [m], shape (nmocap, 3).
        mocap_quat: Mocap body orientations (w, x, y, z), shape (nmocap, 4).
        ee_pos: End-effector position [m], shape (3,).
        goal_index: Index of the goal pursued by the nominal task.
        goal_pos: That goal's position [m], shape (3,) (NaN for non-reaching nominals).
        event: The switch at this step, if any.
        fallback: Whether the braking fallback was applied.
        relaxed: Names of barriers whose promotion was relaxed in this step.

    """

    t: float
    dt: float
    q: np.ndarray
    qd: np.ndarray
    u: np.ndarray
    u_nom: np.ndarray
    on: bool
    h_min: float
    xi_min: float
    true_min: float
    qp_solved: bool
    h: np.ndarray
    names: tuple[str, ...]
    closest: tuple[str, ...]
    witness: np.ndarray
    witness_names: tuple[str, ...]
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    ee_pos: np.ndarray
    goal_index: int
    goal_pos: np.ndarray
    event: SwitchEvent | None = None
    fallback: bool = False
    relaxed: tuple[str, ...] = ()

    @property
    def dist_min(self) -> float:
        """Gone: the record carries :attr:`true_min`, the smallest ``dist - margin`` (each pair's own margin)."""
        raise AttributeError("ArmStepRecord.dist_min is now true_min: the smallest barrier value dist - margin over "
                             "the step's physics steps, each pair with its own margin (not a distance)")


@dataclass(frozen=True)
class FilterParams(FilterSpec):
    """Resolved filter parameters of a run (:func:`isf_robot.arm.resolve_params`).

    A :class:`~isf_robot.core.FilterSpec` and where its ``d_bar`` came from.

    Attributes:
        d_bar_source: ``"argument"``, ``"config"`` or ``"calibration"`` (``+loop`` when the in-loop
            calibration raised it).

    """

    d_bar_source: str = "argument"

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (``d_bar``, its source, then :meth:`~isf_robot.core.FilterSpec.as_info`)."""
        info = self.as_info()
        return {"d_bar": info.pop("d_bar"), "d_bar_source": self.d_bar_source, **info}


@dataclass(frozen=True)
class RunResult:
    """Summary of one episode: the core's metrics and solver figures plus the arm's own.

    Attributes:
        scene: Scene name.
        filter: Strategy name.
        seed: Episode seed (-1: the scene exactly as configured).
        physics_steps: States the safety monitor checked: the start and every physics step after it (steps + 1).
        metrics: Duty cycle, switches, on/off periods, intervention, QP solves
            (:class:`~isf_robot.core.DutyCycleMetrics`).
        stats: Fallbacks, relaxations, re-solves, closed forms, QP times
            (:class:`~isf_robot.core.FilterStats`).
        params: The filter parameters used.
        min_barrier: Smallest ``dist - margin`` [m], true geometry, all physics steps.
        collisions: Physics steps with some collision barrier below 0.
        min_joint_barrier: Smallest joint-limit barrier [rad] over the control steps.
        goals_reached: Goal arrivals of the nominal task.
        goals_missed: Goals given up after the nominal task's timeout.
        goal_times: Time [s] of every goal arrival, in order (``goal_times_s`` in :meth:`as_dict`).
        control_period: Control period T [s].
        timestep: Physics timestep dt [s].
        tracking_error_q99: 99th percentile of ``|q_dot - u|`` at the control ticks [rad/s];
            ``d_bar_covered`` in :meth:`as_dict` says whether the ``d_bar`` in use covers it (if
            not, the robust term does not cover the tracking error this strategy produces, and
            safety rests on the clearance the filter builds). An intermittent strategy's
            ``chatter`` in :meth:`as_dict` is one line when off periods fell under 0.25 s, with the
            change that would stop it (:func:`isf_robot.core.chatter.chatter_advice`), else ``None``.
        wall_s: Wall time of :meth:`ArmSimulation.run` [s] (setup of the episode and the loop;
            not the construction, calibration or scene loading).
        timings: Wall time per phase [s] when timing was requested, else empty.
        maneuvers: With maneuvers by shooting (``shoot > 0``): ``(choices, raised)``, how many times the
            filter chose its push level and how many of those chose one above ``b``
            (:class:`~isf_robot.core.shooting.ManeuverShooter`); ``shoot_choices`` and ``shoot_raised``
            in :meth:`as_dict`. ``None`` without shooting.

    The fields of ``metrics``, ``stats`` and ``params`` read as attributes of the result too
    (``result.duty_cycle``), and :meth:`as_dict` flattens them into one JSON object.

    """

    scene: str
    filter: str
    seed: int
    physics_steps: int
    metrics: DutyCycleMetrics
    stats: FilterStats
    params: FilterParams
    min_barrier: float
    collisions: int
    min_joint_barrier: float
    goals_reached: int
    goals_missed: int
    control_period: float
    timestep: float
    tracking_error_q99: float
    wall_s: float
    timings: Mapping[str, float] = dataclasses.field(default_factory=dict)
    goal_times: tuple[float, ...] = ()
    maneuvers: tuple[int, int] | None = None

    def __getattr__(self, name: str) -> Any:
        for part in ("metrics", "stats", "params"):
            obj = object.__getattribute__(self, part)
            if name in obj.__dataclass_fields__:
                return getattr(obj, name)
        raise AttributeError(f"RunResult has no attribute {name!r}")

    def as_dict(self) -> dict[str, Any]:
        """One flat JSON-ready dict (the ``--json`` output of ``isf-robot run``)."""
        out: dict[str, Any] = {"scene": self.scene, "filter": self.filter, "seed": self.seed}
        m = self.metrics.as_dict()
        out["duration_s"], out["control_steps"] = m.pop("duration_s"), m.pop("control_steps")
        out["physics_steps"] = self.physics_steps
        out.update(m)
        out.update(min_barrier=self.min_barrier, collisions=self.collisions,
                   min_joint_barrier=self.min_joint_barrier, goals_reached=self.goals_reached,
                   goals_missed=self.goals_missed, goal_times_s=list(self.goal_times))
        st = self.stats.as_dict()
        out.update(fallbacks=st.pop("fallbacks"), relaxations=st.pop("relaxations"), resolves=st.pop("resolves"))
        params = self.params.as_dict()
        if not strategy_info(self.filter).intermittent:  # the intermittent options do not apply
            params = {k: v for k, v in params.items() if k not in INTERMITTENT_KEYS}
        out.update(params)
        out.update(control_period=self.control_period, timestep=self.timestep,
                   tracking_error_q99=self.tracking_error_q99,
                   d_bar_covered=bool(self.tracking_error_q99 <= self.params.d_bar))
        if strategy_info(self.filter).intermittent:
            out["chatter"] = chatter_advice(m, self.params, self.control_period)
        if self.maneuvers is not None:
            out["shoot_choices"], out["shoot_raised"] = self.maneuvers
        out.update(st)
        out.update(wall_s=self.wall_s, timings=dict(self.timings))
        return out
