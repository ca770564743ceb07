"""Offscreen pictures of an arm run: a GIF or MP4 video, or one PNG frame, with the filter mode shown.

:class:`VideoRecorder` is an observer of :class:`~isf_robot.arm.ArmSimulation`: at the video's
frame times it poses a copy of the run's model at the step record's ``q`` and mocap poses,
renders it with MuJoCo's offscreen :class:`mujoco.Renderer` and draws a banner with the time
and the mode. The robot is orange while the filter is on.

What is drawn (:func:`drawing_model`, on a copy of the model used for drawing only; the
simulated model is never changed):

* visual geoms (``contype = conaffinity = 0``) as the model draws them; a collision geom is
  hidden when its body (not the world) has visual geoms, so a vendor's collision meshes or
  primitives (Menagerie: group 3, or group 0) do not speckle the visual meshes; a body with
  only collision geoms keeps them. ``show_collision`` draws them all;
* MuJoCo's default geom groups (0, 1, 2) and every group of the robot's and obstacles' drawn geoms;
* a sky: a gradient skybox texture is added (through :class:`mujoco.MjSpec`, from the model's
  file) when the model has none.

The camera (:class:`View`): a named camera of the model, or a free camera whose lookat and
distance fit the arm (the bounding boxes of its drawn geoms at the first frame's pose), the
obstacles and the goals (:func:`fit_camera`); azimuth, elevation, distance and lookat can
each be given.

Writers: ``.gif`` with Pillow (a dependency of rerun-sdk), ``.mp4`` with imageio and its
ffmpeg (the ``video`` extra), ``.png`` one frame (Pillow). Files are written as
``<name>.partial`` and renamed when complete.

Offscreen OpenGL: MuJoCo picks its backend from ``MUJOCO_GL`` when it is first imported.
:func:`select_gl` (called by the command line before MuJoCo is imported) keeps a value the
user set, else tries EGL, then OSMesa, each in a short subprocess, and raises
:class:`RenderUnavailableError` (one line naming both failures) when neither works.
"""

from __future__ import annotations

import copy
import math
import os
import subprocess
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from isf_robot.core import ConfigError, Observer
from isf_robot.core.files import check_output_path, commit_partial, partial_path

__all__ = ["VideoRecorder", "View", "select_gl", "RenderUnavailableError", "FORMATS", "ON_RGBA", "frame_workspace",
           "fit_camera", "framed_points", "drawing_model", "hidden_collision_geoms", "camera_id", "parse_lookat"]

FORMATS = (".gif", ".mp4", ".png")
ON_RGBA = (1.0, 0.55, 0.0, 1.0)
"""Colour of the robot while the filter is on."""
GL_BACKENDS = ("egl", "osmesa")
_PROBE = ("import mujoco; m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\"1\"/></worldbody>"
          "</mujoco>'); r = mujoco.Renderer(m, 8, 8); r.update_scene(mujoco.MjData(m)); r.render()")


class RenderUnavailableError(ConfigError):
    """No offscreen OpenGL backend works on this machine."""


def _probe(backend: str) -> str | None:
    """``None`` when MuJoCo renders offscreen with ``backend``, else the reason (last line of the error)."""
    env = dict(os.environ, MUJOCO_GL=backend, PYOPENGL_PLATFORM=backend)
    try:
        out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return str(exc)
    if out.returncode == 0:
        return None
    lines = [ln.strip() for ln in out.stderr.splitlines() if ln.strip()]
    return lines[-1] if lines else f"exit status {out.returncode}"


