"""Drawing a MuJoCo model in Rerun: geometry once (static), body poses per block of steps.

Layout: ``<root>/<body>`` carries the body's world pose (static for bodies welded to the
world, per step for the others); ``<root>/<body>/<geom>`` carries the geom's shape in its
own frame with a static transform relative to the body. Shapes follow MuJoCo's size
conventions: sphere (radius), capsule and cylinder (radius, half-length along z), ellipsoid
and box (half sizes), plane (half extents in x and y; 0 means infinite, drawn 2 m wide),
mesh (the compiled vertices, already in the geom frame). Height fields and SDFs are skipped.

This module imports mujoco, as it draws MuJoCo geometry (the layering rule allows it here).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np
import rerun as rr

from .buffer import TIMELINE

__all__ = ["MujocoDrawing", "VISIBLE_GROUPS"]

VISIBLE_GROUPS = (0, 1, 2)
"""Geom groups drawn (MuJoCo's viewer shows groups 0-2 by default)."""

_PLANE_HALF = 1.0  # [m] half extent drawn for an infinite plane


def _xyzw(q_wxyz: np.ndarray) -> np.ndarray:
    return np.asarray(q_wxyz, dtype=np.float64)[..., [1, 2, 3, 0]]


def _rgba(model: mujoco.MjModel, g: int) -> list[int]:
    rgba = model.geom_rgba[g]
    mat = int(model.geom_matid[g])
    if mat >= 0 and np.allclose(rgba, [0.5, 0.5, 0.5, 1.0]):
        rgba = model.mat_rgba[mat]
    return [int(round(255 * float(np.clip(c, 0.0, 1.0)))) for c in rgba]


def _name(model: mujoco.MjModel, obj: mujoco.mjtObj, i: int, prefix: str) -> str:
    return rr.escape_entity_path_part(mujoco.mj_id2name(model, obj, i) or f"{prefix}{i}")


def _shape(model: mujoco.MjModel, g: int, color: list[int]) -> Any | None:
    """The Rerun archetype of geom ``g`` in its own frame, or None for unsupported types."""
    t = int(model.geom_type[g])
    size = np.asarray(model.geom_size[g], dtype=np.float64)
    G = mujoco.mjtGeom
    if t == G.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=[color], fill_mode="solid")
    if t == G.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size[:3]], colors=[color], fill_mode="solid")
    if t == G.mjGEOM_CAPSULE:
        return rr.Capsules3D(lengths=[2.0 * size[1]], radii=[size[0]], translations=[[0.0, 0.0, -size[1]]],
                             colors=[color])
    if t == G.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2.0 * size[1]], radii=[size[0]], colors=[color], fill_mode="solid")
    if t == G.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size[:3]], colors=[color], fill_mode="solid")
    if t == G.mjGEOM_PLANE:
        hx = size[0] if size[0] > 0 else _PLANE_HALF
        hy = size[1] if size[1] > 0 else _PLANE_HALF
        return rr.Boxes3D(half_sizes=[[hx, hy, 0.0]], colors=[color], fill_mode="solid")
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


