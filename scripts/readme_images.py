"""Make the README's pictures (docs/images/*.png) with the project's own commands.

Usage::

    python scripts/readme_images.py            # regenerate docs/images/
    python scripts/readme_images.py --check    # regenerate into a temporary folder and compare

Every picture comes from a command a user can type (printed as it runs):

* ``arm.png``: ``isf-robot render`` of ``panda_pole`` with the intermittent filter, the frame at
  3.0 s (the filter is on: the robot is orange), rendered offscreen with MuJoCo (EGL/OSMesa);
* ``compare.png``: ``isf-robot compare --rrd`` of nominal, cbf and isf on ``panda_pole`` (seed 0),
  drawn by ``isf-robot plot``;
* ``satellite.png``: ``isf-satellite run --rrd`` (greedy trigger, the paper's degree-8 gravity
  from ``satellite/data/itokawa_degree8.json``, 150 h), drawn by ``isf-robot plot`` as the paper's figure.

Needs the ``plots`` extra (matplotlib) and an offscreen OpenGL backend. The simulations are
deterministic, so the same versions of MuJoCo, matplotlib and the renderer give the same bytes;
``--check`` says which files differ (another MuJoCo or Mesa version may move a few pixels).
About a minute on two cores.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IMAGES = ROOT / "docs" / "images"
ROBOT = [sys.executable, "-m", "isf_robot.cli"]
SATELLITE = [sys.executable, "-m", "satellite.cli"]
DEGREE8 = Path("satellite") / "data" / "itokawa_degree8.json"
"""The paper's gravity: the committed degree-8 spherical-harmonic table (relative to the checkout)."""


def _run(cmd: list[str]) -> None:
    shown = shlex.join(["isf-robot" if cmd[:3] == ROBOT else "isf-satellite", *cmd[3:]])
    print(f"$ {shown}", flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)


def make(out: Path, work: Path) -> list[Path]:
    """Write the pictures into ``out`` (scratch recordings in ``work``); return their paths."""
    out.mkdir(parents=True, exist_ok=True)
    arm, compare, sat = out / "arm.png", out / "compare.png", out / "satellite.png"
    _run([*ROBOT, "render", "--scene", "panda_pole", "--filter", "isf", "--seed", "0", "--duration", "3.1",
          "--at", "3.0", "--width", "640", "--height", "400", "-o", str(arm)])
    runs = work / "compare"
    _run([*ROBOT, "compare", "--scene", "panda_pole", "--filters", "nominal", "cbf", "isf", "--episodes", "1",
          "--seed", "0", "--quiet", "--rrd", str(runs)])
    _run([*ROBOT, "plot", str(runs), "-o", str(compare), "--title", "panda_pole, seed 0"])
    orbit = work / "satellite.rrd"
    _run([*SATELLITE, "run", "--trigger", "greedy", "--hours", "150", "--gravity", str(DEGREE8), "--seed", "0",
          "--quiet", "--rrd", str(orbit)])
    _run([*ROBOT, "plot", str(orbit), "-o", str(sat), "--hours", "150"])
    return [arm, compare, sat]


def main() -> int:
    """Regenerate the pictures, or with --check compare fresh ones with the committed ones."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true",
                    help="regenerate into a temporary folder and report which committed pictures differ")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        if not args.check:
            for p in make(IMAGES, work):
                print(f"wrote {p.relative_to(ROOT)} ({p.stat().st_size // 1024} KiB)")
            return 0
        fresh = make(work / "images", work)
        differ = [p.name for p in fresh if not (IMAGES / p.name).is_file()
                  or (IMAGES / p.name).read_bytes() != p.read_bytes()]
        print("all pictures reproduced byte for byte" if not differ else f"differ: {', '.join(differ)}")
        return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
