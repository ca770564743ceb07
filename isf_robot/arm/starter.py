"""A starter scene config for a model: what ``isf-robot init --model ARM.xml`` prints.

It reads the model and writes a TOML file (schema: ``models/README.md``) with the arm's joints
(each with its actuator kind, gains, torque limit, damping and range as a comment), its
colliding geoms by body (selected with ``subtree`` and, when they share one group,
``geom_group``), the keyframes found (``home = "home"`` when there is one), the end effector
(a site on the last link, else that link as ``ee_body``), and a suggested ``max_joint_speed``
from the actuator limits and joint damping. Obstacles and goals are left to the user, marked
TODO (a goal at the end effector's home position keeps the file loadable).
"""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, IsfError

from .actuation import actuator_info
from .selection import actuated_joints, geom_label, subtree_bodies

__all__ = ["starter_toml"]

DEFAULT_MAX_JOINT_SPEED = 2.0


def _body(model: mujoco.MjModel, b: int) -> str:
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"


def _root(model: mujoco.MjModel, b: int) -> int:
    while int(model.body_parentid[b]) != 0:
        b = int(model.body_parentid[b])
    return b


def _q(s: str) -> str:
    return json.dumps(s)


def _num(x: float) -> str:
    return f"{x:.6g}" if np.isfinite(x) else "inf"


