"""The arms of a scene with several: which joints, geoms, end effector and goals are each arm's.

A scene with ``[[arm]]`` tables (:class:`~isf_robot.arm.config_schema.ArmConfig`) is one robot for
the single-arm machinery: its joints are every arm's joints in ``[[arm]]`` order, its geoms every
arm's geoms, its goals every arm's goals. :class:`ArmInfo` says which part of each belongs to which
arm, so that a nominal controller, a filter or a metric can act per arm
(:func:`isf_robot.arm.one_arm.arm_scene` makes one arm a single-arm scene).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, UnknownNameError

from .config_schema import SceneConfig

__all__ = ["ArmInfo", "resolve_arms", "geom_arms"]


@dataclass(frozen=True, eq=False)
class ArmInfo:
    """One arm of a scene, resolved against the model.

    Attributes:
        name: The arm's name.
        joints: The arm's columns in the scene's joint order (a slice of length n_i).
        goals: The arm's rows of the scene's ``goal_positions`` (a slice).
        geom_ids: The arm's collision geom ids, shape (r_i,).
        ee_site_id: The arm's end-effector site id.

    """

    name: str
    joints: slice
    goals: slice
    geom_ids: np.ndarray
    ee_site_id: int

    @property
    def n_joints(self) -> int:
        """Number of the arm's joints."""
        return int(self.joints.stop - self.joints.start)


def resolve_arms(model: mujoco.MjModel, cfg: SceneConfig) -> tuple[ArmInfo, ...]:
    """The arms of ``cfg`` (empty for a single-arm scene), with the model's ids.

    Raises:
        UnknownNameError: An arm names a geom or site the model lacks (the message lists the valid ones).
        ConfigError: Two arms share a geom.

    """
    out: list[ArmInfo] = []
    j = g = 0
    seen: dict[int, str] = {}
    for arm in cfg.arms:
        ids = []
        for name in arm.geoms:
            gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
            if gid < 0:
                valid = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, i) for i in range(model.ngeom)]
                raise UnknownNameError("geom", name, [v for v in valid if v])
            if gid in seen:
                raise ConfigError(f"geom {name!r} is listed for arm {seen[gid]!r} and arm {arm.name!r}")
            seen[gid] = arm.name
            ids.append(gid)
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, arm.ee_site)
        if site < 0:
            valid = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, i) for i in range(model.nsite)]
            raise UnknownNameError("site", arm.ee_site, [v for v in valid if v])
        out.append(ArmInfo(arm.name, slice(j, j + len(arm.joints)), slice(g, g + len(arm.goals)),
                           np.array(ids, dtype=np.int64), int(site)))
        j, g = j + len(arm.joints), g + len(arm.goals)
    return tuple(out)


def geom_arms(arms: tuple[ArmInfo, ...], geom_ids: np.ndarray) -> np.ndarray:
    """The arm index of each geom in ``geom_ids`` (-1: no arm's), shape like ``geom_ids``."""
    out = np.full(np.shape(geom_ids), -1, dtype=np.int64)
    for i, arm in enumerate(arms):
        out[np.isin(geom_ids, arm.geom_ids)] = i
    return out
