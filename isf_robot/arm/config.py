"""Scene configuration: the TOML file beside each MJCF scene, parsed into frozen dataclasses.

This module is the public face of three smaller ones, and every name stays importable from here:

* :mod:`.config_schema`: the dataclasses (:class:`SceneConfig` and its sections);
* :mod:`.config_toml`: the TOML reader (:func:`parse_config`, :func:`load_config`);
* :mod:`.paths`: obstacle paths of ``[[moving]]`` (:class:`CirclePath`, :class:`LinearBouncePath`).

The schema is documented in ``models/README.md``. Parsing checks types, shapes and signs and
rejects unknown keys and tables (the message lists the valid ones and the closest); names of joints, geoms, sites and
bodies are resolved against the MuJoCo model later, in :mod:`isf_robot.arm.scene`.
"""

from __future__ import annotations

from .config_schema import (
    BarrierConfig,
    ControlConfig,
    GainsConfig,
    Goal,
    ObstacleConfig,
    RobotConfig,
    SceneConfig,
    TaskConfig,
)
from .config_toml import load_config, parse_config
from .paths import CirclePath, LinearBouncePath, MovingObstacle, ObstaclePath

__all__ = [
    "RobotConfig",
    "ObstacleConfig",
    "Goal",
    "TaskConfig",
    "BarrierConfig",
    "GainsConfig",
    "ControlConfig",
    "CirclePath",
    "LinearBouncePath",
    "ObstaclePath",
    "MovingObstacle",
    "SceneConfig",
    "parse_config",
    "load_config",
]
