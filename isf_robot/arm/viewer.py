"""Watch an arm run live in MuJoCo's passive viewer (``isf-robot run --view``).

:class:`LiveViewer` is an observer of :class:`~isf_robot.arm.ArmSimulation`. It opens
:func:`mujoco.viewer.launch_passive` on the run's own model and data (the start info's
``model`` and ``data``), so what the viewer does to the data reaches the physics: a body
dragged with Ctrl + right/left mouse button gets ``xfrc_applied`` forces, a disturbance the
filter has to answer. The viewer's left panel switches geom groups, frames and contacts; the
robot and obstacle geoms' groups are switched on at the start whatever their group, and the camera
looks at the workspace as in ``isf-robot render``. The run is
paced to ``speed`` x real time; Space pauses and resumes it; the robot is orange while the filter
is on; the overlay shows the time, the
filter mode, ``min h`` and ``min Xi_on``. The window is updated at most 60 times a second of
wall time, and at most every other sync's duration, so a slow (software) renderer shows fewer
frames instead of slowing the run. Closing the window stops the run (:class:`ViewerClosedError`).

The viewer needs a display (X11 or Wayland, ``DISPLAY``/``WAYLAND_DISPLAY``); without one
:func:`check_display` raises a one-line error before anything is simulated. On macOS MuJoCo's
passive viewer needs the ``mjpython`` launcher.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from isf_robot.core import ConfigError, IsfError, Observer

from .camera import frame_workspace
from .drawing import hidden_collision_geoms, robot_drawn_geoms
from .render import ON_RGBA

__all__ = ["LiveViewer", "ViewerUnavailableError", "ViewerClosedError", "check_display"]

SPACE = 32
"""GLFW key code of the space bar (pause / resume)."""
SYNC_HZ = 60.0
"""Most viewer updates per second of wall time."""


class ViewerUnavailableError(ConfigError):
    """No display for MuJoCo's viewer."""


class ViewerClosedError(IsfError):
    """The viewer window was closed: the run stops there."""


def check_display(environ: Mapping[str, str] | None = None) -> None:
    """Raise :class:`ViewerUnavailableError` when there is no display to open a window on."""
    env = os.environ if environ is None else environ
    if sys.platform.startswith("linux") and not (env.get("DISPLAY") or env.get("WAYLAND_DISPLAY")):
        raise ViewerUnavailableError(
            "--view needs a display (DISPLAY and WAYLAND_DISPLAY are unset); on a machine without one use "
            "--rrd (Rerun) or `isf-robot render` (offscreen video), or run under `xvfb-run`")


