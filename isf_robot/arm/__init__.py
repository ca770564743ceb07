"""The MuJoCo layer: scenes and models, collision barriers, nominal control, simulation.

Public names are listed in ``_EXPORTS`` (name -> the submodule that defines it) and load on first
use: the project's one export style (see :mod:`isf_robot._exports`). So ``import isf_robot.arm``
alone imports no submodule, and ``from isf_robot.arm import Scene`` imports only what it needs.
"""

from __future__ import annotations

from isf_robot._exports import lazy_exports

_EXPORTS: dict[str, str] = {
    # scenes and their config (the TOML schema, its reader, obstacle paths)
    "Scene": "scene", "SceneInfo": "scene", "list_scenes": "scene", "load_scene": "scene",
    "load_scene_from_files": "scene", "build_scene": "build",
    "SceneConfig": "config_schema", "RobotConfig": "config_schema", "ObstacleConfig": "config_schema",
    "Goal": "config_schema", "TaskConfig": "config_schema", "BarrierConfig": "config_schema",
    "GainsConfig": "config_schema", "ControlConfig": "config_schema", "ArmConfig": "config_schema",
    "ArmInfo": "arms", "arm_scene": "one_arm",
    "load_config": "config_toml", "parse_config": "config_toml",
    "CirclePath": "paths", "LinearBouncePath": "paths", "ObstaclePath": "paths", "MovingObstacle": "paths",
    # barriers
    "BarrierBatch": "batch", "stack_batches": "batch",
    "CollisionPairs": "pairs", "collision_pairs": "pairs",
    "CollisionBarriers": "collision", "JointLimitBarriers": "joint_limits",
    "Clearance": "clearance", "min_distance": "clearance",
    # nominal control, low-level tracking, calibration
    "NominalController": "nominal", "GoalSequence": "nominal", "ReachingController": "nominal",
    "JointPDController": "nominal", "VelocityTracker": "lowlevel",
    "make_actuation": "actuation", "ServoTracker": "actuation", "TorqueTracker": "actuation",
    "ActuatorInfo": "actuation", "actuator_info": "actuation",
    "Finding": "diagnostics", "check_scene": "diagnostics", "check_calibration": "diagnostics",
    "run_findings": "diagnostics", "starter_toml": "starter",
    "Calibration": "calibration", "calibrate_d_bar": "calibration", "clear_calibration_cache": "calibration",
    # simulation: episodes, the loop, its records
    "EpisodeSetup": "episode", "check_control_period": "episode", "episode_setup": "episode",
    "ArmSimulation": "sim", "run_episode": "sim", "resolve_params": "params",
    "ArmStepRecord": "records", "FilterParams": "records", "RunResult": "records",
    # several arms: the team's nominal, the loop with a coordination, its result
    "TeamReaching": "team_nominal", "MultiArmSimulation": "multi_arm", "ArmRunResult": "multi_arm",
    "run_team": "multi_arm", "COORDINATIONS": "multi_arm",
    # the torque level: second-order barriers on the full dynamics, computed-torque nominal, its d_bar
    "TorqueSimulation": "torque_sim", "TorqueRunResult": "torque_sim", "run_torque_episode": "torque_sim",
    "resolve_torque_params": "torque_sim", "calibrate_torque_d_bar": "torque_calibration",
    "SecondOrderRows": "second_order", "psi_lie": "second_order", "ArmDynamics": "dynamics",
    "DynamicsTerms": "dynamics", "torque_limits": "dynamics", "TorqueNominal": "torque_nominal",
    # comparisons
    "SceneSpec": "compare", "Comparison": "compare", "compare_strategies": "compare", "format_table": "compare",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
