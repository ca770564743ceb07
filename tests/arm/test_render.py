"""`isf-robot render`: a playable video of a run, rendered offscreen, the filter mode visible."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from isf_robot.core import ConfigError


def _render(tmp_path: Path, name: str, *extra: str, duration: float = 4.5) -> tuple[Path, subprocess.CompletedProcess[str]]:
    """Render planar_moving (the filter first turns on at 3.45 s) at 10 frames/s."""
    out = tmp_path / name
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    proc = subprocess.run([sys.executable, "-m", "isf_robot.cli", "render", "--scene", "planar_moving",
                           "--duration", str(duration), "-o", str(out), "--width", "128", "--height", "96", "--fps", "10",
                           *extra], capture_output=True, text=True, env=env, timeout=300)
    if proc.returncode == 2 and "offscreen rendering is not available" in proc.stderr:
        pytest.skip(f"no offscreen OpenGL here: {proc.stderr.strip()}")
    assert proc.returncode == 0, proc.stderr
    return out, proc


def _banner_is_orange(frame: np.ndarray) -> bool:
    r, g, b = frame[2, -3, :3].astype(int)  # right end of the banner, past any text
    return r > 200 and 90 < g < 150 and b < 40


def test_gif_has_a_frame_per_tenth_second_and_shows_the_mode(tmp_path: Path) -> None:
    from PIL import Image, ImageSequence

    from isf_robot.arm import load_scene, resolve_params
    from isf_robot.arm.sim import ArmSimulation
    from isf_robot.core import Observer

    out, proc = _render(tmp_path, "run.gif")
    assert "wrote" in proc.stderr and "frames/s" in proc.stderr
    img = Image.open(out)
    frames = [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(img)]
    assert len(frames) == 45 and frames[0].shape == (96, 128, 3)
    assert not np.array_equal(frames[0], frames[-1])  # the arm moves
    assert not (tmp_path / "run.gif.partial").exists()

    # the banner is orange exactly in the frames whose step had the filter on (same episode, no video)
    class Modes(Observer):
        """The mode at the first step at or after each 0.1 s."""

        def __init__(self) -> None:
            self.on: list[bool] = []

        def on_step(self, record) -> None:  # type: ignore[no-untyped-def]
            if record.t + 1e-9 >= 0.1 * len(self.on):
                self.on.append(bool(record.on))

    scene = load_scene("planar_moving")
    modes = Modes()
    ArmSimulation(scene, "isf", seed=0, params=resolve_params(scene), observers=[modes]).run(4.5)
    want = modes.on
    assert any(want) and not all(want)
    assert [_banner_is_orange(f) for f in frames] == want


def test_png_is_one_frame_with_the_filter_on(tmp_path: Path) -> None:
    from PIL import Image

    out, _ = _render(tmp_path, "still.png", duration=3.6)
    frame = np.asarray(Image.open(out).convert("RGB"))
    assert frame.shape == (96, 128, 3) and _banner_is_orange(frame)


def test_mp4_when_the_video_extra_is_installed(tmp_path: Path) -> None:
    imageio = pytest.importorskip("imageio.v2", reason="the 'video' extra (imageio) is not installed")
    pytest.importorskip("imageio_ffmpeg", reason="the 'video' extra (imageio-ffmpeg) is not installed")
    out, _ = _render(tmp_path, "run.mp4")
    reader = imageio.get_reader(out, format="FFMPEG")
    assert reader.count_frames() == 45
    assert reader.get_data(0).shape[:2] == (96, 128)


def test_no_backend_is_one_clear_line(monkeypatch: pytest.MonkeyPatch) -> None:
    from isf_robot.arm.render import RenderUnavailableError, select_gl

    monkeypatch.delenv("MUJOCO_GL", raising=False)
    with pytest.raises(RenderUnavailableError) as err:
        select_gl(backends=("nope1", "nope2"))
    msg = str(err.value)
    assert "\n" not in msg and "nope1:" in msg and "nope2:" in msg and "EGL" in msg
    assert "MUJOCO_GL" not in os.environ


def test_bad_output_names_the_valid_formats(tmp_path: Path) -> None:
    from isf_robot.arm.render import VideoRecorder

    with pytest.raises(ConfigError, match=r"\.gif, \.mp4, \.png"):
        VideoRecorder(tmp_path / "x.avi")
    with pytest.raises(ConfigError, match="16..4096"):
        VideoRecorder(tmp_path / "x.gif", width=5)


def test_run_video_writes_the_run_it_reports(tmp_path: Path) -> None:
    from PIL import Image, ImageSequence

    out = tmp_path / "run.gif"
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    cmd = [sys.executable, "-m", "isf_robot.cli", "run", "--scene", "planar_moving", "--duration", "0.5", "--json"]
    proc = subprocess.run([*cmd, "--video", str(out)], capture_output=True, text=True, env=env, timeout=300)
    if proc.returncode == 2 and "offscreen rendering is not available" in proc.stderr:
        pytest.skip(f"no offscreen OpenGL here: {proc.stderr.strip()}")
    assert proc.returncode == 0, proc.stderr
    assert '"schema"' in proc.stdout  # the run's own output is unchanged
    assert len(list(ImageSequence.Iterator(Image.open(out)))) == 10  # 0.5 s at 20 frames/s
    bad = subprocess.run([*cmd, "--video", str(tmp_path / "x.avi")], capture_output=True, text=True, env=env,
                         timeout=300)
    assert bad.returncode == 2 and "valid: .gif, .mp4, .png" in bad.stderr and bad.stdout == ""


# -- a vendor's arm: visual geoms over collision geoms, framing, cameras, sky ---------------------------

# Menagerie-style: visual boxes in a "visual" class (group 2, contype = conaffinity = 0), collision
# capsules that enclose them in group 3 of another colour; the hand has only a collision geom.
# Every object has a colour of its own, told apart by chromaticity in the picture.
VENDOR_XML = """<mujoco model="vendor_style">
  <compiler angle="radian"/>
  <option timestep="0.002" ccd_tolerance="1e-10"/>
  <default>
    <default class="arm">
      <joint type="hinge" axis="0 0 1" range="-2.9 2.9" damping="0.5" armature="0.01"/>
      <motor ctrllimited="true" ctrlrange="-20 20"/>
      <default class="visual"><geom group="2" contype="0" conaffinity="0" rgba="0.1 0.85 0.1 1"/></default>
      <default class="collision"><geom group="3" rgba="0.9 0.1 0.9 1"/></default>
    </default>
  </default>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1"/>
    <geom name="floor" type="plane" size="3 3 0.05" rgba="0.8 0.8 0.8 1" contype="0" conaffinity="0"/>
    <camera name="top" pos="0.3 0 2.0" xyaxes="1 0 0 0 1 0"/>
    <camera name="side" pos="0.3 -2 0.5" xyaxes="1 0 0 0 0 1"/>
    <body name="link1" pos="0 0 0.2" childclass="arm">
      <joint name="j1"/>
      <geom class="visual" type="box" size="0.2 0.04 0.04" pos="0.2 0 0"/>
      <geom class="collision" type="capsule" fromto="0 0 0 0.4 0 0" size="0.06" mass="1"/>
      <body name="link2" pos="0.4 0 0">
        <joint name="j2"/>
        <geom class="visual" type="box" size="0.15 0.035 0.035" pos="0.15 0 0"/>
        <geom class="collision" type="capsule" fromto="0 0 0 0.3 0 0" size="0.055" mass="0.8"/>
        <body name="hand" pos="0.3 0 0">
          <joint name="j3"/>
          <geom class="collision" name="hand" type="sphere" size="0.045" pos="0.05 0 0" mass="0.2"
                rgba="0.9 0.9 0.1 1"/>
          <site name="tool" pos="0.08 0 0" size="0.01"/>
        </body>
      </body>
    </body>
    <body name="obstacles">
      <geom name="pole" type="cylinder" size="0.04 0.3" pos="0.55 0.45 0.3" rgba="0.9 0.1 0.1 1"/>
    </body>
    <site name="goal_a" type="sphere" size="0.035" pos="0.6 0.25 0.2" rgba="0.05 0.05 0.95 1"/>
    <site name="goal_b" type="sphere" size="0.035" pos="0.1 -0.5 0.2" rgba="0.05 0.9 0.9 1"/>
  </worldbody>
  <actuator>
    <motor name="m1" joint="j1" class="arm"/>
    <motor name="m2" joint="j2" class="arm"/>
    <motor name="m3" joint="j3" class="arm" ctrlrange="-8 8"/>
  </actuator>
