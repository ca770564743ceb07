"""The engine-free core: barriers, class-K functions, filter QPs, triggers, strategies, impulsive control.

Imports numpy and daqp / qpsolvers / proxsuite only (never mujoco, rerun or scipy); a subprocess test
checks it. Public names are listed in ``_EXPORTS`` (name -> submodule) and load on first use: the
project's one export style (see :mod:`isf_robot._exports`).
"""

from __future__ import annotations

from isf_robot._exports import lazy_exports

_EXPORTS: dict[str, str] = {
    "Barrier": "barrier", "BarrierEval": "barrier", "DiscObstacleBarrier": "barrier", "HalfSpaceBarrier": "barrier",
    "FunctionBarrier": "barrier", "evaluate_barriers": "barrier",
    "ClassK": "class_k", "Linear": "class_k", "Power": "class_k", "CustomClassK": "class_k", "as_class_k": "class_k",
    "IsfError": "exceptions", "ConfigError": "exceptions", "ShapeError": "exceptions", "NonFiniteError": "exceptions",
    "UnknownNameError": "exceptions", "InfeasibleFilterError": "exceptions", "SolverError": "exceptions",
    "PostJumpConditionError": "exceptions", "ZenoError": "exceptions", "IsfWarning": "exceptions",
    "FilterStep": "step", "SafetyFilter": "filters", "IntermittentSafetyFilter": "filters",
    "Observer": "hooks", "Observers": "hooks",
    "JumpEvent": "impulsive", "EventTriggeredImpulsiveController": "impulsive", "ManeuverScheduler": "impulsive",
    "DutyCycleMetrics": "metrics", "FilterStats": "metrics", "compute_metrics": "metrics",
    "MetricsAccumulator": "metrics",
    "miet_bound": "miet", "MietConstants": "miet", "estimate_miet_constants": "miet", "ZenoGuard": "miet",
    "min_interval": "miet", "MietRate": "miet", "estimate_miet_rate": "miet",
    "FilterQP": "qp", "QPResult": "qp", "build_filter_qp": "qp", "project_halfspace": "qp",
    "QPSolver": "qp_solver", "BACKENDS": "qp_solver",
    "StrategyInfo": "strategies", "NominalStrategy": "strategies", "register_strategy": "strategies",
    "strategy_names": "strategies", "strategy_info": "strategies", "make_strategy": "strategies",
    "Strategy": "strategies", "FilterSpec": "spec",
    "SwitchEvent": "switches", "SwitchCounter": "switches",
    "ControlAffineSystem": "system", "SingleIntegrator": "system", "FunctionSystem": "system", "LieData": "system",
    "lie_data": "system",
    "OnOffTrigger": "triggers", "xi_on": "triggers", "xi_tau": "triggers",
    "CentralFilter": "team", "SharedFilter": "team", "AgentTally": "team", "AgentResult": "team",
    "row_agents": "shares", "agent_lie": "shares", "block_matrix": "shares", "SharedRows": "shares",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