class LiveViewer(Observer):
    """Show the run in MuJoCo's passive viewer, in real time, with pause and perturbation.

    Args:
        speed: Simulated seconds per second of wall time (1: real time).
        show_collision: Also draw the collision geoms of bodies that have visual geoms (hidden by
            default, as in ``isf-robot render``; the model's colours come back when the window closes).
        launch: Replaces :func:`mujoco.viewer.launch_passive` (tests).
        clock: Replaces :func:`time.monotonic` (tests).
        sleep: Replaces :func:`time.sleep` (tests).

    """

    def __init__(self, speed: float = 1.0, *, show_collision: bool = False, launch: Callable[..., Any] | None = None,
                 clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep) -> None:
        if not (math.isfinite(speed) and speed > 0):
            raise ConfigError(f"viewer speed must be a positive number (1 = real time), got {speed}")
        self.speed = float(speed)
        self.show_collision = bool(show_collision)
        self._launch, self._clock, self._sleep = launch, clock, sleep
        self.handle: Any = None
        self._threads: list[threading.Thread] = []
        self._model: Any = None
        self._robot = np.zeros(0, dtype=int)
        self._rgba = np.zeros((0, 4))
        self._hidden = np.zeros(0, dtype=int)
        self._hidden_rgba = np.zeros((0, 4))
        self._on = False
        self.paused = False
        self.syncs = 0
        self._t0_wall = 0.0
        self._t0_sim = 0.0
        self._last_sync = -math.inf
        self._sync_cost = 0.0

    def _key(self, key: int) -> None:
        """Space: pause or resume (called from the viewer's thread)."""
        if key == SPACE:
            self.paused = not self.paused

    def on_start(self, info: Mapping[str, Any]) -> None:
        """Open the viewer on the run's model and data; show every robot and obstacle geom's group."""
        model, data = info.get("model"), info.get("data")
        if model is None or data is None:
            raise ConfigError("LiveViewer needs the arm loop's start info (model and the live data)")
        launch = self._launch
        if launch is None:
            check_display()
            import mujoco.viewer

            launch = mujoco.viewer.launch_passive
        before = set(threading.enumerate())
        try:
            self.handle = launch(model, data, key_callback=self._key, show_left_ui=True, show_right_ui=True)
        except Exception as exc:  # GLFW without a usable display
            raise ViewerUnavailableError(f"MuJoCo's viewer could not open a window: {' '.join(str(exc).split())}; "
                                         "use --rrd or `isf-robot render` instead") from None
        self._threads = [t for t in threading.enumerate() if t not in before]  # the viewer's window thread
        robot, others = (np.asarray(info.get(key, ()), dtype=int).reshape(-1)
                         for key in ("robot_geom_ids", "obstacle_geom_ids"))
        # as `isf-robot render`: the visual geoms, not the collision geoms of bodies that have visual ones
        hidden = np.zeros(0, dtype=int) if self.show_collision else hidden_collision_geoms(model)
        shown = np.setdiff1d(robot_drawn_geoms(model, robot, others), hidden)
        groups = {int(model.geom_group[g]) for g in np.concatenate((shown, np.setdiff1d(others, hidden)))}
        self._model, self._robot, self._on = model, shown, False
        self._rgba = np.array(model.geom_rgba[shown], copy=True)  # restored when the window closes
        self._hidden, self._hidden_rgba = hidden, np.array(model.geom_rgba[hidden], copy=True)
        with self.handle.lock():
            model.geom_rgba[hidden, 3] = 0.0  # (drawing only: no physics reads geom_rgba)
            for g in groups:
                if 0 <= g < len(self.handle.opt.geomgroup):
                    self.handle.opt.geomgroup[g] = 1
            goals = info.get("goals")
            frame_workspace(self.handle.cam, model, robot, others, data=data,  # the camera of `isf-robot render`
                            goals=None if goals is None else np.asarray(goals, dtype=float))
        self._title = f"{info.get('scene', '')} {info.get('strategy', '')} seed {info.get('seed', '')}"
        self._t0_wall, self._t0_sim = self._clock(), 0.0

    def on_step(self, record: Any) -> None:
        """Wait for the record's time on the wall clock (and while paused), then update the window."""
        h = self.handle
        if not h.is_running():
            raise ViewerClosedError(f"the viewer was closed at t = {float(record.t):.3f} s; the run stopped there")
        t = float(record.t)
        if bool(record.on) != self._on:
            self._on = bool(record.on)
            self._tint(self._on)
        if self.paused:
            self._overlay(record, paused=True)
            h.sync()
            while self.paused and h.is_running():
                self._sleep(1.0 / SYNC_HZ)
                h.sync()
            self._t0_wall, self._t0_sim = self._clock(), t  # resume from here in real time
        ahead = (t - self._t0_sim) / self.speed - (self._clock() - self._t0_wall)
        if ahead > 0:
            self._sleep(ahead)
        now = self._clock()
        if now - self._last_sync >= max(1.0 / SYNC_HZ, 2.0 * self._sync_cost):
            self._overlay(record)
            h.sync()
            self.syncs += 1
            self._last_sync = after = self._clock()
            self._sync_cost = after - now  # a slow (software) renderer gets fewer frames; the run keeps time

    def _tint(self, on: bool) -> None:
        """The robot orange while the filter is on (as in the Rerun view and the videos), else its colours.

        Only the shared model's ``geom_rgba`` changes (no physics reads it), under the viewer's lock.
        """
        if self._robot.size:
            with self.handle.lock():
                self._model.geom_rgba[self._robot] = ON_RGBA if on else self._rgba

    def _overlay(self, record: Any, paused: bool = False) -> None:
        import mujoco

        xi = float(getattr(record, "xi_min", math.nan))
        text = (f"{self._title}\nt = {float(record.t):.2f} s{'  (paused: space)' if paused else ''}\n"
                f"filter {'ON' if record.on else 'off'}\nmin h = {float(record.h_min):.4f} m\n"
                f"min Xi_on = {xi:.4g}")
        self.handle.set_texts((None, mujoco.mjtGridPos.mjGRID_TOPLEFT, text, None))

    def _close(self) -> None:
        h = self.handle
        if h is None:
            return
        if self._on:  # the model is the scene's: leave its colours as they were
            self._tint(False)
        if self._hidden.size:
            with h.lock():
                self._model.geom_rgba[self._hidden] = self._hidden_rgba
        self.handle = None
        h.close()
        for t in self._threads:  # let the window thread tear GLFW down before the interpreter exits
            t.join(timeout=5.0)

    def on_finish(self, summary: Mapping[str, Any]) -> None:
        """Close the window."""
        self._close()

    def on_abort(self, reason: BaseException) -> None:
        """Close the window (the run stopped)."""
        self._close()
