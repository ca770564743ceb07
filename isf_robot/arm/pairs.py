"""Which geom pairs get a collision barrier: robot-obstacle and optional robot-robot pairs, filtered.

In a scene with several arms, the pairs of geoms of two different arms (inter-arm pairs) are
robot-robot pairs too: both bodies move, so each row carries both arms' Jacobians, exactly as a
self-collision row does (``is_self``).

A candidate pair is dropped when MuJoCo itself would never let the two geoms collide: same
(welded) body, parent and child bodies, contype/conaffinity bits, or an MJCF ``<exclude>``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from .selection import geom_label

__all__ = ["CollisionPairs", "collision_pairs"]


@dataclass(frozen=True, eq=False)
class CollisionPairs:
    """The geom pairs that get a collision barrier, after filtering.

    Attributes:
        geom1: Robot geom id of each pair, shape (k,).
        geom2: Obstacle (or, for self pairs, robot) geom id, shape (k,).
        margin: Margin per pair [m], shape (k,).
        is_self: True for robot-robot pairs, shape (k,).
        names: ``"<geom1>|<geom2>"`` per pair.
        excluded: ``(name, reason)`` of every candidate pair that was filtered out.

    """

    geom1: np.ndarray
    geom2: np.ndarray
    margin: np.ndarray
    is_self: np.ndarray
    names: tuple[str, ...]
    excluded: tuple[tuple[str, str], ...]

    @property
    def k(self) -> int:
        """Number of pairs."""
        return int(self.geom1.shape[0])


def _exclusion_reason(model: mujoco.MjModel, g1: int, g2: int) -> str | None:
    b1, b2 = int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])
    w1, w2 = int(model.body_weldid[b1]), int(model.body_weldid[b2])
    if w1 == w2:
        return "same body"
    if w1 != 0 and w2 != 0:
        p1 = int(model.body_weldid[model.body_parentid[w1]])
        p2 = int(model.body_weldid[model.body_parentid[w2]])
        if p1 == w2 or p2 == w1:
            return "parent-child"
    ct1, ca1 = int(model.geom_contype[g1]), int(model.geom_conaffinity[g1])
    ct2, ca2 = int(model.geom_contype[g2]), int(model.geom_conaffinity[g2])
    if not (ct1 & ca2 or ct2 & ca1):
        return "contype/conaffinity"
    sig = {(b1 << 16) + b2, (b2 << 16) + b1}
    if model.nexclude and sig & {int(s) for s in model.exclude_signature}:
        return "excluded in MJCF"
    return None


def collision_pairs(
    model: mujoco.MjModel,
    robot_geoms: Sequence[int] | np.ndarray,
    obstacle_geoms: Sequence[int] | np.ndarray,
    *,
    margin: float,
    self_collision: bool = False,
    self_margin: float = 0.0,
    arm_of: Sequence[int] | np.ndarray | None = None,
) -> CollisionPairs:
    """Build the filtered robot-obstacle (and optionally robot-robot) pairs.

    A candidate pair is dropped when both geoms are on the same (welded) body, on a parent
    and child body (unless one is the world), when their contype/conaffinity bits exclude
    contact, or when the MJCF has an ``<exclude>`` for their bodies. Robot-robot pairs (only
    with ``self_collision``) are taken once per unordered pair.

    Args:
        model: The model.
        robot_geoms: Robot geom ids.
        obstacle_geoms: Obstacle geom ids.
        margin: Robot-obstacle margin [m].
        self_collision: Add the non-adjacent robot-robot pairs.
        self_margin: Robot-robot margin [m].
        arm_of: The arm index of each robot geom (a scene with several arms): robot-robot pairs of
            geoms of different arms are added with the robot-obstacle ``margin`` (with or without
            ``self_collision``, which adds the pairs within an arm).

    Returns:
        The pairs, robot-obstacle first.

    """
    def name(g: int) -> str:
        return geom_label(model, g)

    cands = [(int(r), int(o), False) for r in robot_geoms for o in obstacle_geoms]
    rg = [int(g) for g in robot_geoms]
    arm = [0] * len(rg) if arm_of is None else [int(a) for a in arm_of]
    inter = arm_of is not None
    if self_collision or inter:
        cands += [(rg[i], rg[j], True) for i in range(len(rg)) for j in range(i + 1, len(rg))
                  if self_collision or arm[i] != arm[j]]
    between = {(rg[i], rg[j]) for i in range(len(rg)) for j in range(len(rg)) if arm[i] != arm[j]}
    keep, excluded = [], []
    for g1, g2, is_self in cands:
        why = _exclusion_reason(model, g1, g2)
        if why is None:
            keep.append((g1, g2, is_self))
        else:
            excluded.append((f"{name(g1)}|{name(g2)}", why))
    return CollisionPairs(
        geom1=np.array([p[0] for p in keep], dtype=np.int64),
        geom2=np.array([p[1] for p in keep], dtype=np.int64),
        margin=np.array([self_margin if p[2] and (p[0], p[1]) not in between else margin for p in keep],
                        dtype=float),
        is_self=np.array([p[2] for p in keep], dtype=bool),
        names=tuple(f"{name(p[0])}|{name(p[1])}" for p in keep),
        excluded=tuple(excluded),
    )