def select_gl(backends: Sequence[str] = GL_BACKENDS) -> str:
    """Choose the offscreen OpenGL backend and set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``).

    A ``MUJOCO_GL`` set by the user is kept as it is (and checked). Must run before MuJoCo is
    imported to take effect; when it already is, the backend it chose stays.

    Raises:
        RenderUnavailableError: No backend works (the message says why for each).

    """
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    candidates = [chosen] if chosen else list(backends)
    reasons = []
    for b in candidates:
        why = _probe(b)
        if why is None:
            os.environ["MUJOCO_GL"] = b
            os.environ.setdefault("PYOPENGL_PLATFORM", b)
            return b
        reasons.append(f"{b}: {why}")
    hint = ("unset MUJOCO_GL to try EGL and OSMesa" if chosen else
            "install EGL (Debian: libegl1) or OSMesa (libosmesa6), or run where a GPU driver is present")
    raise RenderUnavailableError(f"offscreen rendering is not available ({'; '.join(reasons)}); {hint}")


SKY_TOP = (0.42, 0.62, 0.85)
"""Colour of the added sky at the zenith (a gradient to :data:`SKY_BOTTOM` at the horizon and below)."""
SKY_BOTTOM = (0.93, 0.95, 0.98)
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
        for k in ("azimuth", "elevation", "distance"):
            v = free[k]
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


def _is_visual(model: Any, g: int) -> bool:
    return int(model.geom_contype[g]) == 0 and int(model.geom_conaffinity[g]) == 0


def hidden_collision_geoms(model: Any) -> np.ndarray:
    """Collision geoms whose body (not the world) also has visual geoms (``contype = conaffinity = 0``)."""
    import mujoco

    ids = np.arange(model.ngeom)
    body = np.asarray(model.geom_bodyid)
    visual = (np.asarray(model.geom_contype) == 0) & (np.asarray(model.geom_conaffinity) == 0)
    visual &= np.asarray(model.geom_type) != mujoco.mjtGeom.mjGEOM_PLANE
    with_visual = set(body[visual].tolist()) - {0}
    return ids[~visual & np.isin(body, list(with_visual)) & (np.asarray(model.geom_contype) | np.asarray(
        model.geom_conaffinity) != 0)]


def _has_sky(model: Any) -> bool:
    import mujoco

    return bool(np.any(np.asarray(model.tex_type) == mujoco.mjtTexture.mjTEXTURE_SKYBOX))


def _with_sky(model: Any, path: str | Path | None) -> Any:
    """A copy of ``model`` with a gradient skybox, compiled again from its file; ``None`` when that is not the same model."""
    import mujoco

    if path is None or not Path(path).is_file():
        return None
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        spec.add_texture(name="isf_robot_render_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                         builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=list(SKY_TOP), rgb2=list(SKY_BOTTOM),
                         width=256, height=256)
        sky = spec.compile()
    except Exception:  # a file MuJoCo's spec reader takes differently: no sky rather than no picture
        return None
    same = all(getattr(sky, k) == getattr(model, k) for k in ("nq", "nbody", "ngeom", "nsite", "nmocap", "ncam",
                                                                 "nmat"))
    if not same or not (np.allclose(sky.geom_size, model.geom_size) and np.allclose(sky.body_pos, model.body_pos)):
        return None
    for key in ("geom_rgba", "geom_group", "geom_matid", "site_rgba", "site_group", "mat_rgba"):
        getattr(sky, key)[:] = getattr(model, key)
    return sky


def drawing_model(model: Any, robot: np.ndarray, others: np.ndarray, *, show_collision: bool = False,
                  model_path: str | Path | None = None, sky: bool = True) -> tuple[Any, Any]:
    """A copy of ``model`` for drawing and the :class:`mujoco.MjvOption` to draw it with.

    Collision geoms of bodies that have visual geoms get alpha 0 (MuJoCo skips them) unless
    ``show_collision``; a gradient skybox is added when the model has none and its file is given.
    The geom groups drawn are MuJoCo's default ones and every group of the robot's and the
    obstacles' bodies' drawn geoms.
    """
    import mujoco

    m = (_with_sky(model, model_path) if sky and not _has_sky(model) else None) or copy.deepcopy(model)
    if not show_collision:
        hide = hidden_collision_geoms(m)
        m.geom_rgba[hide, 3] = 0.0
        m.geom_matid[hide] = -1
    option = mujoco.MjvOption()
    ids = np.concatenate((np.asarray(robot, dtype=int), np.asarray(others, dtype=int)))
    for g in drawn(m, ids):
        option.geomgroup[int(m.geom_group[g])] = 1
    return m, option