def starter_toml(xml_path: str | Path) -> str:
    """The starter TOML for the MJCF file ``xml_path`` (see the module docstring).

    Raises:
        ConfigError: The file is missing or malformed, or no actuator drives a hinge/slide joint.

    """
    xml = Path(xml_path)
    if not xml.is_file():
        raise ConfigError(f"MJCF file not found: {xml}")
    try:
        model = mujoco.MjModel.from_xml_path(str(xml))
    except ValueError as exc:
        raise ConfigError(f"{xml}: malformed MJCF: {' '.join(str(exc).split())}") from exc
    joints = actuated_joints(model)
    if not joints:
        raise ConfigError(f"{xml}: no actuator drives a hinge or slide joint; isf-robot needs one "
                          "actuator per arm joint")
    jid = [int(model.joint(j).id) for j in joints]
    dofs = model.jnt_dofadr[jid]
    keys = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k) or "" for k in range(model.nkey)]
    named = [k for k in keys if k]
    home_key = "home" if "home" in named else (named[0] if named else None)
    data = mujoco.MjData(model)
    if home_key is not None:
        data.qpos[:] = model.key_qpos[keys.index(home_key)]
    mujoco.mj_forward(model, data)
    grav = np.abs(data.qfrc_bias[dofs])

    lines = [f"# Starter scene config for {xml.name}, written by `isf-robot init` (schema: models/README.md).",
             "# Add your obstacles and goals (TODO below), then check it:",
             f"#   isf-robot check --model {xml.name} --config {xml.stem}.toml",
             "", "[scene]", f"name = {_q(xml.stem)}",
             f"description = {_q(f'{xml.stem}: starter config (edit me)')}", f"model = {_q(xml.name)}",
             "", "[robot]", "# Arm joints: the hinge/slide joints the actuators drive, in actuator order",
             "# (leave 'joints' out to get exactly these):"]
    speeds = []
    for j, d, g in zip(joints, dofs, grav):
        a = next(a for a in range(model.nu)
                 if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
                 and int(model.actuator_trnid[a, 0]) == int(model.joint(j).id))
        damping = float(model.dof_damping[d])
        try:
            info = actuator_info(model, a, j)
            kind = {"torque": "torque motor", "position": f"position servo kp {info.kp:g} kv {info.kv:g}",
                    "velocity": f"velocity servo kv {info.kv:g}"}[info.kind]
            limit = info.force_limit
        except IsfError as exc:
            kind, limit = f"UNSUPPORTED ({exc})", np.inf
        v = (max(limit - g, 0.0) / damping) if damping > 0 and np.isfinite(limit) else np.inf
        speeds.append(v)
        rng = model.jnt_range[model.joint(j).id] if model.jnt_limited[model.joint(j).id] else (-np.inf, np.inf)
        lines.append(f"#   {j}: {kind}, limit {_num(limit)} N m, damping {damping:g} N m s/rad, "
                     f"range [{_num(rng[0])}, {_num(rng[1])}], max speed {_num(v)} rad/s")
    lines.append(f"joints = [{', '.join(_q(j) for j in joints)}]")

    root = _root(model, int(model.jnt_bodyid[jid[0]]))
    bodies = subtree_bodies(model, root)
    colliding = [g for b in bodies
                 for g in range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b]))
                 if model.geom_contype[g] or model.geom_conaffinity[g]]
    groups = sorted({int(model.geom_group[g]) for g in colliding})
    lines.append(f"# Colliding geoms of the arm (subtree of {_body(model, root)!r}), by body:")
    for b in bodies:
        gs = [g for g in colliding if int(model.geom_bodyid[g]) == b]
        desc = ", ".join(f"{geom_label(model, g)} ({mujoco.mjtGeom(int(model.geom_type[g])).name[7:].lower()}, "
                         f"group {int(model.geom_group[g])})" for g in gs)
        lines.append(f"#   {_body(model, b)}: {desc or '(none)'}")
    lines.append(f"subtree = {_q(_body(model, root))}")
    if len(groups) == 1 and groups[0] != 0:
        lines.append(f"geom_group = {groups[0]}")
    if home_key is not None:
        lines.append(f"home = {_q(home_key)}  # keyframes: {', '.join(named)}")
    else:
        lines.append("# home: no named keyframe; give home = [...] (default: qpos0)")
    last = max((int(model.jnt_bodyid[j]) for j in jid), key=lambda b: len(_chain(model, b)))
    tip = subtree_bodies(model, last)
    last = max(tip, key=lambda b: len(_chain(model, b)))  # the deepest body: the hand, the flange
    sites = [s for s in range(model.nsite) if int(model.site_bodyid[s]) in tip
             and mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s)]
    if sites:
        s = sites[-1]
        lines.append(f"ee_site = {_q(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s))}")
    else:
        lines += [f"ee_body = {_q(_body(model, last))}  # no site on the last link: its frame origin ...",
                  "ee_offset = [0.0, 0.0, 0.0]  # ... plus this offset [m] in its frame: TODO the tool centre"]
    lines.append("self_collision = false")

    other = [g for g in range(model.ngeom) if (model.geom_contype[g] or model.geom_conaffinity[g])
             and g not in colliding and int(model.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_PLANE)
             and (model.body_weldid[model.geom_bodyid[g]] == 0 or model.body_mocapid[model.geom_bodyid[g]] >= 0)]
    lines += ["", "[obstacles]"]
    if other:
        lines.append(f"geoms = [{', '.join(_q(geom_label(model, g)) for g in other)}]  # colliding geoms off the arm")
    else:
        lines += ["# TODO: this model has no obstacles. Write a scene file that <include>s it and adds them",
                  "# (e.g. in a body \"obstacles\"), point [scene] model at that file, and select them:",
                  "bodies = [\"obstacles\"]"]

    ee = data.site_xpos[sites[-1]] if sites else data.xpos[last]
    lines += ["", "[task]", "duration = 10.0", "loop = true", "tolerance = 0.02",
              "# TODO: the goals, in order (a site name or a world position [m]); this one is the",
              "# end effector at home:", "[[task.goals]]",
              f"pos = [{', '.join(f'{x:.4f}' for x in ee)}]", "dwell = 0.5"]
    vmin = float(np.min(speeds))
    suggest = min(DEFAULT_MAX_JOINT_SPEED, 0.8 * vmin)
    lines += ["", "[gains]",
              f"# 80% of the slowest joint's (torque limit - gravity at home) / damping = {_num(vmin)} rad/s"
              if np.isfinite(vmin) else "# no joint damping/torque limit bounds the speed: the default",
              f"max_joint_speed = {suggest:.2g}", "max_ee_speed = 0.4", "",
              "[control]", f"period = {2 * model.opt.timestep:g}  # [s] a whole multiple of the timestep", ""]
    return "\n".join(lines)


def _chain(model: mujoco.MjModel, b: int) -> list[int]:
    out = [b]
    while b != 0:
        b = int(model.body_parentid[b])
        out.append(b)
    return out
