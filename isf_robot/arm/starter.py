"""A starter scene config for a model: what ``isf-robot init --model ARM.xml`` prints.

It reads the model and writes a TOML file (schema: ``models/README.md``) with

* the arm's joints, each with its actuator kind, gains, torque limit, damping, friction, range
  and the speed it allows as a comment (:func:`~isf_robot.arm.actuation.speed_bound`: the
  damping's steady speed, or for a servo on an undamped joint the largest velocity step it
  answers within its force range, ``(F - |gravity|) / kv``);
* its colliding geoms by body (selected with ``subtree`` and, when they share one group,
  ``geom_group``);
* the home: the ``home`` keyframe (else the first named one, else ``qpos0``); a home with an arm
  joint outside its range is flagged and replaced by the nearest pose inside the ranges;
* the end effector: a tool site on the last link (``attachment_site``, ``tcp``, ``tool``,
  ``flange``, ``gripper``, ``ee``, ``end_effector``, ...) before any other site and never an
  axis marker (``ee_x``, ``x_axis``, ...) when another site is there, else that link as
  ``ee_body``;
* the colliding geoms off the arm as obstacles; colliding planes (a floor) are left out and named;
* the ``goal_*`` sites as goals (else one placeholder goal at the end effector's home position,
  which keeps the file loadable);
* ``max_joint_speed`` = 80% of the slowest joint's speed (at most 2 rad/s).
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, IsfError

from .actuation import ActuatorInfo, actuator_info, speed_bound
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

    A model whose actuated joints hang from more than one body on the world (several arms) gets one
    ``[[arm]]`` table per such body instead of ``[robot]``, each with that arm's joints, geoms, end
    effector, home and ``goal_*`` sites (those named with the arm's prefix).

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
    qadr = model.jnt_qposadr[jid]
    keys = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k) or "" for k in range(model.nkey)]
    named = [k for k in keys if k]
    home_key = "home" if "home" in named else (named[0] if named else None)
    data = mujoco.MjData(model)
    if home_key is not None:
        data.qpos[:] = model.key_qpos[keys.index(home_key)]
    limited = model.jnt_limited[jid].astype(bool)
    lo = np.where(limited, model.jnt_range[jid, 0], -np.inf)
    hi = np.where(limited, model.jnt_range[jid, 1], np.inf)
    q_home = data.qpos[qadr].copy()
    outside = [i for i in range(len(jid)) if not lo[i] <= q_home[i] <= hi[i]]
    q_valid = np.clip(q_home, lo, hi)
    data.qpos[qadr] = q_valid
    mujoco.mj_forward(model, data)
    grav = np.abs(data.qfrc_bias[dofs])
    roots: dict[int, list[int]] = {}
    for i, j in enumerate(jid):
        roots.setdefault(_root(model, int(model.jnt_bodyid[j])), []).append(i)

    lines = [f"# Starter scene config for {xml.name}, written by `isf-robot init` (schema: models/README.md).",
             "# Check the TODOs below, then:",
             f"#   isf-robot check --model {xml.name} --config {xml.stem}.toml",
             "", "[scene]", f"name = {_q(xml.stem)}",
             f"description = {_q(f'{xml.stem}: starter config (edit me)')}", f"model = {_q(xml.name)}", ""]
    if len(roots) > 1:
        arms, speeds, rules, colliding = _arm_tables(model, data, joints, jid, roots, grav, lo, hi, q_valid)
        lines += arms
    else:
        lines += ["[robot]", "# Arm joints: the hinge/slide joints the actuators drive, in actuator order",
                  "# (leave 'joints' out to get exactly these):"]
        joint_lines, speeds, rules = _joint_lines(model, joints, jid, grav, lo, hi)
        lines += joint_lines
        lines.append(f"joints = [{', '.join(_q(j) for j in joints)}]")
        root = next(iter(roots))
        bodies, colliding, geom_lines = _arm_geoms(model, root)
        lines += geom_lines
        source = f"keyframe {home_key!r}" if home_key is not None else "qpos0 (the model has no named keyframe)"
        if outside:
            what = ", ".join(f"{joints[i]} {q_home[i]:.4g} outside [{_num(lo[i])}, {_num(hi[i])}]" for i in outside)
            lines += [f"# TODO: the home from {source} has arm joints outside their range ({what});",
                      "# the nearest pose inside the ranges (those joints clipped to their limits):",
                      f"home = [{', '.join(f'{x:.6g}' for x in q_valid)}]"]
        elif home_key is not None:
            lines.append(f"home = {_q(home_key)}  # keyframes: {', '.join(named)}")
        else:
            lines.append("# home: no named keyframe; give home = [...] (default: qpos0)")
        site, last, ee_lines = _ee_lines(model, jid)
        lines += ee_lines
        lines.append("self_collision = false")

    off_arm = [g for g in range(model.ngeom) if (model.geom_contype[g] or model.geom_conaffinity[g])
               and g not in colliding
               and (model.body_weldid[model.geom_bodyid[g]] == 0 or model.body_mocapid[model.geom_bodyid[g]] >= 0)]
    planes = [g for g in off_arm if int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_PLANE)]
    other = [g for g in off_arm if g not in planes]
    lines += ["", "[obstacles]"]
    if planes:
        lines += [f"# Left out: the colliding plane(s) {', '.join(_q(geom_label(model, g)) for g in planes)}. MuJoCo "
                  "simulates their contacts but the",
                  "# filter does not guard them (a plane has no bounding sphere for the broad phase): keep the "
                  "goals above",
                  "# them, or add a thin box-shaped convex mesh under the arm's reach as an obstacle."]
    if other:
        lines.append(f"geoms = [{', '.join(_q(geom_label(model, g)) for g in other)}]  # colliding geoms off the arm")
    else:
        lines += ["# TODO: this model has no obstacles. Write a scene file that <include>s it and adds them",
                  "# (e.g. in a body \"obstacles\"), point [scene] model at that file, and select them:",
                  "bodies = [\"obstacles\"]"]

    lines += ["", "[task]", "duration = 10.0", "loop = true", "tolerance = 0.02"]
    if len(roots) == 1:
        goal_sites = _goal_sites(model, bodies)
        if goal_sites:
            lines.append(f"# the model's goal sites, in name order ({len(goal_sites)}):")
            for n in goal_sites:
                lines += ["[[task.goals]]", f"site = {_q(n)}", "dwell = 0.5"]
        else:
            ee = data.site_xpos[site] if site is not None else data.xpos[last]
            lines += ["# TODO: the goals, in order (a site name or a world position [m]); this one is the",
                      "# end effector at home (sites named goal_* are picked up by init):", "[[task.goals]]",
                      f"pos = [{', '.join(f'{x:.4f}' for x in ee)}]", "dwell = 0.5"]
    finite = [(v, r) for v, r in zip(speeds, rules) if np.isfinite(v)]
    vmin = min((v for v, _ in finite), default=np.inf)
    suggest = min(DEFAULT_MAX_JOINT_SPEED, 0.8 * vmin)
    if finite:
        rule = {r for v, r in finite if v == vmin}.pop()
        why = {"damping": "(torque limit - gravity at home) / damping",
               "servo kv": "(force limit - gravity at home) / servo kv: the largest velocity step the servo "
                           "answers unsaturated"}[rule]
        comment = f"# 80% of the slowest joint's {why} = {_num(vmin)} rad/s (at most {DEFAULT_MAX_JOINT_SPEED:g})"
    else:
        comment = "# no joint damping, servo kv or torque limit bounds the speed: the default"
    lines += ["", "[gains]", comment, f"max_joint_speed = {suggest:.2g}", "max_ee_speed = 0.4", "",
              "[control]", f"period = {2 * model.opt.timestep:g}  # [s] a whole multiple of the timestep", "",
              "# [filter] is optional: alpha, c, b, d_bar (0: calibrated) and the intermittent filter's options.",
              "# Its hand-over (blend) and predictive off trigger (horizon) are designed from [gains] and",
              "# [control] when left out (models/README.md); `isf-robot check` prints the values.", ""]
    return "\n".join(lines)


def _joint_lines(model: mujoco.MjModel, joints: list[str], jid: list[int], grav: np.ndarray, lo: np.ndarray,
                 hi: np.ndarray) -> tuple[list[str], list[float], list[str]]:
    """A comment per joint (actuator, limit, damping, friction, range, speed) and each joint's speed bound."""
    lines, speeds, rules = [], [], []
    for j, d, g, lo_j, hi_j in zip(joints, model.jnt_dofadr[jid], grav, lo, hi):
        a = next(a for a in range(model.nu)
                 if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
                 and int(model.actuator_trnid[a, 0]) == int(model.joint(j).id))
        damping = float(model.dof_damping[d])
        info: ActuatorInfo | None
        try:
            info = actuator_info(model, a, j)
            kind = {"torque": "torque motor", "position": f"position servo kp {info.kp:g} kv {info.kv:g}",
                    "velocity": f"velocity servo kv {info.kv:g}"}[info.kind]
            limit = info.force_limit
        except IsfError as exc:
            info, kind, limit = None, f"UNSUPPORTED ({exc})", np.inf
        v, rule = speed_bound(info, limit, damping, float(g))
        speeds.append(v)
        rules.append(rule)
        how = {"damping": "(limit - gravity) / damping", "servo kv": "(limit - gravity) / kv",
               "none": "nothing in the model bounds it"}[rule]
        fric = float(model.dof_frictionloss[d])
        lines.append(f"#   {j}: {kind}, limit {_num(limit)} N m, damping {damping:g} N m s/rad, "
                     + (f"friction {fric:g} N m (fed forward), " if fric > 0 else "")
                     + f"range [{_num(lo_j)}, {_num(hi_j)}], max speed {_num(v)} rad/s ({how})")
    return lines, speeds, rules


