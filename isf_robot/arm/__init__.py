"""The MuJoCo layer: scenes and models, collision barriers, nominal control, simulation.

Scenes and barriers (:mod:`.scene`, :mod:`.config`, :mod:`.barriers`) are listed first;
other modules append their names below.
"""

from .barriers import (
    BarrierBatch,
    Clearance,
    CollisionBarriers,
    CollisionPairs,
    JointLimitBarriers,
    collision_pairs,
    min_distance,
    stack_batches,
)
from .config import (
    BarrierConfig,
    CirclePath,
    ControlConfig,
    FilterConfig,
    GainsConfig,
    Goal,
    LinearBouncePath,
    MovingObstacle,
    ObstacleConfig,
    ObstaclePath,
    RobotConfig,
    SceneConfig,
    TaskConfig,
    load_config,
    parse_config,
)
from .scene import Scene, SceneInfo, list_scenes, load_scene, load_scene_from_files

__all__ = [
    # scenes and config
    "Scene",
    "SceneInfo",
    "list_scenes",
    "load_scene",
    "load_scene_from_files",
    "SceneConfig",
    "RobotConfig",
    "ObstacleConfig",
    "Goal",
    "TaskConfig",
    "BarrierConfig",
    "GainsConfig",
    "FilterConfig",
    "ControlConfig",
    "CirclePath",
    "LinearBouncePath",
    "ObstaclePath",
    "MovingObstacle",
    "load_config",
    "parse_config",
    # barriers
    "BarrierBatch",
    "stack_batches",
    "CollisionPairs",
    "collision_pairs",
    "CollisionBarriers",
    "JointLimitBarriers",
    "Clearance",
    "min_distance",
]

# nominal control, low-level tracking, calibration, simulation (appended by the sim layer)
from .calibration import Calibration, calibrate_d_bar, clear_calibration_cache  # noqa: E402
from .compare import Comparison, SceneSpec, compare_strategies, format_table  # noqa: E402
from .lowlevel import VelocityTracker  # noqa: E402
from .nominal import (  # noqa: E402
    GoalSequence,
    JointPDController,
    NominalController,
    ReachingController,
)
from .sim import (  # noqa: E402
    STRATEGIES,
    ArmSimulation,
    ArmStepRecord,
    EpisodeSetup,
    FilterParams,
    RunResult,
    check_control_period,
    episode_setup,
    run_episode,
)

__all__ += [
    # nominal control and tracking
    "NominalController",
    "GoalSequence",
    "ReachingController",
    "JointPDController",
    "VelocityTracker",
    "Calibration",
    "calibrate_d_bar",
    "clear_calibration_cache",
    # simulation
    "STRATEGIES",
    "ArmSimulation",
    "ArmStepRecord",
    "EpisodeSetup",
    "FilterParams",
    "RunResult",
    "check_control_period",
    "episode_setup",
    "run_episode",
    # comparisons
    "SceneSpec",
    "Comparison",
    "compare_strategies",
    "format_table",
]
