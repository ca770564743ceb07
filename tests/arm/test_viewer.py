"""`isf-robot run --view`: MuJoCo's passive viewer on the run's live data, paced, pausable."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from contextlib import nullcontext
from typing import Any

import numpy as np
import pytest

from isf_robot.arm import load_scene, resolve_params
from isf_robot.arm.render import ON_RGBA
from isf_robot.arm.sim import ArmSimulation
from isf_robot.arm.viewer import SPACE, LiveViewer, ViewerClosedError, ViewerUnavailableError, check_display


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0
        self.slept: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, s: float) -> None:
        self.slept.append(s)
        self.now += s


class FakeHandle:
    """Stands in for mujoco.viewer.Handle; ``on_sync`` runs at each sync (what the user does)."""

    def __init__(self, model: Any, data: Any, key_callback: Any, on_sync: Any = None) -> None:
        self.model, self.data, self.key = model, data, key_callback
        self.opt = type("Opt", (), {"geomgroup": np.zeros(6, dtype=np.uint8)})()
        self.cam = type("Cam", (), {"lookat": np.zeros(3), "distance": 0.0, "azimuth": 0.0, "elevation": 0.0})()
        self.running, self.synced_t, self.texts, self.rgba = True, [], [], []
        self.on_sync = on_sync

    def lock(self) -> Any:
        return nullcontext()

    def is_running(self) -> bool:
        return self.running

    def sync(self) -> None:
        self.synced_t.append(float(self.data.time))
        self.rgba.append(np.array(self.model.geom_rgba, copy=True))
        if self.on_sync is not None:
            self.on_sync(self)

    def set_texts(self, texts: Any) -> None:
        self.texts.append(texts[2])

    def close(self) -> None:
        self.running = False


def _run(scene: Any, viewer: LiveViewer | None, duration: float = 1.0) -> Any:
    obs = [viewer] if viewer is not None else []
    return ArmSimulation(scene, "isf", seed=0, params=resolve_params(scene), observers=obs).run(duration)


def test_paced_to_real_time_and_shows_every_robot_group() -> None:
    scene = load_scene("panda_pole")  # its collision geoms are in group 3, hidden by default
    clock, handles = FakeClock(), []

    def launch(m: Any, d: Any, **kw: Any) -> FakeHandle:
        handles.append(FakeHandle(m, d, kw["key_callback"]))
        return handles[0]

    v = LiveViewer(speed=2.0, launch=launch, clock=clock, sleep=clock.sleep)
    _run(scene, v, 1.0)
    h = handles[0]
    groups = {int(scene.model.geom_group[g]) for g in scene.robot_geom_ids}
    assert 3 in groups and all(h.opt.geomgroup[g] == 1 for g in groups)
    # the camera of `isf-robot render`: looking into the box of the arm, the obstacles and the goals, from 1-4 m
    box = np.vstack([scene.goal_positions, scene.model.body_pos[scene.model.body_rootid[scene.model.geom_bodyid[scene.robot_geom_ids]]]])
    assert np.all(box.min(axis=0) - 0.3 <= h.cam.lookat) and np.all(h.cam.lookat <= box.max(axis=0) + 0.3)
    assert 1.0 < h.cam.distance < 4.0
    # 1 s simulated at 2x real time: the wall clock advanced by ~0.5 s (the last step starts 1 period early)
    assert clock.now - 100.0 == pytest.approx(0.5 - 0.002 / 2.0, abs=1e-9)
    # at most 60 updates a second of wall time, and the window saw the run's data advance
    assert 25 <= v.syncs <= 31 and h.synced_t == sorted(h.synced_t) and h.synced_t[-1] > 0.9
    assert "filter" in h.texts[-1] and not h.running  # closed at the end
    # the robot is orange exactly in the frames whose overlay says the filter is on; colours restored
    robot = np.asarray(scene.robot_geom_ids)
    orange = [bool(np.allclose(rgba[robot], ON_RGBA)) for rgba in h.rgba]
    assert orange == ["filter ON" in text for text in h.texts] and any(orange) and not all(orange)
    assert not np.allclose(scene.model.geom_rgba[robot], ON_RGBA)


def test_space_pauses_and_closing_the_window_stops_the_run() -> None:
    scene = load_scene("planar_moving")
    clock = FakeClock()
    paused_syncs = []

    def on_sync(h: FakeHandle) -> None:
        if len(h.synced_t) == 5:
            h.key(SPACE)  # pause...
        elif v.paused:
            paused_syncs.append(h.data.time)
            if len(paused_syncs) == 10:
                h.key(SPACE)  # ...and resume after 10 updates
        elif len(h.synced_t) == 40:
            h.running = False  # the user closes the window

    v = LiveViewer(launch=lambda m, d, **kw: FakeHandle(m, d, kw["key_callback"], on_sync), clock=clock,
                   sleep=clock.sleep)
    with pytest.raises(ViewerClosedError, match=r"closed at t = \d"):
        _run(scene, v, 3.0)
    assert len(paused_syncs) == 10 and len(set(paused_syncs)) == 1  # the simulation did not move while paused


def test_a_drag_in_the_viewer_reaches_the_physics() -> None:
    scene = load_scene("planar_moving")
    body = int(scene.model.geom_bodyid[scene.robot_geom_ids[-1]])
    clock = FakeClock()

    def push(h: FakeHandle) -> None:  # what Ctrl + drag does: a force on a body of the live data
        h.data.xfrc_applied[body, :3] = (0.0, 40.0, 0.0)

    v = LiveViewer(launch=lambda m, d, **kw: FakeHandle(m, d, kw["key_callback"], push), clock=clock,
                   sleep=clock.sleep)
    pushed = _run(scene, v, 0.5)
    plain = _run(scene, None, 0.5)
    assert pushed.tracking_error_q99 > 10.0 * plain.tracking_error_q99  # the arm was pushed off its command


def test_no_display_is_one_line_before_simulating(monkeypatch: pytest.MonkeyPatch, capsys) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    if sys.platform.startswith("linux"):
        with pytest.raises(ViewerUnavailableError, match="needs a display"):
            check_display({})
        check_display({"DISPLAY": ":0"})
        monkeypatch.delenv("DISPLAY", raising=False)
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        assert main(["run", "--scene", "planar", "--view", "--duration", "0.1"]) == 2
        err = capsys.readouterr()
        assert "needs a display" in err.err and err.err.count("\n") == 1 and "scene" not in err.out
    with pytest.raises(Exception, match="positive"):
        LiveViewer(speed=0.0)


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run is not installed (Debian: xvfb)")
def test_real_viewer_under_xvfb() -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY")}
    proc = subprocess.run(["xvfb-run", "-a", sys.executable, "-m", "isf_robot.cli", "run", "--scene", "planar_moving",
                           "--duration", "0.5", "--view", "--view-speed", "5"],
                          capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "duty cycle" in proc.stdout


def test_a_vendor_arm_shows_its_visual_geoms_and_gets_its_colours_back(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.arm.scene import load_scene_from_files

    from .test_render import VENDOR_TOML, VENDOR_XML

    (tmp_path / "arm.xml").write_text(VENDOR_XML)
    (tmp_path / "arm.toml").write_text(VENDOR_TOML)
    scene = load_scene_from_files(tmp_path / "arm.xml", tmp_path / "arm.toml")
    m = scene.model
    rgba0 = np.array(m.geom_rgba, copy=True)
    capsules = [g for g in range(m.ngeom) if m.geom_type[g] == 3]  # the links' collision capsules
    hand = m.geom("hand").id  # a body with only a collision geom: drawn
    seen: list[np.ndarray] = []

    def launch(mm: Any, d: Any, **kw: Any) -> FakeHandle:
        h = FakeHandle(mm, d, kw["key_callback"], on_sync=lambda hh: seen.append(np.array(mm.geom_rgba, copy=True)))
        return h

    clock = FakeClock()
    _run(scene, LiveViewer(speed=50.0, launch=launch, clock=clock, sleep=clock.sleep), 0.2)
    assert seen and capsules
    assert all(r[capsules, 3].max() == 0.0 and r[hand, 3] > 0 for r in seen)  # hidden while shown, the hand drawn
    assert np.array_equal(m.geom_rgba, rgba0)  # the model's colours back when the window closed
    clock = FakeClock()
    seen.clear()
    _run(scene, LiveViewer(speed=50.0, show_collision=True, launch=launch, clock=clock, sleep=clock.sleep), 0.2)
    assert seen and all(r[capsules, 3].min() > 0 for r in seen)