def _arm_geoms(model: mujoco.MjModel, root: int, select: bool = True) -> tuple[list[int], list[int], list[str]]:
    """The bodies of ``root``'s subtree, its colliding geoms, and the lines selecting them (by subtree)."""
    bodies = subtree_bodies(model, root)
    colliding = [g for b in bodies
                 for g in range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b]))
                 if model.geom_contype[g] or model.geom_conaffinity[g]]
    groups = sorted({int(model.geom_group[g]) for g in colliding})
    lines = [f"# Colliding geoms of the arm (subtree of {_body(model, root)!r}), by body:"]
    for b in bodies:
        gs = [g for g in colliding if int(model.geom_bodyid[g]) == b]
        desc = ", ".join(f"{geom_label(model, g)} ({mujoco.mjtGeom(int(model.geom_type[g])).name[7:].lower()}, "
                         f"group {int(model.geom_group[g])})" for g in gs)
        lines.append(f"#   {_body(model, b)}: {desc or '(none)'}")
    if not select:
        return bodies, colliding, lines
    lines.append(f"subtree = {_q(_body(model, root))}")
    if len(groups) == 1 and groups[0] != 0:
        lines.append(f"geom_group = {groups[0]}")
    return bodies, colliding, lines


def _ee_lines(model: mujoco.MjModel, jid: list[int]) -> tuple[int | None, int, list[str]]:
    """The end-effector site (or ``None``), the deepest body, and the lines naming the end effector."""
    last = max((int(model.jnt_bodyid[j]) for j in jid), key=lambda b: len(_chain(model, b)))
    tip = subtree_bodies(model, last)
    last = max(tip, key=lambda b: len(_chain(model, b)))  # the deepest body: the hand, the flange
    site = _ee_site(model, tip)
    if site is not None:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, site)
        others = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) for s in _named_sites(model, tip)
                  if s != site]
        return site, last, [f"ee_site = {_q(name)}" + (f"  # other sites on the last links: {', '.join(others)}"
                                                         if others else "")]
    return site, last, [f"ee_body = {_q(_body(model, last))}  # no tool site on the last link: its frame origin ...",
                        "ee_offset = [0.0, 0.0, 0.0]  # ... plus this offset [m] in its frame: TODO the tool centre"]


