"""What a picture draws: a copy of the run's model for drawing only (the simulated model is never changed).

* visual geoms (``contype = conaffinity = 0``) as the model draws them; a collision geom is
  hidden (alpha 0, no material) when its body (not the world) has visual geoms, so a vendor's
  collision meshes or primitives (Menagerie: group 3, or group 0) do not speckle the visual
  meshes; a body with only collision geoms keeps them. ``show_collision`` draws them all;
* MuJoCo's default geom groups (0, 1, 2) and every group of the robot's and obstacles' drawn geoms;
* a sky: a gradient skybox texture is added (through :class:`mujoco.MjSpec`, from the model's
  file) when the model has none.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np

# mujoco is imported inside the functions: `isf-robot render` loads this module before render.select_gl sets
# MUJOCO_GL, which MuJoCo reads once, at its first import

__all__ = ["drawing_model", "hidden_collision_geoms", "drawn", "robot_drawn_geoms", "SKY_TOP", "SKY_BOTTOM"]

SKY_TOP = (0.42, 0.62, 0.85)
"""Colour of the added sky at the zenith (a gradient to :data:`SKY_BOTTOM` at the horizon and below)."""
SKY_BOTTOM = (0.93, 0.95, 0.98)


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
    """A copy of ``model`` with a gradient skybox, compiled again from its file.

    ``None`` when the file does not compile to the same model (same sizes, geom sizes and body
    positions); the run's colours, groups and materials are copied over.
    """
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