</mujoco>
"""

VENDOR_TOML = """[scene]
name = "vendor_style"
model = "arm.xml"

[robot]
subtree = "link1"
ee_site = "tool"
home = [0.3, -0.6, 0.0]
self_collision = false

[obstacles]
bodies = ["obstacles"]

[task]
loop = true
tolerance = 0.02
duration = 1.0

[[task.goals]]
site = "goal_a"
dwell = 0.3

[[task.goals]]
site = "goal_b"
dwell = 0.3

[barrier]
margin = 0.02
cutoff = 0.25

[gains]
task_kp = 4.0
max_ee_speed = 0.6
max_joint_speed = 2.0
tracking_kp = [400.0, 300.0, 150.0]
tracking_kd = [40.0, 30.0, 15.0]

[control]
period = 0.002
"""

PALETTE = {"visual": (0.1, 0.85, 0.1), "collision": (0.9, 0.1, 0.9), "hand": (0.9, 0.9, 0.1),
           "pole": (0.9, 0.1, 0.1), "goal_a": (0.05, 0.05, 0.95), "goal_b": (0.05, 0.9, 0.9)}
W, H = 240, 180
BANNER = max(14, H // 16)


def _vendor(tmp_path: Path) -> tuple[Path, Path]:
    xml, toml = tmp_path / "arm.xml", tmp_path / "arm.toml"
    xml.write_text(VENDOR_XML)
    toml.write_text(VENDOR_TOML)
    return xml, toml


def _render_vendor(tmp_path: Path, name: str, *extra: str) -> subprocess.CompletedProcess[str]:
    xml, toml = _vendor(tmp_path)
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    proc = subprocess.run([sys.executable, "-m", "isf_robot.cli", "render", "--model", str(xml), "--config", str(toml),
                           "--filter", "nominal", "--duration", "0.02", "-o", str(tmp_path / name), "--width", str(W),
                           "--height", str(H), *extra], capture_output=True, text=True, env=env, timeout=300)
    if proc.returncode == 2 and "offscreen rendering is not available" in proc.stderr:
        pytest.skip(f"no offscreen OpenGL here: {proc.stderr.strip()}")
    return proc


def _labels(frame: np.ndarray) -> dict[str, np.ndarray]:
    """Pixel masks of the palette's colours (chromaticity within 0.08, not dark), below the banner."""
    rgb = frame[BANNER:, :, :3].astype(float)
    total = rgb.sum(axis=2, keepdims=True)
    chroma = rgb / np.maximum(total, 1.0)
    out = {}
    for name, colour in PALETTE.items():
        c = np.asarray(colour) / sum(colour)
        out[name] = (np.linalg.norm(chroma - c, axis=2) < 0.08) & (total[..., 0] > 90)
    return out


