"""Drawing a MuJoCo model in Rerun: geometry once (static), body poses per block of steps.

Layout: ``<root>/<body>`` carries the body's world pose (static for bodies welded to the
world, per step for the others); ``<root>/<body>/<geom>`` carries the geom's shape in its
own frame with a static transform relative to the body. Shapes follow MuJoCo's size
conventions: sphere (radius), capsule and cylinder (radius, half-length along z), ellipsoid
and box (half sizes), plane (half extents in x and y; 0 means infinite, drawn 2 m wide),
mesh (the compiled vertices, already in the geom frame). Every shape is solid. Height fields
and SDFs are skipped.

Which geoms: those of the visible groups (0-2, as MuJoCo's viewer), plus every geom listed in
``include`` whatever its group (the arm layer's robot and obstacle collision geoms, often in
group 3), plus every other geom on the kinematic trees those belong to (e.g. an arm's base).
Geoms listed in ``tinted`` get their colour per step (:meth:`MujocoDrawing.send_tint`: their
own colour, or a tint while a flag such as the filter mode is set); their static shape then
carries no colour (Rerun lets static data shadow temporal data of the same component).

This module imports mujoco, as it draws MuJoCo geometry (the layering rule allows it here).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.components import RotationQuatBatch, Translation3DBatch

from .buffer import TIMELINE

__all__ = ["MujocoDrawing", "VISIBLE_GROUPS", "TINT", "transform_columns"]

VISIBLE_GROUPS = (0, 1, 2)
"""Geom groups drawn (MuJoCo's viewer shows groups 0-2 by default)."""

_PLANE_HALF = 1.0  # [m] half extent drawn for an infinite plane

TINT = (255, 140, 0)
"""Colour blended into tinted geoms while the flag is set (orange: the filter is on)."""
_TINT_WEIGHT = 0.65


def _xyzw(q_wxyz: np.ndarray) -> np.ndarray:
    return np.asarray(q_wxyz, dtype=np.float64)[..., [1, 2, 3, 0]]


class _Arrow:
    """An Arrow array as a component batch (what ``rr.ComponentColumn`` partitions)."""

    __slots__ = ("array",)

    def __init__(self, array: pa.Array) -> None:
        self.array = array

    def as_arrow_array(self) -> pa.Array:
        return self.array


_TRANSFORM: list[Any] = []  # (the descriptors of Transform3D's translation and quaternion columns, made once)


def transform_columns(translation: np.ndarray, quaternion_wxyz: np.ndarray) -> list[Any]:
    """``rr.Transform3D.columns(translation=..., quaternion=...)`` of ``n`` poses, one per row, built in Arrow.

    ``translation``: shape (n, 3); ``quaternion_wxyz``: MuJoCo's (w, x, y, z), shape (n, 4). The same
    columns as Rerun's (float32 values, the quaternion as (x, y, z, w)), without its per-component
    conversion.
    """
    if not _TRANSFORM:
        _TRANSFORM.extend(c.component_descriptor()
                          for c in rr.Transform3D.columns(translation=np.zeros((1, 3)), quaternion=np.zeros((1, 4))))
    n = len(translation)
    tr = np.ascontiguousarray(translation, dtype=np.float32).reshape(-1)
    q = np.empty((n, 4), dtype=np.float32)
    q[:, :3] = quaternion_wxyz[:, 1:]
    q[:, 3] = quaternion_wxyz[:, 0]
    offsets = np.arange(n + 1, dtype=np.int32)
    return [rr.ComponentColumn(_TRANSFORM[0], _Arrow(pa.FixedSizeListArray.from_arrays(
                pa.array(tr), type=Translation3DBatch._ARROW_DATATYPE)), offsets=offsets),
            rr.ComponentColumn(_TRANSFORM[1], _Arrow(pa.FixedSizeListArray.from_arrays(
                pa.array(q.reshape(-1)), type=RotationQuatBatch._ARROW_DATATYPE)), offsets=offsets)]


def _rgba(model: mujoco.MjModel, g: int) -> list[int]:
    rgba = model.geom_rgba[g]
    mat = int(model.geom_matid[g])
    if mat >= 0 and np.allclose(rgba, [0.5, 0.5, 0.5, 1.0]):
        rgba = model.mat_rgba[mat]
    return [int(round(255 * float(np.clip(c, 0.0, 1.0)))) for c in rgba]


def _name(model: mujoco.MjModel, obj: mujoco.mjtObj, i: int, prefix: str) -> str:
    return rr.escape_entity_path_part(mujoco.mj_id2name(model, obj, i) or f"{prefix}{i}")


def _shape(model: mujoco.MjModel, g: int, color: list[int] | None) -> Any | None:
    """The Rerun archetype of geom ``g`` in its own frame (solid), or None for unsupported types.

    ``color=None``: no colour component (it is sent per step, see :meth:`MujocoDrawing.send_tint`).
    """
    t = int(model.geom_type[g])
    size = np.asarray(model.geom_size[g], dtype=np.float64)
    G = mujoco.mjtGeom
    colors = None if color is None else [color]
    if t == G.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=colors, fill_mode="solid")
    if t == G.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size[:3]], colors=colors, fill_mode="solid")
    if t == G.mjGEOM_CAPSULE:
        return rr.Capsules3D(lengths=[2.0 * size[1]], radii=[size[0]], translations=[[0.0, 0.0, -size[1]]],
                             colors=colors, fill_mode="solid")
    if t == G.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2.0 * size[1]], radii=[size[0]], colors=colors, fill_mode="solid")
    if t == G.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size[:3]], colors=colors, fill_mode="solid")
    if t == G.mjGEOM_PLANE:
        hx = size[0] if size[0] > 0 else _PLANE_HALF
        hy = size[1] if size[1] > 0 else _PLANE_HALF
        return rr.Boxes3D(half_sizes=[[hx, hy, 0.0]], colors=colors, fill_mode="solid")
    if t == G.mjGEOM_MESH:
        mid = int(model.geom_dataid[g])
        if mid < 0:
            return None
        va, vn = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
        fa, fn = int(model.mesh_faceadr[mid]), int(model.mesh_facenum[mid])
        verts = np.asarray(model.mesh_vert[va:va + vn], dtype=np.float64)
        faces = np.asarray(model.mesh_face[fa:fa + fn], dtype=np.uint32)
        return rr.Mesh3D(vertex_positions=verts, triangle_indices=faces, albedo_factor=color)
    return None


