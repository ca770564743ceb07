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