def _picture(tmp_path: Path, name: str, *extra: str) -> np.ndarray:
    from PIL import Image

    proc = _render_vendor(tmp_path, name, *extra)
    assert proc.returncode == 0, proc.stderr
    return np.asarray(Image.open(tmp_path / name).convert("RGB"))


def test_vendor_arm_shows_its_visual_geoms_framed_under_a_sky(tmp_path: Path) -> None:
    frame = _picture(tmp_path, "default.png")
    lab = _labels(frame)
    n = {k: int(v.sum()) for k, v in lab.items()}
    # the visual boxes are drawn; the collision capsules enclosing them are not
    assert n["visual"] > 200 and n["collision"] < 10, n  # (a few: edges of red on blue)
    # a body with only collision geoms keeps them: the hand is drawn
    assert n["hand"] > 20, n
    # framing: the obstacle and both goals are in the picture, and the scene fills it
    assert n["pole"] > 50 and n["goal_a"] > 10 and n["goal_b"] > 10, n
    things = np.zeros_like(lab["pole"])
    for v in lab.values():
        things |= v
    rows, cols = np.nonzero(things)
    assert (cols.max() - cols.min()) > 0.75 * W or (rows.max() - rows.min()) > 0.75 * (H - BANNER)
    # nothing is cut by the image's edges or hidden under the banner
    assert not things[0].any() and not things[-1].any() and not things[:, 0].any() and not things[:, -1].any()
    # a sky, not black: the first rows under the banner are a light blue
    top = frame[BANNER + 1:BANNER + 4].reshape(-1, 3).astype(int)
    assert top.mean() > 120 and (top[:, 2] > top[:, 0] + 20).all()


