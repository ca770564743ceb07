"""Resolving a scene config's selections against a compiled model, the way models are written.

Menagerie-style models leave collision geoms unnamed (class "collision", group 3), put no site
at the tool centre and ship a "home" keyframe. So a config may select

* geoms by name, by label ``body[index]`` (the index-th geom of that body, counting all its
  geoms from 0 in model order: how unnamed geoms are named in every message), by ``bodies``
  (their colliding geoms) or by ``subtree`` (the colliding geoms of a body and all its
  descendants), narrowed by ``geom_group``; "colliding" means ``contype`` or ``conaffinity``
  is non-zero;
* the arm joints explicitly, or by default the hinge/slide joints the actuators drive through
  joint transmissions, in actuator order;
* ``home`` as numbers or as the name of a keyframe;
* the end effector as a site, or as a body plus an offset in its frame.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, UnknownNameError

__all__ = [
    "geom_label",
    "geom_labels",
    "geom_by_label",
    "subtree_bodies",
    "select_geoms",
    "actuated_joints",
    "keyframe_home",
    "body_id",
]

_GEOM = mujoco.mjtObj.mjOBJ_GEOM
_BODY = mujoco.mjtObj.mjOBJ_BODY


def _body_name(model: mujoco.MjModel, b: int) -> str:
    return mujoco.mj_id2name(model, _BODY, b) or ("world" if b == 0 else f"body{b}")


def geom_label(model: mujoco.MjModel, g: int) -> str:
    """The geom's name, or ``body[index]`` for an unnamed geom (index among its body's geoms)."""
    name = mujoco.mj_id2name(model, _GEOM, int(g))
    if name:
        return name
    b = int(model.geom_bodyid[g])
    return f"{_body_name(model, b)}[{int(g) - int(model.body_geomadr[b])}]"


def geom_labels(model: mujoco.MjModel) -> list[str]:
    """Labels of every geom (see :func:`geom_label`), by geom id."""
    return [geom_label(model, g) for g in range(model.ngeom)]


def _colliding(model: mujoco.MjModel, g: int) -> bool:
    return bool(model.geom_contype[g] or model.geom_conaffinity[g])


def geom_by_label(model: mujoco.MjModel, label: str) -> int:
    """The geom id of a name or a ``body[index]`` label.

    Raises:
        UnknownNameError: No such geom; the message lists the colliding geoms' labels and every
            named geom.

    """
    g = mujoco.mj_name2id(model, _GEOM, label)
    if g >= 0:
        return int(g)
    if label.endswith("]") and "[" in label:
        body, _, idx = label[:-1].rpartition("[")
        b = mujoco.mj_name2id(model, _BODY, body) if body != "world" else 0
        if b >= 0 and idx.isdigit() and int(idx) < int(model.body_geomnum[b]):
            return int(model.body_geomadr[b]) + int(idx)
    valid = [geom_label(model, i) for i in range(model.ngeom)
             if _colliding(model, i) or mujoco.mj_id2name(model, _GEOM, i)]
    raise UnknownNameError("geom", label, valid)


def body_id(model: mujoco.MjModel, name: str) -> int:
    """The id of body ``name`` (an error listing the model's bodies when there is none)."""
    b = mujoco.mj_name2id(model, _BODY, name)
    if b < 0:
        raise UnknownNameError("body", name, [_body_name(model, i) for i in range(1, model.nbody)])
    return int(b)


def subtree_bodies(model: mujoco.MjModel, root: int) -> list[int]:
    """Body ids of ``root`` and all its descendants, in id order."""
    out = []
    for b in range(model.nbody):
        a = b
        while a != root and a != 0:
            a = int(model.body_parentid[a])
        if a == root:
            out.append(b)
    return out


def select_geoms(model: mujoco.MjModel, *, geoms: Sequence[str] = (), bodies: Sequence[str] = (),
                 subtree: str | None = None, geom_group: int | None = None,
                 exclude: Sequence[int] = (), all_if_group: bool = False,
                 origin: str = "<config>", where: str = "robot") -> np.ndarray:
    """Geom ids selected by names/labels, bodies and a subtree, narrowed by group.

    Args:
        model: The model.
        geoms: Names or ``body[index]`` labels, taken as given (any group, colliding or not).
        bodies: Bodies whose colliding geoms are selected.
        subtree: A body whose subtree's colliding geoms are selected.
        geom_group: Keep only geoms of this group among those from ``bodies``/``subtree``.
        exclude: Geom ids never selected from bodies/subtree/group (e.g. the robot's, for
            obstacles).
        all_if_group: With ``geom_group`` and no bodies/subtree, select every colliding geom
            of the group (not in ``exclude``).
        origin: Label of the config for messages.
        where: Table name for messages.

    Returns:
        Geom ids, explicit ones first (in the given order), then the rest by id.

    Raises:
        ConfigError: Nothing is selected, or the group is out of range.
        UnknownNameError: An unknown geom or body; the message lists the valid ones.

    """
    if geom_group is not None and not 0 <= geom_group <= 5:
        raise ConfigError(f"{origin}: [{where}] geom_group must be 0..5 (MuJoCo's groups), got {geom_group}")
    out = [geom_by_label(model, g) for g in geoms]
    pool: list[int] = []
    for name in bodies:
        b = body_id(model, name)
        pool += range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b]))
    if subtree is not None:
        for b in subtree_bodies(model, body_id(model, subtree)):
            pool += range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b]))
    if all_if_group and geom_group is not None and not bodies and subtree is None:
        pool += range(model.ngeom)
    skip = set(out) | {int(e) for e in exclude}
    for g in sorted(set(pool)):
        if g in skip or not _colliding(model, g):
            continue
        if geom_group is not None and int(model.geom_group[g]) != geom_group:
            continue
        out.append(g)
    if not out:
        sel = ", ".join(f"{k} = {v!r}" for k, v in (("geoms", list(geoms)), ("bodies", list(bodies)),
                                                    ("subtree", subtree), ("geom_group", geom_group))
                        if v not in ([], None))
        groups = sorted({int(model.geom_group[g]) for g in sorted(set(pool)) if _colliding(model, g)})
        taken = [geom_label(model, g) for g in sorted(set(pool)) if g in skip]
        hint = (f"; {taken} there are already robot geoms" if taken else
                f"; the colliding geoms there are in groups {groups}" if groups else "")
        raise ConfigError(f"{origin}: [{where}] selects no colliding geom ({sel or 'nothing given'}){hint}")
    if len(set(out)) != len(out):
        dup = sorted({geom_label(model, g) for g in out if out.count(g) > 1})
        raise ConfigError(f"{origin}: [{where}] geoms {dup} are listed twice")
    return np.array(out, dtype=np.int32)


def actuated_joints(model: mujoco.MjModel) -> list[str]:
    """Names of the hinge/slide joints driven by joint-transmission actuators, in actuator order."""
    jt = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    out: list[str] = []
    for a in range(model.nu):
        if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT):
            continue
        j = int(model.actuator_trnid[a, 0])
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        if int(model.jnt_type[j]) in jt and name and name not in out:
            out.append(name)
    return out


def keyframe_home(model: mujoco.MjModel, key: str, qpos_adr: np.ndarray) -> np.ndarray:
    """The arm's joint positions in keyframe ``key``.

    Raises:
        UnknownNameError: No such keyframe; the message lists the model's keyframes.

    """
    k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, key)
    if k < 0:
        raise UnknownNameError("keyframe", key,
                               [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, i) or f"#{i}"
                                for i in range(model.nkey)])
    return np.array(model.key_qpos[k][qpos_adr], dtype=float)
