"""The engine-free core: barriers, class-K functions, filter QPs, triggers, impulsive control.

Imports numpy and qpsolvers/proxsuite only (never mujoco or rerun).
"""

from .barrier import Barrier, BarrierEval, DiscObstacleBarrier, FunctionBarrier, HalfSpaceBarrier, evaluate_barriers
from .class_k import ClassK, CustomClassK, Linear, Power, as_class_k
from .exceptions import (
    ConfigError,
    InfeasibleFilterError,
    IsfError,
    IsfWarning,
    NonFiniteError,
    PostJumpConditionError,
    ShapeError,
    SolverError,
    UnknownNameError,
    ZenoError,
)
from .filters import FilterStep, IntermittentSafetyFilter, SafetyFilter
from .hooks import Observer, Observers
from .impulsive import EventTriggeredImpulsiveController, JumpEvent, ManeuverScheduler
from .metrics import DutyCycleMetrics, FilterStats, MetricsAccumulator, compute_metrics
from .miet import MietConstants, ZenoGuard, estimate_miet_constants, miet_bound, min_interval
from .qp import FilterQP, QPResult, build_filter_qp, project_halfspace
from .qp_solver import QPSolver
from .system import ControlAffineSystem, FunctionSystem, LieData, SingleIntegrator, lie_data
from .triggers import OnOffTrigger, SwitchEvent, xi_on, xi_tau

__all__ = [
    "Barrier", "BarrierEval", "DiscObstacleBarrier", "FunctionBarrier", "HalfSpaceBarrier", "evaluate_barriers",
    "ClassK", "CustomClassK", "Linear", "Power", "as_class_k",
    "ConfigError", "InfeasibleFilterError", "IsfError", "IsfWarning", "NonFiniteError",
    "PostJumpConditionError", "ShapeError", "SolverError", "UnknownNameError", "ZenoError",
    "FilterStep", "IntermittentSafetyFilter", "SafetyFilter",
    "Observer", "Observers",
    "EventTriggeredImpulsiveController", "JumpEvent", "ManeuverScheduler",
    "DutyCycleMetrics", "FilterStats", "MetricsAccumulator", "compute_metrics",
    "MietConstants", "ZenoGuard", "estimate_miet_constants", "miet_bound", "min_interval",
    "FilterQP", "QPResult", "QPSolver", "build_filter_qp", "project_halfspace",
    "ControlAffineSystem", "FunctionSystem", "LieData", "SingleIntegrator", "lie_data",
    "OnOffTrigger", "SwitchEvent", "xi_on", "xi_tau",
]