def test_vendor_arm_show_collision_draws_the_collision_geoms(tmp_path: Path) -> None:
    lab = _labels(_picture(tmp_path, "collision.png", "--show-collision"))
    assert int(lab["collision"].sum()) > 200 and int(lab["hand"].sum()) > 20


def test_named_camera_and_unknown_camera(tmp_path: Path) -> None:
    frame = _picture(tmp_path, "top.png", "--camera", "top")
    lab = _labels(frame)
    assert lab["hand"].sum() > 20 and lab["goal_a"].sum() > 10 and lab["goal_b"].sum() > 10 and lab["pole"].sum() > 50
    top = frame[BANNER + 1:BANNER + 4].reshape(-1, 3).astype(int)  # looking down: floor under the banner, no sky
    assert np.median(np.abs(top[:, 2] - top[:, 0])) < 12


def test_bad_camera_options_are_one_line_errors_before_anything_runs(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """In this process: the checks run before the episode and before any OpenGL context (no subprocess needed)."""
    import mujoco  # noqa: F401  (imported already: the command does not choose an OpenGL backend for this process)

    from isf_robot.cli import main

    xml, toml = _vendor(tmp_path)
    base = ["render", "--model", str(xml), "--config", str(toml), "--filter", "nominal", "--duration", "0.02",
            "-o", str(tmp_path / "x.png")]
    assert main([*base, "--camera", "front"]) == 2 and not (tmp_path / "x.png").exists()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'front'" in err[0] and "valid: top, side" in err[0], err
    assert main([*base, "--camera", "top", "--azimuth", "90"]) == 2
    assert "--azimuth" in capsys.readouterr().err
    assert main([*base, "--lookat", "1,2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "X,Y,Z" in err[0], err
    assert not (tmp_path / "x.png").exists()
    for at, want in (("nan", "--at"), ("-1", "--at"), ("0.5", "past the run's end (0.02 s)")):
        assert main([*base, "--at", at]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and want in err[0], err
    gif = [*base[:-1], str(tmp_path / "x.gif"), "--at", "0.01"]  # (a video has no single frame's time)
    assert main(gif) == 2 and ".gif" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "x.gif").exists()


@pytest.mark.parametrize(("azimuth", "elevation", "aspect"), [(140.0, -22.0, 4 / 3), (90.0, -60.0, 1.0),
                                                               (0.0, -5.0, 2.0), (225.0, -89.0, 0.5)])
def test_fitted_free_camera_shows_every_corner_of_the_box(azimuth: float, elevation: float, aspect: float) -> None:
    """The fitted lookat and distance, given to MuJoCo's own camera, put every corner inside the frustum, tightly."""
    import mujoco

    from isf_robot.arm.camera import fit_camera

    m = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='0.1'/></worldbody></mujoco>")
    d = mujoco.MjData(m)
    low, high = np.array([-0.3, -0.8, 0.0]), np.array([0.9, 0.4, 0.7])
    corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    lookat, dist = fit_camera(corners, fovy=float(m.vis.global_.fovy), aspect=aspect, azimuth=azimuth,
                              elevation=elevation, margin=0.05)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:], cam.distance, cam.azimuth, cam.elevation = lookat, dist, azimuth, elevation
    scn = mujoco.MjvScene(m, maxgeom=10)
    mujoco.mjv_updateScene(m, d, mujoco.MjvOption(), None, cam, mujoco.mjtCatBit.mjCAT_ALL, scn)
    left, right_eye = scn.camera[0], scn.camera[1]  # a mono picture is seen from between the two eyes
    pos = 0.5 * (np.asarray(left.pos) + np.asarray(right_eye.pos))
    fwd, up = np.asarray(left.forward), np.asarray(left.up)
    right = np.cross(fwd, up)
    half_h = (left.frustum_top - left.frustum_bottom) / 2
    half_w = half_h * aspect
    ndc = []
    for corner in corners:
        v = corner - pos
        depth = v @ fwd
        assert depth > left.frustum_near
        ndc.append(((v @ right) * left.frustum_near / depth / half_w, (v @ up) * left.frustum_near / depth / half_h))
    ndc = np.abs(np.asarray(ndc))
    assert ndc.max() <= 0.95 + 1e-6  # inside, with the margin
    assert ndc.max() > 0.93  # and tight: no wasted frame
