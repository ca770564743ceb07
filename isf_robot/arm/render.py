"""Offscreen pictures of an arm run: a GIF or MP4 video, or one PNG frame, with the filter mode shown.

:class:`VideoRecorder` is an observer of :class:`~isf_robot.arm.ArmSimulation`: at the video's
frame times it poses a copy of the run's model at the step record's ``q`` and mocap poses,
renders it with MuJoCo's offscreen :class:`mujoco.Renderer` and draws a banner with the time
and the mode. The robot is orange while the filter is on.

What is drawn: visual geoms, not the collision geoms they cover, and a sky
(:mod:`isf_robot.arm.drawing`, on a copy of the model used for drawing only). The camera: a
named camera of the model or a free camera framing the arm, the obstacles and the goals
(:mod:`isf_robot.arm.camera`).

Writers: ``.gif`` with Pillow (a dependency of rerun-sdk), ``.mp4`` with imageio and its
ffmpeg (the ``video`` extra), ``.png`` one frame (Pillow). Files are written as
``<name>.partial`` and renamed when complete.

Offscreen OpenGL: MuJoCo picks its backend from ``MUJOCO_GL`` when it is first imported.
:func:`select_gl` (called by the command line before MuJoCo is imported) keeps a value the
user set, else tries EGL, then OSMesa, each in a short subprocess, and raises
:class:`RenderUnavailableError` (one line naming both failures) when neither works.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from isf_robot.core import ConfigError, Observer
from isf_robot.support.extras import install_hint
from isf_robot.support.files import check_output_path, commit_partial, partial_path

from .camera import View, camera_id, frame_workspace
from .drawing import drawing_model, drawn, robot_drawn_geoms

__all__ = ["VideoRecorder", "View", "select_gl", "RenderUnavailableError", "FORMATS", "ON_RGBA", "frame_workspace"]

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
        ConfigError: Unknown format, bad sizes, a bad ``at``, or an unwritable path (before any rendering).

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
        if at is not None and not (self.format == ".png" and isinstance(at, (int, float)) and math.isfinite(at)
                                   and at >= 0):
            raise ConfigError(f"the frame's time (--at) must be a number of seconds >= 0 and is for a .png only; got "
                              f"{at!r} for a {self.format} file")
        if self.format == ".mp4":
            try:
                import imageio.v2  # noqa: F401
            except ImportError:
                raise ConfigError(f"writing .mp4 needs the 'video' extra ({install_hint('video')}); "
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