def _color_columns(shape: Any, colors: np.ndarray) -> Any:
    """Per-row colour columns of a shape archetype (one colour per row)."""
    if isinstance(shape, rr.Mesh3D):
        return rr.Mesh3D.columns(albedo_factor=colors)
    return type(shape).columns(colors=colors)


def _tinted(color: list[int]) -> list[int]:
    w = _TINT_WEIGHT
    return [int(round((1 - w) * c + w * k)) for c, k in zip(color[:3], TINT)] + [color[3]]


class MujocoDrawing:
    """Static geometry and per-step body poses of a MuJoCo model.

    Args:
        model: The compiled model.
        root: Entity path under which bodies are logged.
        groups: Geom groups to draw.
        include: Geom ids drawn whatever their group (with every geom of their kinematic trees).
        tinted: Geom ids whose colour follows a per-step flag (:meth:`send_tint`).

    """

    def __init__(self, model: mujoco.MjModel, root: str = "/world/bodies",
                 groups: Sequence[int] = VISIBLE_GROUPS, include: Sequence[int] = (),
                 tinted: Sequence[int] = ()) -> None:
        self.model = model
        self.root = root.rstrip("/")
        self.groups = tuple(int(g) for g in groups)
        self.include = sorted({int(g) for g in include} | {int(g) for g in tinted})
        bad = [g for g in self.include if not 0 <= g < model.ngeom]
        if bad:
            raise ValueError(f"geom ids {bad} out of range 0..{model.ngeom - 1}")
        self.tinted = sorted({int(g) for g in tinted})
        roots = {int(model.body_rootid[int(model.geom_bodyid[g])]) for g in self.include}
        roots.discard(0)  # geoms welded to the world do not pull in the whole world body
        self._trees = roots
        self._tint_shapes: list[tuple[str, Any, list[int]]] = []  # (path, shape, colour)
        self._last_flag: bool | None = None
        self.drawn_ids: list[int] = []
        self.data = mujoco.MjData(model)
        names = [_name(model, mujoco.mjtObj.mjOBJ_BODY, b, "body") for b in range(model.nbody)]
        self.body_paths = [f"{self.root}/{n}" for n in names]
        self.moving = np.flatnonzero(np.asarray(model.body_weldid) != 0)
        self.geoms_drawn = 0
        self.geoms_skipped: list[str] = []

    def drawn(self, g: int) -> bool:
        """Whether geom ``g`` is drawn (visible group, listed, or on a listed geom's tree)."""
        m = self.model
        if g in self.include:
            return True
        if _rgba(m, g)[3] == 0:
            return False
        return int(m.geom_group[g]) in self.groups or int(m.body_rootid[int(m.geom_bodyid[g])]) in self._trees

    def log_static(self, stream: rr.RecordingStream) -> None:
        """Log every drawable geom (static) and the poses of bodies welded to the world."""
        m = self.model
        mujoco.mj_kinematics(m, self.data)
        tinted = set(self.tinted)
        for g in range(m.ngeom):
            if not self.drawn(g):
                continue
            gname = _name(m, mujoco.mjtObj.mjOBJ_GEOM, g, "geom")
            color = _rgba(m, g)
            color[3] = max(color[3], 1)
            shape = _shape(m, g, None if g in tinted else color)
            if shape is None:
                self.geoms_skipped.append(gname)
                continue
            path = f"{self.body_paths[int(m.geom_bodyid[g])]}/{gname}"
            local = rr.Transform3D(translation=m.geom_pos[g], quaternion=rr.Quaternion(xyzw=_xyzw(m.geom_quat[g])))
            stream.log(path, local, shape, static=True)  # (the geom's frame and shape: one message)
            if g in tinted:
                self._tint_shapes.append((path, shape, color))
            self.drawn_ids.append(g)
            self.geoms_drawn += 1
        moving = set(self.moving.tolist())
        for b in range(m.nbody):
            if b not in moving:
                pose = rr.Transform3D(translation=self.data.xpos[b],
                                      quaternion=rr.Quaternion(xyzw=_xyzw(self.data.xquat[b])))
                stream.log(self.body_paths[b], pose, static=True)

    def send_poses(self, stream: rr.RecordingStream, t: np.ndarray, pos: np.ndarray, quat: np.ndarray,
                   index: Any = None) -> None:
        """The moving bodies' poses over a block of steps: one ``send_columns`` per moving body.

        Args:
            stream: Where to send.
            t: Times [s], shape (N,).
            pos: Every body's position at each time [m] (MuJoCo's ``xpos`` per row), shape (N, nbody, 3).
            quat: Every body's orientation (w, x, y, z) (``xquat`` per row), shape (N, nbody, 4).
            index: The time column of ``t`` (``rr.TimeColumn``) when the caller has made it already.

        The columns are those ``rr.Transform3D.columns(translation=..., quaternion=...)`` makes (float32
        translations and (x, y, z, w) quaternions), built from every moving body at once
        (:func:`transform_columns`): Rerun's own conversion costs some 2 ms per body and block of 16384 steps.

        """
        n = len(t)
        if not self.moving.size or n == 0:
            return
        nbody = self.model.nbody
        if pos.shape != (n, nbody, 3) or quat.shape != (n, nbody, 4):
            raise ValueError(f"poses must have shapes ({n}, {nbody}, 3) and ({n}, {nbody}, 4) (every body of the "
                             f"model at each of the {n} times); got {pos.shape} and {quat.shape}")
        idx = [index if index is not None else rr.TimeColumn(TIMELINE, duration=t)]
        mv = self.moving
        sel: Any = slice(int(mv[0]), int(mv[-1]) + 1) if int(mv[-1]) - int(mv[0]) + 1 == mv.size else mv
        p32, q32 = pos[:, sel].astype(np.float32), quat[:, sel].astype(np.float32)  # (float32, as Rerun stores them)
        for k, b in enumerate(mv.tolist()):
            stream.send_columns(self.body_paths[b], indexes=idx, columns=transform_columns(p32[:, k], q32[:, k]))

    def send_tint(self, stream: rr.RecordingStream, t: np.ndarray, flag: np.ndarray) -> None:
        """Colour of the tinted geoms: their own while ``flag`` is false, tinted while true.

        Only the rows where the flag changes (and the very first row) are sent.
        """
        flag = np.asarray(flag, dtype=bool)
        if not self._tint_shapes or not flag.size:
            return
        prev = np.concatenate(([not flag[0]] if self._last_flag is None else [self._last_flag], flag[:-1]))
        rows = np.flatnonzero(flag != prev)
        self._last_flag = bool(flag[-1])
        if not rows.size:
            return
        idx = [rr.TimeColumn(TIMELINE, duration=np.asarray(t)[rows])]
        for path, shape, color in self._tint_shapes:
            cols = np.where(flag[rows, None], np.asarray(_tinted(color)), np.asarray(color)).astype(np.uint8)
            stream.send_columns(path, indexes=idx, columns=_color_columns(shape, cols))

    def workspace(self) -> tuple[np.ndarray, float]:
        """Centre and radius [m] of a sphere holding the included geoms at any configuration.

        Centre: the root body of the tinted geoms' trees (the robot's base), else the included
        geoms' mean position; radius: the largest distance from there to an included geom at
        the model's reference pose plus that geom's bounding radius.
        """
        m = self.model
        d = mujoco.MjData(m)  # the reference pose (self.data holds the last drawn state)
        mujoco.mj_kinematics(m, d)
        ids = [g for g in self.include] or list(range(m.ngeom))
        roots = sorted({int(m.body_rootid[int(m.geom_bodyid[g])]) for g in self.tinted} - {0})
        if roots:
            centre = np.mean([d.xpos[b] for b in roots], axis=0)
        else:
            centre = np.mean([d.geom_xpos[g] for g in ids], axis=0)
        radius = 0.0
        for g in ids:
            if int(m.geom_type[g]) == mujoco.mjtGeom.mjGEOM_PLANE:
                continue
            radius = max(radius, float(np.linalg.norm(d.geom_xpos[g] - centre)) + float(m.geom_rbound[g]))
        return centre, max(radius, 0.1)
