"""Offscreen rendering speed of ``isf-robot render`` (MuJoCo's Renderer, EGL or OSMesa).

Usage: ``python benchmarks/render_bench.py [--repeats 3] [--frames 40] [--out BENCHMARKS.md]``.

For each frame size, the ``panda_pole`` episode (intermittent filter, seed 0) runs with a
:class:`~isf_robot.arm.render.VideoRecorder` writing a GIF at 10 frames per simulated second
until ``--frames`` frames are rendered, and once without it. Reported per size (medians over
the repeats): the rendering rate (frames / time spent in ``VideoRecorder.render``: posing,
drawing, reading pixels, the banner), the run's wall time with and without the video and their
ratio (GIF encoding at the end included). Only the section between
``<!-- render-bench:start -->`` and ``<!-- render-bench:end -->`` of the output file is rewritten.
"""

from __future__ import annotations

import argparse
import datetime
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from _common import cpu_model, write_section  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

START = "<!-- render-bench:start -->"
END = "<!-- render-bench:end -->"
SIZES = ((320, 240), (480, 360), (640, 480))


def main() -> int:
    """Measure and write the section."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--frames", type=int, default=40, help="frames per measurement (10 per simulated second)")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "BENCHMARKS.md")
    args = ap.parse_args()

    from isf_robot.arm.render import select_gl

    backend = select_gl()  # before MuJoCo is imported
    import mujoco

    from isf_robot.arm import load_scene, resolve_params
    from isf_robot.arm.render import VideoRecorder
    from isf_robot.arm.sim import ArmSimulation

    scene = load_scene("panda_pole")
    params = resolve_params(scene)
    duration = args.frames / 10.0 - 0.05
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for w, h in SIZES:
            rates, with_video, without = [], [], []
            for i in range(args.repeats):
                t0 = time.perf_counter()
                ArmSimulation(scene, "isf", seed=0, params=params).run(duration)
                without.append(time.perf_counter() - t0)
                video = VideoRecorder(Path(tmp) / f"b{w}-{i}.gif", fps=10.0, width=w, height=h)
                t0 = time.perf_counter()
                ArmSimulation(scene, "isf", seed=0, params=params, observers=[video]).run(duration)
                with_video.append(time.perf_counter() - t0)
                rates.append(len(video.frame_times) / video.render_s)
            a, b = statistics.median(without), statistics.median(with_video)
            rows.append(f"| {w} x {h} | {statistics.median(rates):.1f} | {a:.2f} | {b:.2f} | {b / a:.1f} |")
            print(rows[-1], file=sys.stderr, flush=True)
    body = "\n".join([
        "## Offscreen rendering (`benchmarks/render_bench.py`)",
        "",
        f"{datetime.date.today().isoformat()}, {cpu_model()}, MUJOCO_GL={backend}, MuJoCo {mujoco.__version__}; "
        f"panda_pole, isf, seed 0, {args.frames} frames (GIF, 10 frames per simulated second), "
        f"medians of {args.repeats}.",
        "",
        "| frame | frames/s rendered | run without video [s] | run with video [s] | ratio |",
        "|---|---|---|---|---|",
        *rows,
        "",
        "Rendering runs on the CPU here (Mesa's llvmpipe, software OpenGL, behind EGL; no GPU). "
        "The machine is shared: "
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the end of the measurement.",
    ])
    write_section(args.out, START, END, body)
    print(f"wrote the render section of {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
