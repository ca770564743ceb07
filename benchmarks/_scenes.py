"""Scenes built for the benchmarks (import from a script in ``benchmarks/``, or put it on the path).

:func:`far_spheres_scene` is panda_pole with extra static spheres far from the arm: their geom
pairs with the arm are real collision barriers, yet no sphere ever comes within the broad
phase's cut-off, so a broad phase that costs next to nothing for far obstacles leaves the
control step's cost where it is on panda_pole.
"""

from __future__ import annotations

import atexit
import math
import re
import shutil
import tempfile
from pathlib import Path

from isf_robot.arm import Scene, load_scene_from_files
from isf_robot.paths import models_dir

__all__ = ["far_spheres_scene", "FAR_RADIUS"]

FAR_RADIUS = 3.0  # [m] distance of the spheres' ring from the arm's base (the arm reaches < 1.2 m)


def _sphere_lines(n: int) -> list[str]:
    """``n`` spheres (radius 5 cm) on a ring of radius ``FAR_RADIUS`` at heights 0.2-1.4 m."""
    out = []
    for i in range(n):
        a = 2.0 * math.pi * i / max(n, 1)
        x, y, z = FAR_RADIUS * math.cos(a), FAR_RADIUS * math.sin(a), 0.2 + 1.2 * (i % 7) / 6
        out.append(f'    <geom name="far{i}" type="sphere" size="0.05" pos="{x:.6f} {y:.6f} {z:.6f}" '
                   'rgba="0.3 0.3 0.3 1"/>')
    return out


def far_spheres_scene(n: int = 64) -> Scene:
    """panda_pole with ``n`` extra static spheres ``FAR_RADIUS`` [m] from the arm, all obstacles.

    The MJCF is written to a temporary folder (removed at exit) that links the shipped
    ``panda_pole.xml`` and ``panda_arm.xml`` and includes the former; the config is
    panda_pole's with the spheres added to ``[obstacles] geoms``. So the scene has
    ``14 * (2 + n)`` robot-obstacle pairs, of which the ``14 * n`` new ones are never active.

    Args:
        n: Number of extra spheres, >= 0.

    Returns:
        The scene (name ``"panda_pole_far<n>"``).

    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    src = models_dir()
    tmp = Path(tempfile.mkdtemp(prefix="isf_far_spheres_"))
    atexit.register(shutil.rmtree, tmp, True)
    for name in ("panda_pole.xml", "panda_arm.xml"):
        (tmp / name).symlink_to(src / name)
    name = f"panda_pole_far{n}"
    xml = tmp / f"{name}.xml"
    xml.write_text("\n".join([f'<mujoco model="{name}">', '  <include file="panda_pole.xml"/>',
                              "  <worldbody>", *_sphere_lines(n), "  </worldbody>", "</mujoco>", ""]))
    toml = (src / "panda_pole.toml").read_text()
    toml = toml.replace('name = "panda_pole"', f'name = "{name}"', 1)
    toml = toml.replace('model = "panda_pole.xml"', f'model = "{xml.name}"', 1)
    far = ", ".join(f'"far{i}"' for i in range(n))
    toml, count = re.subn(r'(\[obstacles\]\s*geoms = \["pole", "ball")\]', rf"\1{', ' + far if n else ''}]",
                          toml, count=1)
    if count != 1:
        raise RuntimeError("panda_pole.toml has changed: its [obstacles] geoms line was not found")
    cfg = tmp / f"{name}.toml"
    cfg.write_text(toml)
    return load_scene_from_files(xml, cfg)