def _goal_sites(model: mujoco.MjModel, bodies: list[int], prefix: str = "") -> list[str]:
    """Sites named ``<prefix>goal*`` off the arm, in natural name order."""
    pattern = re.escape(prefix) + r"goal(_|\d|$)"
    return sorted((n for s in range(model.nsite) if int(model.site_bodyid[s]) not in bodies
                   and re.match(pattern, n := mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) or "",
                                re.IGNORECASE)),
                  key=lambda n: [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", n.lower())])


def _arm_tables(model: mujoco.MjModel, data: mujoco.MjData, joints: list[str], jid: list[int],
                roots: dict[int, list[int]], grav: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                q_valid: np.ndarray) -> tuple[list[str], list[float], list[str], list[int]]:
    """One ``[[arm]]`` table per root body carrying actuated joints (a model with several arms)."""
    lines = [f"# {len(roots)} arms: the actuated joints hang from {len(roots)} bodies on the world. One [[arm]] "
             "table each (names written in full;", "# a 'prefix' is put before the names that lack it)."]
    speeds: list[float] = []
    rules: list[str] = []
    colliding: list[int] = []
    for k, (root, idx) in enumerate(roots.items()):
        names = [joints[i] for i in idx]
        prefix = os.path.commonprefix(names)
        prefix = prefix[: max(prefix.rfind("_"), prefix.rfind("/")) + 1]  # (up to a separator: "left_")
        name = prefix.strip("_/") or _body(model, root)
        jl, sp, ru = _joint_lines(model, names, [jid[i] for i in idx], grav[idx], lo[idx], hi[idx])
        speeds += sp
        rules += ru
        bodies, geoms, geom_lines = _arm_geoms(model, root, select=False)
        colliding += geoms
        site, last, ee_lines = _ee_lines(model, [jid[i] for i in idx])
        lines += ["", "[[arm]]", f"name = {_q(name)}"] + ([f"prefix = {_q(prefix)}"] if prefix else []) + jl
        lines += [f"joints = [{', '.join(_q(j) for j in names)}]"] + geom_lines
        lines.append(f"geoms = [{', '.join(_q(geom_label(model, g)) for g in geoms)}]")
        lines.append(f"home = [{', '.join(f'{q_valid[i]:.6g}' for i in idx)}]  # the model's home (or qpos0)")
        if site is None:
            lines.append("# TODO: no tool site on the last link; an [[arm]] needs an ee_site (add a site to the hand)")
            lines.append(f"ee_site = {_q(prefix + 'ee')}")
        else:
            lines += [ee_lines[0]]
        goals = _goal_sites(model, bodies, prefix) if prefix else []
        if goals:
            lines.append(f"goals = [{', '.join('{ site = ' + _q(n) + ', dwell = 0.5 }' for n in goals)}]")
        else:
            ee = data.site_xpos[site] if site is not None else data.xpos[last]
            lines += [f"# TODO: arm {k + 1}'s goals (sites named <prefix>goal_* are picked up by init); this one is "
                      "its end effector at home:",
                      f"goals = [{{ pos = [{', '.join(f'{x:.4f}' for x in ee)}], dwell = 0.5 }}]"]
    return lines, speeds, rules, colliding


_TOOL_WORDS = ("attachment", "tcp", "tool", "flange", "end_effector", "endeffector", "eef", "ee", "gripper",
               "grasp", "pinch", "hand", "tip")
"""Words of a site name that mark a tool point, best first."""


def _is_axis_marker(name: str) -> bool:
    """``ee_x``, ``ee_y``, ``x_axis``, ``axis_z``, ``site_y``: a site that marks a frame axis."""
    words = [w for w in re.split(r"[^a-z0-9]+", name.lower()) if w]
    return "axis" in words or any(w in ("x", "y", "z") for w in words) or bool(re.search(r"(^|_)axis", name.lower()))


def _named_sites(model: mujoco.MjModel, bodies: list[int]) -> list[int]:
    return [s for s in range(model.nsite) if int(model.site_bodyid[s]) in bodies
            and mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s)]


def _ee_site(model: mujoco.MjModel, tip: list[int]) -> int | None:
    """The end-effector site among the named sites of the last links (module docstring), or ``None``."""
    sites = [s for s in _named_sites(model, tip)
             if not _is_axis_marker(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s))]
    if not sites:
        return None

    def rank(s: int) -> tuple[int, int, int]:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s).lower()
        words = [w for w in re.split(r"[^a-z0-9]+", name) if w]
        hit = [i for i, t in enumerate(_TOOL_WORDS) if t in words or (len(t) > 3 and t in name)]
        return (-(min(hit) if hit else len(_TOOL_WORDS)), len(_chain(model, int(model.site_bodyid[s]))), s)

    return max(sites, key=rank)


def _chain(model: mujoco.MjModel, b: int) -> list[int]:
    out = [b]
    while b != 0:
        b = int(model.body_parentid[b])
        out.append(b)
    return out
