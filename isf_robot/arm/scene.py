"""Scenes: an MJCF model plus its TOML config, with every name resolved to MuJoCo ids.

A scene called ``name`` is the pair ``models/<name>.xml`` (or the file the config's
``[scene] model`` names) and ``models/<name>.toml``; the folder is
:func:`isf_robot.paths.models_dir`.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, UnknownNameError
from isf_robot.paths import models_dir

from .arms import ArmInfo, resolve_arms
from .config_schema import SceneConfig
from .config_toml import load_config
from .paths import path_track
from .selection import actuated_joints, body_id, geom_label, keyframe_home, select_geoms

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["SceneInfo", "Scene", "list_scenes", "load_scene", "load_scene_from_files"]


@dataclass(frozen=True)
class SceneInfo:
    """Name and one-line description of a shipped scene."""

    name: str
    description: str


def _names(model: mujoco.MjModel, obj: mujoco.mjtObj, count: int) -> list[str]:
    return [mujoco.mj_id2name(model, obj, i) or "" for i in range(count)]


def _lookup(model: mujoco.MjModel, obj: mujoco.mjtObj, kind: str, name: str, count: int) -> int:
    i = mujoco.mj_name2id(model, obj, name)
    if i < 0:
        raise UnknownNameError(kind, name, [n for n in _names(model, obj, count) if n])
    return int(i)


@dataclass(frozen=True, eq=False)
class Scene:
    """A loaded scene: the model, its config and the resolved ids.

    Arrays are indexed in the config's joint order (n arm joints) unless stated otherwise.

    Attributes:
        name: Scene name.
        model: The compiled MuJoCo model.
        config: The parsed config.
        xml_path: The MJCF file (``None`` for a scene built from an ``MjModel``).
        joint_ids: Arm joint ids, shape (n,).
        qpos_adr: Addresses of the arm joints in ``qpos``, shape (n,).
        dof_adr: Addresses of the arm joints in ``qvel`` (dof indices), shape (n,).
        actuator_ids: Id of the actuator driving each arm joint (-1: none), shape (n,).
        joint_range: Joint limits [rad or m], shape (n, 2); ``(-inf, inf)`` when unlimited.
        torque_limit: Largest actuator torque [Nm] per joint (``forcerange``, and ``ctrlrange``
            of a motor; inf: none), shape (n,).
        home: Initial arm joint positions, shape (n,).
        robot_geom_ids: Robot collision geom ids, shape (r,).
        obstacle_geom_ids: Obstacle geom ids, shape (o,).
        ee_site_id: End-effector site id, or -1 when the config gives ``ee_body``.
        moving_body_ids: Body id of each ``[[moving]]`` obstacle, shape (p,).
        moving_mocap_ids: Mocap index (row of ``data.mocap_pos``) of each, shape (p,).
        goal_positions: Goal positions in the world frame [m], shape (g, 3).
        goal_dwell: Dwell time per goal [s], shape (g,).
        arm_joint_names: Arm joint names in control order (the config's, or the actuated joints).
        ee_body_id: Body carrying the end-effector point (the site's body for ``ee_site``).
        ee_offset: The end-effector point in that body's frame [m], shape (3,).
        arms: Each arm's joints, geoms, end effector and goals in a scene with several arms
            (``[[arm]]`` tables); empty for one arm.

    """

    name: str
    model: mujoco.MjModel
    config: SceneConfig
    xml_path: Path | None
    joint_ids: np.ndarray
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    actuator_ids: np.ndarray
    joint_range: np.ndarray
    torque_limit: np.ndarray
    home: np.ndarray
    robot_geom_ids: np.ndarray
    obstacle_geom_ids: np.ndarray
    ee_site_id: int
    moving_body_ids: np.ndarray
    moving_mocap_ids: np.ndarray
    goal_positions: np.ndarray
    goal_dwell: np.ndarray
    arm_joint_names: tuple[str, ...] = ()
    ee_body_id: int = -1
    ee_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    arms: tuple[ArmInfo, ...] = ()

    @property
    def n_joints(self) -> int:
        """Number of arm joints n (the filter's input dimension)."""
        return int(self.joint_ids.shape[0])

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Arm joint names in control order."""
        return self.arm_joint_names or self.config.robot.joints

    def ee_position(self, data: mujoco.MjData) -> np.ndarray:
        """End-effector position [m], shape (3,), from the kinematics in ``data``."""
        if self.ee_site_id >= 0:
            return data.site_xpos[self.ee_site_id]
        b = self.ee_body_id
        return data.xpos[b] + data.xmat[b].reshape(3, 3) @ self.ee_offset

    def ee_jacobian(self, data: mujoco.MjData, jacp: np.ndarray) -> None:
        """Write the end effector's translational Jacobian, shape (3, nv), into ``jacp``."""
        if self.ee_site_id >= 0:
            mujoco.mj_jacSite(self.model, data, jacp, None, self.ee_site_id)
        else:
            mujoco.mj_jac(self.model, data, jacp, None, self.ee_position(data), self.ee_body_id)

    def set_moving_obstacles(self, data: mujoco.MjData, t: float) -> None:
        """Write the moving obstacles' positions at time ``t`` [s] into ``data.mocap_pos``.

        Positions come from :func:`isf_robot.arm.paths.path_track` (the same numbers as a
        precomputed track at that time).

        Kinematics (``mj_kinematics``/``mj_forward``/``mj_step``) must run afterwards for
        ``geom_xpos`` to follow.
        """
        for mocap, mv in zip(self.moving_mocap_ids, self.config.moving):
            data.mocap_pos[mocap] = path_track(mv.path, t)[0][0]

    def mocap_velocities(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Linear and angular velocities of every mocap body at time ``t`` [s].

        Returns:
            ``(lin, ang)``, each shape (nmocap, 3), in [m/s] and [rad/s] (world frame);
            rows of mocap bodies without a path are zero. Pass them to
            :meth:`isf_robot.arm.CollisionBarriers.evaluate` for ``dh/dt``.

        """
        lin = np.zeros((self.model.nmocap, 3))
        for mocap, mv in zip(self.moving_mocap_ids, self.config.moving):
            lin[mocap] = path_track(mv.path, t)[1][0]
        return lin, np.zeros((self.model.nmocap, 3))

    def make_data(self, t: float = 0.0) -> mujoco.MjData:
        """A fresh ``MjData`` at the home configuration, obstacles at time ``t``, kinematics done."""
        data = mujoco.MjData(self.model)
        data.qpos[self.qpos_adr] = self.home
        data.time = t
        self.set_moving_obstacles(data, t)
        mujoco.mj_forward(self.model, data)
        return data


def _torque_limit(model: mujoco.MjModel, a: int) -> float:
    """Largest joint torque actuator ``a`` can give [N m].

    ``forcerange`` x gear, and for a motor
    (no bias) also ``ctrlrange`` x gain x gear; ``inf`` when unlimited.
    """
    gear = abs(float(model.actuator_gear[a, 0]))
    lim = np.inf
    if model.actuator_forcelimited[a]:
        lim = float(np.max(np.abs(model.actuator_forcerange[a]))) * gear
    if (model.actuator_ctrllimited[a]
            and int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_NONE)):
        gain = abs(float(model.actuator_gainprm[a, 0]))
        lim = min(lim, float(np.max(np.abs(model.actuator_ctrlrange[a]))) * gain * gear)
    return float(lim)


def _resolve(model: mujoco.MjModel, cfg: SceneConfig, xml_path: Path | None) -> Scene:
    origin = str(cfg.source) if cfg.source is not None else "<config>"
    jt = mujoco.mjtJoint
    joint_ids = []
    joint_names = cfg.robot.joints or tuple(actuated_joints(model))
    if not joint_names:
        raise ConfigError(f"{origin}: [robot] joints not given and no actuator drives a hinge or slide "
                          "joint; list the arm joints")
    for name in joint_names:
        j = _lookup(model, mujoco.mjtObj.mjOBJ_JOINT, "joint", name, model.njnt)
        if int(model.jnt_type[j]) not in (int(jt.mjJNT_HINGE), int(jt.mjJNT_SLIDE)):
            raise ConfigError(f"{origin}: [robot] joint {name!r} must be a hinge or slide joint")
        joint_ids.append(j)
    joint_ids_a = np.array(joint_ids, dtype=np.int32)
    qpos_adr = model.jnt_qposadr[joint_ids_a].astype(np.int32)
    dof_adr = model.jnt_dofadr[joint_ids_a].astype(np.int32)

    rng = np.where(model.jnt_limited[joint_ids_a, None].astype(bool),
                   model.jnt_range[joint_ids_a], np.array([-np.inf, np.inf]))
    act = np.full(len(joint_ids), -1, dtype=np.int32)
    tau = np.full(len(joint_ids), np.inf)
    for a in range(model.nu):
        if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT):
            hit = np.nonzero(joint_ids_a == model.actuator_trnid[a, 0])[0]
            if hit.size:
                act[hit[0]] = a
                tau[hit[0]] = _torque_limit(model, a)

    rc, oc = cfg.robot, cfg.obstacles
    robot = select_geoms(model, geoms=rc.geoms, bodies=rc.bodies, subtree=rc.subtree,
                         geom_group=rc.geom_group, origin=origin, where="robot")
    obst = select_geoms(model, geoms=oc.geoms, bodies=oc.bodies, subtree=oc.subtree,
                        geom_group=oc.geom_group, exclude=robot, all_if_group=True,
                        origin=origin, where="obstacles")
    both = sorted(geom_label(model, g) for g in set(robot.tolist()) & set(obst.tolist()))
    if both:
        raise ConfigError(f"{origin}: geoms {both} are listed as robot and as obstacle")
    for g in obst:
        weld = model.body_weldid[model.geom_bodyid[g]]
        if weld != 0 and model.body_mocapid[weld] < 0:
            raise ConfigError(
                f"{origin}: obstacle geom {geom_label(model, g)!r} must be on the world body, a static "
                "body or a mocap body (its body has degrees of freedom)"
            )
    if rc.ee_site is not None:
        site = _lookup(model, mujoco.mjtObj.mjOBJ_SITE, "site", rc.ee_site, model.nsite)
        ee_body, ee_offset = int(model.site_bodyid[site]), model.site_pos[site].copy()
    else:
        site, ee_body, ee_offset = -1, body_id(model, str(rc.ee_body)), np.array(rc.ee_offset, dtype=float)

    mov_b, mov_m = [], []
    for mv in cfg.moving:
        b = _lookup(model, mujoco.mjtObj.mjOBJ_BODY, "body", mv.body, model.nbody)
        if model.body_mocapid[b] < 0:
            mocaps = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) or str(i)
                      for i in range(model.nbody) if model.body_mocapid[i] >= 0]
            raise ConfigError(f"{origin}: [[moving]] body {mv.body!r} is not a mocap body; "
                              f"mocap bodies: {mocaps}")
        mov_b.append(b)
        mov_m.append(int(model.body_mocapid[b]))

    if isinstance(rc.home, str):
        home = keyframe_home(model, rc.home, qpos_adr)
    elif rc.home is not None:
        home = np.array(rc.home, dtype=float)
        if home.shape != (len(joint_names),):
            raise ConfigError(f"{origin}: [robot] home has {home.size} numbers for {len(joint_names)} "
                              f"joints {list(joint_names)}")
    else:
        home = model.qpos0[qpos_adr].copy()
    for key in ("tracking_kp", "tracking_kd"):
        k = len(getattr(cfg.gains, key))
        if k not in (1, len(joint_names)):
            raise ConfigError(f"{origin}: [gains] {key}: expected 1 or {len(joint_names)} numbers, got {k}")
    low, high = rng[:, 0], rng[:, 1]
    bad = np.nonzero((home < low) | (home > high))[0]
    if bad.size:
        raise ConfigError(f"{origin}: [robot] home is outside the joint range for joints "
                          f"{[joint_names[i] for i in bad]}")

    dt = float(model.opt.timestep)
    ratio = cfg.control.period / dt
    if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
        raise ConfigError(f"{origin}: [control] period {cfg.control.period} s must be an integer "
                          f"multiple of the model timestep {dt} s")

    goals = np.array([g.position for g in cfg.task.goals], dtype=float)
    if any(g.site is not None for g in cfg.task.goals):
        data = mujoco.MjData(model)
        data.qpos[qpos_adr] = home
        mujoco.mj_kinematics(model, data)
        for i, g in enumerate(cfg.task.goals):
            if g.site is not None:
                s = _lookup(model, mujoco.mjtObj.mjOBJ_SITE, "site", g.site, model.nsite)
                goals[i] = data.site_xpos[s]

    return Scene(
        name=cfg.name, model=model, config=cfg, xml_path=xml_path, joint_ids=joint_ids_a,
        qpos_adr=qpos_adr, dof_adr=dof_adr, actuator_ids=act, joint_range=rng,
        torque_limit=tau, home=home, robot_geom_ids=robot, obstacle_geom_ids=obst,
        ee_site_id=site, moving_body_ids=np.array(mov_b, dtype=np.int32),
        moving_mocap_ids=np.array(mov_m, dtype=np.int32), goal_positions=goals,
        goal_dwell=np.array([g.dwell for g in cfg.task.goals]),
        arm_joint_names=tuple(joint_names), ee_body_id=ee_body, ee_offset=ee_offset,
        arms=resolve_arms(model, cfg),
    )


def _compile(xml_path: Path) -> mujoco.MjModel:
    if not xml_path.is_file():
        raise ConfigError(f"MJCF file not found: {xml_path}")
    try:
        return mujoco.MjModel.from_xml_path(str(xml_path))
    except ValueError as exc:
        detail = " ".join(str(exc).split())  # MuJoCo's parser message spans lines
        raise ConfigError(f"{xml_path}: malformed MJCF: {detail}") from exc


def load_scene_from_files(xml_path: str | Path, toml_path: str | Path) -> Scene:
    """Load a scene from an MJCF file and a TOML config.

    Args:
        xml_path: The MJCF file (``<include>`` paths are relative to its folder).
        toml_path: The scene config (schema in ``models/README.md``).

    Returns:
        The scene with every name resolved.

    Raises:
        ConfigError: A file is missing or malformed (the message names it), or the config is
            inconsistent with the model.
        UnknownNameError: The config names a joint, geom, site or body the model lacks; the
            message lists the valid names.

    """
    cfg = load_config(toml_path)
    xml = Path(xml_path)
    return _resolve(_compile(xml), cfg, xml)


def _scene_files() -> dict[str, Path]:
    return {p.stem: p for p in sorted(models_dir().glob("*.toml"))}


def list_scenes() -> list[SceneInfo]:
    """The shipped scenes, sorted by name, with their one-line descriptions."""
    out = []
    for name, path in _scene_files().items():
        try:
            with path.open("rb") as fh:
                desc = tomllib.load(fh).get("scene", {}).get("description", "")
        except (OSError, tomllib.TOMLDecodeError):
            desc = "(unreadable config)"
        out.append(SceneInfo(name=name, description=str(desc)))
    return out


def load_scene(name: str) -> Scene:
    """Load a shipped scene by name (see :func:`list_scenes`).

    Raises:
        UnknownNameError: No such scene; the message lists the valid scene names.
        ConfigError: Its files are malformed.

    """
    files = _scene_files()
    if name not in files:
        raise UnknownNameError("scene", name, files)
    cfg = load_config(files[name])
    if cfg.name != name:
        raise ConfigError(f"{files[name]}: [scene] name {cfg.name!r} differs from the file name "
                          f"{name!r}; a shipped scene's name is its file stem")
    xml = files[name].parent / cfg.model
    return _resolve(_compile(xml), cfg, xml)

