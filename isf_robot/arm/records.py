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

from isf_robot.core import SwitchEvent

__all__ = ["ArmStepRecord", "FilterParams", "RunResult"]



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
        dist_min: Smallest true signed distance [m] over the collision pairs and over the
            physics steps of this control step (no margin).
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
    dist_min: float
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


@dataclass(frozen=True)
class FilterParams:
    """Resolved filter parameters of a run.

    Attributes:
        alpha: Linear class-K gain ``alpha(h) = alpha h`` [1/s].
        c: Off-trigger margin of the intermittent filter.
        b: Promotion rate of the intermittent filter [m/s or rad/s].
        d_bar: Tracking-error bound [rad/s].
        d_bar_source: ``"argument"``, ``"config"`` or ``"calibration"``.

    """

    alpha: float
    c: float
    b: float
    d_bar: float
    d_bar_source: str


@dataclass(frozen=True)
class RunResult:
    """Summary of one episode. Metric fields come from :class:`isf_robot.core.MetricsAccumulator`.

    Attributes:
        scene: Scene name.
        filter: Strategy (``nominal``, ``cbf``, ``isf``).
        seed: Episode seed.
        duration_s: Simulated time [s].
        control_steps: Number of control steps.
        physics_steps: Number of physics steps.
        duty_cycle: Fraction of time the filter is on.
        on_switches: Off-to-on switches.
        off_switches: On-to-off switches.
        mean_on_s: Mean complete on period [s] (None: none).
        min_on_s: Shortest complete on period [s].
        mean_off_s: Mean complete off period [s].
        min_off_s: Shortest complete off period [s] (the measured inter-event time).
        max_off_s: Longest complete off period [s].
        intervention: ``sum |u - u_nom|^2 T`` [rad^2/s].
        qp_solves: Control steps with a QP solve.
        min_barrier: Smallest ``dist - margin`` [m], true geometry, all physics steps.
        collisions: Physics steps with some collision barrier below 0.
        min_joint_barrier: Smallest joint-limit barrier [rad] over the control steps.
        goals_reached: Goal arrivals of the nominal task.
        goals_missed: Goals given up after the nominal task's timeout.
        fallbacks: Steps where the filter was infeasible and the arm braked.
        relaxations: Steps where promotions were relaxed (intermittent filter).
        resolves: Steps where a joint-limit row left out of the QP (slack above the keep
            threshold under ``u_nom``) was violated at the solution, so the QP was solved
            again with every row (the pruning never changes the command).
        d_bar: Tracking-error bound used [rad/s].
        d_bar_source: Where it came from.
        alpha: Class-K gain [1/s].
        c: Off-trigger margin.
        b: Promotion rate.
        control_period: Control period T [s].
        timestep: Physics timestep dt [s].
        tracking_error_q99: 99th percentile of ``|q_dot - u|`` at the control ticks [rad/s].
        qp_time_median_us: Median QP solve time [us] (None: no QP), including the
            single-row problems solved in closed form.
        qp_closed_form: QP solves done in closed form (one row, no bounds).
        proxqp_time_median_us: Median time of the solves that went to ProxQP [us].
        wall_s: Wall time of :meth:`ArmSimulation.run` [s] (setup of the episode and the loop;
            not the construction, calibration or scene loading).
        timings: Wall time per phase [s] when timing was requested, else empty.

    """

    scene: str
    filter: str
    seed: int
    duration_s: float
    control_steps: int
    physics_steps: int
    duty_cycle: float
    on_switches: int
    off_switches: int
    mean_on_s: float | None
    min_on_s: float | None
    mean_off_s: float | None
    min_off_s: float | None
    max_off_s: float | None
    intervention: float
    qp_solves: int
    min_barrier: float
    collisions: int
    min_joint_barrier: float
    goals_reached: int
    goals_missed: int
    fallbacks: int
    relaxations: int
    resolves: int
    d_bar: float
    d_bar_source: str
    alpha: float
    c: float
    b: float
    control_period: float
    timestep: float
    tracking_error_q99: float
    qp_time_median_us: float | None
    qp_closed_form: int
    proxqp_time_median_us: float | None
    wall_s: float
    timings: Mapping[str, float] = dataclasses.field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-ready dict."""
        d = dataclasses.asdict(self)
        d["timings"] = dict(self.timings)
        return d
