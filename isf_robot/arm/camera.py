"""The camera of a picture: a named camera of the model, or a free camera framing the arm, obstacles and goals.

:class:`View` holds what the user asked for (``--camera NAME``, or any of ``--azimuth``,
``--elevation``, ``--distance``, ``--lookat``); :func:`frame_workspace` fits the rest:
:func:`framed_points` are the corners of each drawn geom's bounding box and a small cube about
each goal, and :func:`fit_camera` finds the lookat and the smallest distance at which MuJoCo's
free camera shows them all, centred in the part of the image under the banner.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from isf_robot.core import ConfigError

# mujoco is imported inside the functions: `isf-robot render` loads this module before render.select_gl sets
# MUJOCO_GL, which MuJoCo reads once, at its first import

__all__ = ["View", "parse_lookat", "camera_id", "framed_points", "fit_camera", "frame_workspace",
           "DEFAULT_AZIMUTH", "DEFAULT_ELEVATION", "GOAL_ROOM", "FIT_MARGIN"]

DEFAULT_AZIMUTH = 140.0
"""Free camera: from the front-left [deg] (MuJoCo's azimuth)."""
DEFAULT_ELEVATION = -22.0
"""Free camera: slightly above [deg] (negative looks down)."""
GOAL_ROOM = 0.04
"""Half-side [m] of the cube about a goal that the picture shows (room for the goal's marker)."""
FIT_MARGIN = 0.06
"""Fraction of the image's half-width and half-height left free around the framed box."""



@dataclass(frozen=True)
class View:
    """The camera of a picture: a named camera of the model, or a free camera (each value optional).

    Unset free-camera values are defaults (azimuth :data:`DEFAULT_AZIMUTH`, elevation
    :data:`DEFAULT_ELEVATION`) or fitted (:func:`fit_camera`: lookat and distance framing the arm,
    the obstacles and the goals).
    """

    camera: str | None = None
    azimuth: float | None = None
    elevation: float | None = None
    distance: float | None = None
    lookat: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        free = {"azimuth": self.azimuth, "elevation": self.elevation, "distance": self.distance,
                "lookat": self.lookat}
        given = [k for k, v in free.items() if v is not None]
        if self.camera is not None and given:
            raise ConfigError(f"--camera {self.camera!r} is a camera of the model; it takes no "
                              f"{', '.join('--' + k for k in given)} (those set the free camera)")
        for k, v in (("azimuth", self.azimuth), ("elevation", self.elevation), ("distance", self.distance)):
            if v is not None and not math.isfinite(float(v)):
                raise ConfigError(f"--{k} must be a finite number, got {v!r}")
        if self.elevation is not None and not -90.0 <= float(self.elevation) <= 90.0:
            raise ConfigError(f"--elevation must be in [-90, 90] degrees (negative looks down), got {self.elevation}")
        if self.distance is not None and not float(self.distance) > 0:
            raise ConfigError(f"--distance must be a positive number of metres, got {self.distance}")
        if self.lookat is not None and (len(self.lookat) != 3 or not all(math.isfinite(float(x)) for x in self.lookat)):
            raise ConfigError(f"--lookat must be three finite numbers X,Y,Z [m], got {self.lookat!r}")


def parse_lookat(text: str) -> tuple[float, float, float]:
    """``"X,Y,Z"`` -> three floats; a :class:`ConfigError` naming the valid form otherwise."""
    parts = [t.strip() for t in str(text).split(",")]
    try:
        xyz = tuple(float(t) for t in parts)
    except ValueError:
        xyz = ()
    if len(xyz) != 3 or not all(math.isfinite(x) for x in xyz):
        raise ConfigError(f"--lookat {text!r}: expected three numbers X,Y,Z in metres, e.g. --lookat 0.4,0,0.3")
    return (xyz[0], xyz[1], xyz[2])


def camera_id(model: Any, name: str) -> int:
    """Id of the model's camera ``name``; a :class:`ConfigError` listing the valid names otherwise."""
    import mujoco

    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i) or "" for i in range(model.ncam)]
    if name in names and name:
        return names.index(name)
    valid = [n for n in names if n]
    if not valid:
        raise ConfigError(f"--camera {name!r}: the model has no named camera; use the free camera's "
                          "--azimuth, --elevation, --distance, --lookat")
    raise ConfigError(f"--camera {name!r}: no such camera in the model; valid: {', '.join(valid)}")