class MujocoDrawing:
    """Static geometry and per-step body poses of a MuJoCo model.

    Args:
        model: The compiled model.
        root: Entity path under which bodies are logged.
        groups: Geom groups to draw.

    """

    def __init__(self, model: mujoco.MjModel, root: str = "/world/bodies",
                 groups: Sequence[int] = VISIBLE_GROUPS) -> None:
        self.model = model
        self.root = root.rstrip("/")
        self.groups = tuple(int(g) for g in groups)
        self.data = mujoco.MjData(model)
        names = [_name(model, mujoco.mjtObj.mjOBJ_BODY, b, "body") for b in range(model.nbody)]
        self.body_paths = [f"{self.root}/{n}" for n in names]
        self.moving = np.flatnonzero(np.asarray(model.body_weldid) != 0)
        self.geoms_drawn = 0
        self.geoms_skipped: list[str] = []
        self._mocap = model.nmocap > 0
        self._mocap_pos = self.data.mocap_pos  # views into MjData (valid while self.data lives)
        self._mocap_quat = self.data.mocap_quat
        self._xpos: np.ndarray | None = None
        self._xquat: np.ndarray | None = None
        if self.moving.size:
            lo, hi = int(self.moving[0]), int(self.moving[-1]) + 1
            if hi - lo == self.moving.size:  # contiguous: views, no copy per step
                self._xpos, self._xquat = self.data.xpos[lo:hi], self.data.xquat[lo:hi]

    def log_static(self, stream: rr.RecordingStream) -> None:
        """Log every drawable geom (static) and the poses of bodies welded to the world."""
        m = self.model
        mujoco.mj_kinematics(m, self.data)
        for g in range(m.ngeom):
            gname = _name(m, mujoco.mjtObj.mjOBJ_GEOM, g, "geom")
            color = _rgba(m, g)
            if int(m.geom_group[g]) not in self.groups or color[3] == 0:
                continue
            shape = _shape(m, g, color)
            if shape is None:
                self.geoms_skipped.append(gname)
                continue
            path = f"{self.body_paths[int(m.geom_bodyid[g])]}/{gname}"
            local = rr.Transform3D(translation=m.geom_pos[g], quaternion=rr.Quaternion(xyzw=_xyzw(m.geom_quat[g])))
            stream.log(path, local, static=True)
            stream.log(path, shape, static=True)
            self.geoms_drawn += 1
        moving = set(self.moving.tolist())
        for b in range(m.nbody):
            if b not in moving:
                pose = rr.Transform3D(translation=self.data.xpos[b],
                                      quaternion=rr.Quaternion(xyzw=_xyzw(self.data.xquat[b])))
                stream.log(self.body_paths[b], pose, static=True)

    def send_poses(self, stream: rr.RecordingStream, t: np.ndarray, qpos_adr: slice | np.ndarray,
                   q: Sequence[np.ndarray], mocap_pos: Sequence[np.ndarray] | None = None,
                   mocap_quat: Sequence[np.ndarray] | None = None) -> None:
        """Forward kinematics of a block of states and one ``send_columns`` per moving body.

        Args:
            stream: Where to send.
            t: Times [s], shape (N,).
            qpos_adr: Addresses (or a slice) of ``q`` in ``qpos``.
            q: Joint positions per row.
            mocap_pos: Mocap positions per row, each shape (nmocap, 3), or ``None``.
            mocap_quat: Mocap orientations (w, x, y, z) per row, or ``None``.

        """
        nb = int(self.moving.size)
        n = len(t)
        if nb == 0 or n == 0:
            return
        d, m = self.data, self.model
        pos = np.empty((n, nb, 3))
        quat = np.empty((n, nb, 4))
        xpos, xquat = self._xpos, self._xquat
        views = xpos is not None and xquat is not None
        mocap = self._mocap and mocap_pos is not None and mocap_quat is not None
        kin = mujoco.mj_kinematics
        for i in range(n):
            d.qpos[qpos_adr] = q[i]
            if mocap:
                self._mocap_pos[:] = mocap_pos[i]  # type: ignore[index]
                self._mocap_quat[:] = mocap_quat[i]  # type: ignore[index]
            kin(m, d)
            if views:
                pos[i] = xpos
                quat[i] = xquat
            else:
                pos[i] = d.xpos[self.moving]
                quat[i] = d.xquat[self.moving]
        idx = [rr.TimeColumn(TIMELINE, duration=t)]
        quat = _xyzw(quat)
        for j, b in enumerate(self.moving.tolist()):
            stream.send_columns(self.body_paths[b], indexes=idx,
                                columns=rr.Transform3D.columns(translation=pos[:, j], quaternion=quat[:, j]))

    @staticmethod
    def index(adr: np.ndarray) -> slice | np.ndarray:
        """A slice when the addresses are contiguous (cheaper to assign through), else the array."""
        adr = np.asarray(adr, dtype=np.intp)
        if adr.size and np.array_equal(adr, np.arange(adr[0], adr[0] + adr.size)):
            return slice(int(adr[0]), int(adr[0]) + int(adr.size))
        return adr
