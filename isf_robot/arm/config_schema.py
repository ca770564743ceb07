"""Scene configuration: the frozen dataclasses a scene's TOML file is parsed into.

The schema is documented in ``models/README.md``; :mod:`isf_robot.arm.config_toml` reads the
file into these classes (checking types, shapes and signs) and the obstacle paths of
``[[moving]]`` live in :mod:`isf_robot.arm.paths`. Names of joints, geoms, sites and bodies are
resolved against the MuJoCo model later, in :mod:`isf_robot.arm.scene`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from isf_robot.core.spec import FilterSpec

from .paths import MovingObstacle

__all__ = [
    "RobotConfig",
    "ArmConfig",
    "ObstacleConfig",
    "Goal",
    "TaskConfig",
    "BarrierConfig",
    "GainsConfig",
    "ControlConfig",
    "SceneConfig",
    "LEVELS",
]

LEVELS = ("velocity", "torque")
"""The levels a filter can act at (``[filter] level``; ``--level`` on the command line), the default first."""


@dataclass(frozen=True)
class RobotConfig:
    """The arm: which joints the filter acts on, its end effector and its collision geoms.

    Robot geoms are the union of ``geoms`` and the colliding geoms of ``bodies`` and of the
    ``subtree``, the latter two narrowed to ``geom_group`` when given (see
    :mod:`isf_robot.arm.selection`).

    Attributes:
        joints: Names of the arm's hinge/slide joints, in control order (length n); empty: the
            joints the actuators drive, in actuator order.
        ee_site: Name of the end-effector site (or give ``ee_body``).
        geoms: Names (or ``body[index]`` labels) of robot collision geoms.
        home: Initial joint positions [rad], shape (n,); or the name of a keyframe; ``None``
            for the model's qpos0.
        self_collision: Also build barriers for non-adjacent robot-robot geom pairs.
        bodies: Bodies whose colliding geoms are robot geoms.
        subtree: A body whose subtree's colliding geoms are robot geoms.
        geom_group: Keep only this geom group among the geoms of ``bodies``/``subtree``.
        ee_body: Body carrying the end-effector point (instead of ``ee_site``).
        ee_offset: The end-effector point in ``ee_body``'s frame [m].

    """

    joints: tuple[str, ...] = ()
    ee_site: str | None = None
    geoms: tuple[str, ...] = ()
    home: tuple[float, ...] | str | None = None
    self_collision: bool = False
    bodies: tuple[str, ...] = ()
    subtree: str | None = None
    geom_group: int | None = None
    ee_body: str | None = None
    ee_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ArmConfig:
    """One arm of a scene with several arms (a ``[[arm]]`` table).

    The names below are the model's, prefix included (the file may write them without it; see
    ``models/README.md``). A scene with arms has no ``[robot]`` table: its robot is every arm's
    joints and geoms in ``[[arm]]`` order (:attr:`SceneConfig.robot` is built from them), so the
    single-arm machinery acts on the concatenated joints; its goals are every arm's goals in order.

    Attributes:
        name: The arm's name (unique in the scene).
        prefix: The prefix of the arm's names in the model (e.g. the ``prefix`` of an ``<attach>``).
        joints: The arm's joints in control order.
        geoms: The arm's collision geoms.
        ee_site: The arm's end-effector site.
        home: Initial joint positions [rad], shape (len(joints),); ``None``: the model's qpos0.
        goals: The arm's reaching goals, in order.
        self_collision: Barriers for the non-adjacent pairs of the arm's own geoms too (every arm of a
            scene gives the same value).

    """

    name: str
    prefix: str
    joints: tuple[str, ...]
    geoms: tuple[str, ...]
    ee_site: str
    home: tuple[float, ...] | None
    goals: tuple[Goal, ...]
    self_collision: bool = False


@dataclass(frozen=True)
class ObstacleConfig:
    """Obstacles: geoms on the world body, on static bodies or on mocap bodies.

    Selected like the robot's geoms (names or ``body[index]`` labels, bodies, a subtree,
    narrowed by ``geom_group``); ``geom_group`` alone selects every colliding geom of that
    group that is not a robot geom.

    Attributes:
        geoms: Names (or labels) of the obstacle geoms.
        bodies: Bodies whose colliding geoms are obstacles.
        subtree: A body whose subtree's colliding geoms are obstacles.
        geom_group: Group filter (see above).

    """

    geoms: tuple[str, ...] = ()
    bodies: tuple[str, ...] = ()
    subtree: str | None = None
    geom_group: int | None = None


@dataclass(frozen=True)
class Goal:
    """One end-effector goal of the reaching task.

    Attributes:
        position: Goal position in the world frame [m], shape (3,) (resolved from ``site``
            when the config names a site instead of a position).
        dwell: Time to hold the goal once reached [s].
        site: Name of the site the goal was read from, or ``None``.

    """

    position: tuple[float, float, float]
    dwell: float = 0.0
    site: str | None = None


@dataclass(frozen=True)
class TaskConfig:
    """The nominal task: reach the goals in order.

    Attributes:
        goals: The goals, in order.
        loop: Start again at the first goal after the last one.
        tolerance: Distance [m] below which a goal counts as reached.
        duration: Default episode length [s].

    """

    goals: tuple[Goal, ...]
    loop: bool = True
    tolerance: float = 0.02
    duration: float = 10.0


@dataclass(frozen=True)
class BarrierConfig:
    """Barrier parameters.

    Attributes:
        margin: Safety margin on the robot-obstacle distance [m]: ``h = dist - margin``.
        self_margin: Margin on robot-robot distances [m] (only with ``self_collision``).
        joint_margin: Margin on the joint limits [rad]: ``h = q - q_min - joint_margin``.
        cutoff: Broad-phase cut-off [m]: pairs whose bounding spheres are farther apart than
            this are reported inactive (h from the bounding-sphere distance, zero gradient).

    """

    margin: float = 0.02
    self_margin: float = 0.01
    joint_margin: float = 0.05
    cutoff: float = 0.3


@dataclass(frozen=True)
class GainsConfig:
    """Gains of the nominal and low-level controllers.

    Attributes:
        task_kp: Task-space proportional gain of the reaching controller [1/s].
        dls_damping: Damping of the damped-least-squares inverse [m].
        max_ee_speed: Cap on the commanded end-effector speed [m/s].
        max_joint_speed: Cap on the commanded joint speeds [rad/s].
        max_joint_acc: Cap on the change of the nominal command [rad/s^2].
        joint_kp: Joint-space proportional gain of the joint PD nominal [1/s].
        tracking_kp: Low-level tracking gain per joint (or one for all); its unit depends on the
            low-level controller that reads it.
        tracking_kd: Low-level damping gain per joint (or one for all).
        goal_timeout: A goal not reached within this time is given up [s].
        extra: The numeric entries of the ``[gains.extra]`` table, by key (read-only): numbers for
            the user's own controllers, which the checks cannot know.

    """

    task_kp: float = 4.0
    dls_damping: float = 0.05
    max_ee_speed: float = 0.5
    max_joint_speed: float = 2.0
    max_joint_acc: float = 10.0
    joint_kp: float = 2.0
    tracking_kp: tuple[float, ...] = (100.0,)
    tracking_kd: tuple[float, ...] = (20.0,)
    goal_timeout: float = 4.0
    extra: Mapping[str, float | tuple[float, ...]] = field(default_factory=dict)


@dataclass(frozen=True)
class ControlConfig:
    """Control timing.

    Attributes:
        period: Control period [s]; an integer multiple of the model's physics timestep.

    """

    period: float = 0.002


@dataclass(frozen=True)
class SceneConfig:
    """Everything a scene's TOML file says.

    Attributes:
        name: Scene name.
        description: One-line description.
        model: MJCF file name, relative to the TOML file's folder.
        robot: The arm.
        obstacles: The obstacle geoms.
        task: The reaching task.
        barrier: Barrier margins and broad-phase cut-off.
        gains: Controller gains.
        filter: Default safety-filter parameters (``[filter]``: any field of :class:`~isf_robot.core.FilterSpec`;
            ``d_bar = 0``: calibrate it).
        control: Control timing.
        moving: Mocap obstacles with known paths.
        arms: The arms of a scene with several (``[[arm]]`` tables); empty for one arm (``[robot]``).
        source: The TOML file this was read from, or ``None``.
        level: The level the filter acts at by default (``[filter] level``, one of :data:`LEVELS`):
            ``"velocity"`` (joint velocities on ``q_dot = u + d``) or ``"torque"`` (joint torques on the
            full dynamics, :mod:`isf_robot.arm.torque_sim`).

    """

    name: str
    description: str
    model: str
    robot: RobotConfig
    obstacles: ObstacleConfig
    task: TaskConfig
    barrier: BarrierConfig = BarrierConfig()
    gains: GainsConfig = GainsConfig()
    filter: FilterSpec = FilterSpec()
    control: ControlConfig = ControlConfig()
    moving: tuple[MovingObstacle, ...] = ()
    source: Path | None = None
    arms: tuple[ArmConfig, ...] = ()
    level: str = "velocity"