def framed_points(model: Any, data: Any, geoms: Sequence[int] | np.ndarray,
                  goals: np.ndarray | None = None) -> np.ndarray:
    """Points [m] a picture must show, shape (n, 3): geoms' bounding boxes' corners and cubes about the goals.

    The corners of each geom's box at the data's pose, and of a cube of half-side
    :data:`GOAL_ROOM` about each goal. A geom's box is MuJoCo's ``geom_aabb`` (in the geom's
    frame, turned with it); planes do not count.
    """
    import mujoco

    plane = mujoco.mjtGeom.mjGEOM_PLANE
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    points: list[np.ndarray] = [np.zeros((0, 3))]
    for g in np.asarray(geoms, dtype=int).reshape(-1):
        if int(model.geom_type[g]) == plane:
            continue
        local = model.geom_aabb[g, :3] + signs * model.geom_aabb[g, 3:]
        points.append(data.geom_xpos[g] + local @ data.geom_xmat[g].reshape(3, 3).T)
    if goals is not None and np.size(goals):  # a goal with room for its marker around it
        goals = np.asarray(goals, dtype=float).reshape(-1, 3)
        points.append((goals[:, None, :] + GOAL_ROOM * signs[None, :, :]).reshape(-1, 3))
    pts = np.concatenate(points)
    return pts if len(pts) else np.array([[-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]])


def _axes(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Forward, up and right unit vectors of MuJoCo's free camera."""
    az, el = math.radians(azimuth), math.radians(elevation)
    fwd = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    up = np.array([-math.sin(el) * math.cos(az), -math.sin(el) * math.sin(az), math.cos(el)])
    return fwd, up, np.cross(fwd, up)


def fit_camera(points: np.ndarray, *, fovy: float, aspect: float,
               azimuth: float = DEFAULT_AZIMUTH, elevation: float = DEFAULT_ELEVATION,
               lookat: Sequence[float] | None = None, distance: float | None = None,
               margin: float = FIT_MARGIN, top: float = 0.0) -> tuple[np.ndarray, float]:
    """Lookat and distance of a free camera that shows every point of ``points`` (shape (n, 3)).

    Each point ``p`` at offset ``v = p - lookat`` lies at depth ``distance + v.forward``; it is
    inside the image when ``|v.right| <= tan(fovx/2) (1 - margin) depth`` and likewise upwards
    (where the top ``top`` fraction of the image's height is kept free, for the banner). The
    smallest such distance is taken, the lookat moved to centre the points' picture in the free
    part, and the distance fitted again. A given ``lookat`` or ``distance`` is kept as given.
    """
    fwd, up, right = _axes(azimuth, elevation)
    ty = math.tan(math.radians(fovy) / 2.0) * (1.0 - margin)
    tx = math.tan(math.radians(fovy) / 2.0) * aspect * (1.0 - margin)
    w_top = 1.0 - 2.0 * float(top) / (1.0 - margin)  # highest usable y / (ty depth); the lowest is -1
    corners = np.asarray(points, dtype=float).reshape(-1, 3)
    centre = 0.5 * (corners.min(axis=0) + corners.max(axis=0)) if lookat is None else np.asarray(lookat, dtype=float)
    d = 1.0
    for _ in range(6):
        v = corners - centre
        f, x, y = v @ fwd, v @ right, v @ up
        if distance is not None:
            d = float(distance)
        else:
            need_y = np.where(y > 0, y / (ty * w_top), -y / ty)
            d = max(float(np.max(np.abs(x) / tx - f)), float(np.max(need_y - f)), 0.05)
        if lookat is not None:
            break
        depth = np.maximum(d + f, 1e-6)
        u, w = x / (tx * depth), y / (ty * depth)  # -1..1 across the usable image
        du, dw = 0.5 * (u.max() + u.min()), 0.5 * (w.max() + w.min()) - 0.5 * (w_top - 1.0)
        if abs(du) < 1e-4 and abs(dw) < 1e-4:
            break
        centre = centre + du * tx * d * right + dw * ty * d * up
    return centre, d


def frame_workspace(cam: Any, model: Any, robot: np.ndarray, others: np.ndarray, *,
                    goals: np.ndarray | None = None, aspect: float = 4.0 / 3.0, view: View | None = None,
                    data: Any = None, top: float = 0.0) -> None:
    """Point a free camera (:class:`mujoco.MjvCamera`) at the arm, the obstacles and the goals.

    The arm and obstacles are taken at ``data``'s pose (default: the model's reference pose).
    """
    import mujoco

    if data is None:
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
    view = view or View()
    points = framed_points(model, data, np.concatenate((np.asarray(robot, dtype=int), np.asarray(others, dtype=int))),
                           goals)
    az = DEFAULT_AZIMUTH if view.azimuth is None else float(view.azimuth)
    el = DEFAULT_ELEVATION if view.elevation is None else float(view.elevation)
    lookat, dist = fit_camera(points, fovy=float(model.vis.global_.fovy), aspect=aspect, azimuth=az,
                              elevation=el, lookat=view.lookat, distance=view.distance, top=top)
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = lookat
    cam.distance = dist
    cam.azimuth, cam.elevation = az, el
