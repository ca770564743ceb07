"""One arm of a scene with several, as a single-arm scene (for its nominal controller and its checks)."""

from __future__ import annotations

import dataclasses

from .config_schema import RobotConfig
from .scene import Scene

__all__ = ["arm_scene"]


def arm_scene(scene: Scene, i: int) -> Scene:
    """Arm ``i`` of ``scene`` as a single-arm scene: its joints, geoms, end effector and goals.

    Its config's ``[robot]`` and ``[task] goals`` are the arm's (so goal messages name the arm's sites);
    the model, obstacles, gains and filter are the scene's.
    """
    a, cfg = scene.arms[i], scene.config
    j, g, model, arm = a.joints, a.goals, scene.model, cfg.arms[i]
    robot = RobotConfig(joints=arm.joints, ee_site=arm.ee_site, geoms=arm.geoms, home=arm.home,
                        self_collision=arm.self_collision)
    config = dataclasses.replace(cfg, robot=robot, task=dataclasses.replace(cfg.task, goals=arm.goals), arms=())
    return dataclasses.replace(
        scene, name=f"{scene.name}:{a.name}", config=config, joint_ids=scene.joint_ids[j],
        qpos_adr=scene.qpos_adr[j], dof_adr=scene.dof_adr[j], actuator_ids=scene.actuator_ids[j],
        joint_range=scene.joint_range[j], torque_limit=scene.torque_limit[j], home=scene.home[j],
        robot_geom_ids=a.geom_ids, ee_site_id=a.ee_site_id, ee_body_id=int(model.site_bodyid[a.ee_site_id]),
        ee_offset=model.site_pos[a.ee_site_id].copy(), goal_positions=scene.goal_positions[g],
        goal_dwell=scene.goal_dwell[g], arm_joint_names=scene.joint_names[j], arms=())