def drawn(model: Any, geoms: np.ndarray) -> np.ndarray:
    """The geoms among ``geoms`` and the other geoms of their bodies (not the world) that are drawn (alpha > 0)."""
    geoms = np.asarray(geoms, dtype=int)
    bodies = set(np.asarray(model.geom_bodyid)[geoms].tolist()) - {0}
    out = [g for g in range(model.ngeom) if (g in set(geoms.tolist()) or int(model.geom_bodyid[g]) in bodies)
           and float(model.geom_rgba[g, 3]) > 0]
    return np.asarray(out, dtype=int)


def robot_drawn_geoms(model: Any, robot: np.ndarray, others: np.ndarray) -> np.ndarray:
    """The geoms that show the robot: every drawn geom of the robot's subtrees (not the obstacles')."""
    robot = np.asarray(robot, dtype=int)
    if robot.size == 0:
        return robot
    roots = set(np.asarray(model.body_rootid)[np.asarray(model.geom_bodyid)[robot]].tolist()) - {0}
    obstacle_bodies = set(np.asarray(model.geom_bodyid)[np.asarray(others, dtype=int)].tolist())
    out = [g for g in range(model.ngeom)
           if int(model.body_rootid[int(model.geom_bodyid[g])]) in roots
           and int(model.geom_bodyid[g]) not in obstacle_bodies and float(model.geom_rgba[g, 3]) > 0]
    return np.union1d(np.asarray(out, dtype=int), robot[np.asarray(model.geom_rgba)[robot, 3] > 0])


def framed_points(model: Any, data: Any, geoms: Sequence[int], goals: np.ndarray | None = None) -> np.ndarray:
    """Points [m] a picture must show, shape (n, 3): the corners of each geom's bounding box at the data's pose, and
    of a cube of half-side :data:`GOAL_ROOM` about each goal.

    A geom's box is MuJoCo's ``geom_aabb`` (in the geom's frame, turned with it); planes do not count.
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


class VideoRecorder(Observer):
    """Render an arm run offscreen into a video (``.gif``/``.mp4``) or one frame (``.png``).

    Args:
        path: Output file; its suffix picks the format (:data:`FORMATS`).
        fps: Frames per second of video (simulated time runs at ``speed`` x real time).
        width: Frame width [px].
        height: Frame height [px].
        speed: Simulated seconds per second of video.
        at: ``.png`` only: the time [s] of the frame (default: the first step with the filter
            on, else the last step).
        view: The camera (default: the free camera framing the arm, obstacles and goals).
        show_collision: Draw the collision geoms that visual geoms of their body would show instead.
        sky: Add a gradient sky when the model has none (needs the model's file, ``model_path``
            of the start info).

    Raises:
        ConfigError: Unknown format, bad sizes, or an unwritable path (before any rendering).

    """

    def __init__(self, path: str | Path, *, fps: float = 20.0, width: int = 480, height: int = 360,
                 speed: float = 1.0, at: float | None = None, view: View | None = None,
                 show_collision: bool = False, sky: bool = True) -> None:
        self.path = check_output_path(path, "video file")
        self.format = self.path.suffix.lower()
        if self.format not in FORMATS:
            raise ConfigError(f"video file {str(path)!r}: unknown format {self.format or '(none)'}; "
                              f"valid: {', '.join(FORMATS)}")
        if not (16 <= int(width) <= 4096 and 16 <= int(height) <= 4096):
            raise ConfigError(f"frame size must be 16..4096 px, got {width} x {height}")
        if not (math.isfinite(fps) and 0 < fps <= 120 and math.isfinite(speed) and speed > 0):
            raise ConfigError(f"fps must be in (0, 120] and speed > 0, got fps={fps}, speed={speed}")
        if self.format == ".mp4":
            try:
                import imageio.v2  # noqa: F401
            except ImportError:
                raise ConfigError("writing .mp4 needs the 'video' extra (pip install 'isf-robot[video]'); "
                                  ".gif and .png need nothing more") from None
        self.fps, self.width, self.height, self.speed, self.at = float(fps), int(width), int(height), float(speed), at
        self.view = view or View()
        self.show_collision, self.sky = bool(show_collision), bool(sky)
        self.frames: list[np.ndarray] = []
        self.frame_times: list[float] = []
        self.render_s = 0.0
        self._next = 0.0
        self._title = ""
        self._writer: Any = None
        self._best: tuple[float, Any] | None = None  # (time, step record) of the still

    # -- observer hooks ------------------------------------------------------------------
    def on_start(self, info: Mapping[str, Any]) -> None:
        """Copy the model, colour it, place the camera, open the renderer."""
        import mujoco

        model = info.get("model")
        if model is None or info.get("qpos_adr") is None:
            raise ConfigError("VideoRecorder needs the arm loop's start info (model, qpos_adr)")
        robot = np.asarray(info.get("robot_geom_ids", ()), dtype=int)
        others = np.asarray(info.get("obstacle_geom_ids", ()), dtype=int)
        cam_id = camera_id(model, self.view.camera) if self.view.camera is not None else -1
        m, self.option = drawing_model(model, robot, others, show_collision=self.show_collision,
                                       model_path=info.get("model_path"), sky=self.sky)
        self.model = m
        self.data = mujoco.MjData(m)
        self.qpos_adr = np.asarray(info["qpos_adr"], dtype=int)
        self.robot = robot_drawn_geoms(m, robot, others)
        self.robot_rgba = m.geom_rgba[self.robot].copy()
        self.robot_matid = m.geom_matid[self.robot].copy()
        m.vis.headlight.ambient[:] = np.maximum(m.vis.headlight.ambient, 0.35)
        m.vis.global_.offwidth = max(int(m.vis.global_.offwidth), self.width)
        m.vis.global_.offheight = max(int(m.vis.global_.offheight), self.height)
        try:
            self.renderer = mujoco.Renderer(m, self.height, self.width)
        except Exception as exc:  # no GL context: say which variable picks it
            raise RenderUnavailableError(
                f"MuJoCo cannot render offscreen with MUJOCO_GL={os.environ.get('MUJOCO_GL', '(unset)')}: "
                f"{' '.join(str(exc).split())}; set MUJOCO_GL=egl (or osmesa) before starting") from None
        cam = mujoco.MjvCamera()
        if cam_id >= 0:
            cam.type, cam.fixedcamid = mujoco.mjtCamera.mjCAMERA_FIXED, cam_id
        self.camera = cam
        self._framed = cam_id >= 0  # the free camera is fitted at the first frame's pose
        goals = info.get("goals")
        self._goals = None if goals is None else np.asarray(goals, dtype=float).reshape(-1, 3)
        self._frame_geoms = np.union1d(self.robot, drawn(m, others))
        scene_flags = self.renderer.scene.flags
        scene_flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0  # several times faster on a CPU renderer
        scene_flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        self._title = f"{info.get('scene', '')}  {info.get('strategy', '')}  seed {info.get('seed', '')}"
        if self.format == ".mp4":
            import imageio.v2 as imageio

            self._writer = imageio.get_writer(self._mp4_tmp(), format="FFMPEG", fps=self.fps,
                                              codec="libx264", quality=7, macro_block_size=8)

    def on_step(self, record: Any) -> None:
        """Render a frame when the record reaches the next frame time."""
        t = float(record.t)
        if self.format == ".png":
            self._consider_still(t, record)
            return
        if t + 1e-9 < self._next:
            return
        self._next += self.speed / self.fps
        self._add(self.render(record))

    def on_finish(self, summary: Mapping[str, Any]) -> None:
        """Write the file (``.partial``, then renamed)."""
        tmp = partial_path(self.path)
        if self.format == ".mp4":
            self._writer.close()
            os.replace(self._mp4_tmp(), tmp)  # ffmpeg wants the .mp4 suffix while it writes
        elif self.format == ".gif":
            from PIL import Image

            if not self.frames:
                raise ConfigError("the run was too short for one video frame")
            imgs = [Image.fromarray(f).quantize(colors=128, method=Image.Quantize.MEDIANCUT) for f in self.frames]
            imgs[0].save(tmp, format="GIF", save_all=True, append_images=imgs[1:],
                         duration=int(round(1000 / self.fps)), loop=0, optimize=True)
        else:
            from PIL import Image

            assert self._best is not None
            Image.fromarray(self.render(self._best[1])).save(tmp, format="PNG", optimize=True)
        commit_partial(self.path)
        self.renderer.close()

    def on_abort(self, reason: BaseException) -> None:
        """The run stopped: close the writer, leave ``<name>.partial``."""
        if self._writer is not None:
            self._writer.close()

    # -- frames --------------------------------------------------------------------------
    def _mp4_tmp(self) -> Path:
        return self.path.with_name(self.path.name + ".partial.mp4")

    def _add(self, frame: np.ndarray) -> None:
        if self._writer is not None:
            self._writer.append_data(frame)
        else:
            self.frames.append(frame)

    def _consider_still(self, t: float, record: Any) -> None:
        """Keep the record of the still: the one at ``at``, else the first with the filter on."""
        if self.at is not None:
            if self._best is None or abs(t - self.at) < abs(self._best[0] - self.at):
                self._best = (t, record)
        elif self._best is None or (record.on and not self._best[1].on):
            self._best = (t, record)

    def render(self, record: Any) -> np.ndarray:
        """The frame of one step record: pose, colours, camera, banner; (height, width, 3) uint8."""
        import time

        import mujoco

        t0 = time.perf_counter()
        m, d = self.model, self.data
        d.qpos[self.qpos_adr] = record.q
        if m.nmocap:
            d.mocap_pos[:] = record.mocap_pos
            d.mocap_quat[:] = record.mocap_quat
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)  # cameras and lights follow their bodies
        if not self._framed:
            frame_workspace(self.camera, m, self._frame_geoms, np.zeros(0, dtype=int), goals=self._goals,
                            aspect=self.width / self.height, view=self.view, data=d,
                            top=self._banner_height() / self.height)
            self._framed = True
        if record.on:
            m.geom_rgba[self.robot] = ON_RGBA
            m.geom_matid[self.robot] = -1  # a material's colour would win over the geom's
        else:
            m.geom_rgba[self.robot] = self.robot_rgba
            m.geom_matid[self.robot] = self.robot_matid
        self.renderer.update_scene(d, camera=self.camera, scene_option=self.option)
        frame = np.array(self.renderer.render(), copy=True)
        self._banner(frame, float(record.t), bool(record.on))
        self.render_s += time.perf_counter() - t0
        self.frame_times.append(float(record.t))
        return frame

    def _banner_height(self) -> int:
        return max(14, self.height // 16)

    def _banner(self, frame: np.ndarray, t: float, on: bool) -> None:
        """A strip at the top: orange 'filter ON' or grey 'filter off', the time and the run."""
        from PIL import Image, ImageDraw

        h = self._banner_height()
        frame[:h] = (230, 120, 0) if on else (60, 60, 60)
        img = Image.fromarray(frame[:h])
        draw = ImageDraw.Draw(img)
        draw.text((6, max(0, (h - 11) // 2)), f"filter {'ON ' if on else 'off'}   t = {t:6.2f} s   {self._title}",
                  fill=(255, 255, 255))
        frame[:h] = np.asarray(img)
