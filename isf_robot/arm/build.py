"""Building a scene in Python: an ``MjModel`` (or an MJCF path) plus a config, no TOML file.

The config is either a mapping with the same tables and keys as a scene's TOML file
(``models/README.md``; the ``scene`` table is optional) or a
:class:`~isf_robot.arm.config_schema.SceneConfig`. So a MuJoCo script that already has its
model needs no file::

    import mujoco
    from isf_robot.arm import build_scene, run_episode

    model = mujoco.MjModel.from_xml_path("my_scene.xml")
    scene = build_scene(model, {
        "robot": {"subtree": "base", "home": "home", "ee_body": "wrist_3_link",
                  "ee_offset": [0, 0.1, 0]},
        "obstacles": {"bodies": ["obstacles"]},
        "task": {"goals": [{"pos": [0.3, -0.45, 0.3]}, {"pos": [-0.3, -0.45, 0.3]}]},
        "gains": {"max_joint_speed": 0.5},
    })
    result = run_episode(scene, "isf", duration=10.0)

A scene built from an ``MjModel`` has no files: its ``d_bar`` calibration is not cached, and
:func:`isf_robot.arm.compare_strategies` (which reloads scenes in worker processes by file) needs
an MJCF and TOML pair instead.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco

from isf_robot.core.exceptions import ConfigError

from .config_schema import SceneConfig
from .config_toml import parse_config
from .scene import Scene, _compile, _resolve

__all__ = ["build_scene"]


def build_scene(model: mujoco.MjModel | str | Path, config: Mapping[str, Any] | SceneConfig, *,
                name: str | None = None) -> Scene:
    """A :class:`~isf_robot.arm.scene.Scene` from a model and a config (see the module docstring).

    Args:
        model: A compiled ``MjModel`` (used as is, not copied) or the path of an MJCF file.
        config: The config as a TOML-shaped mapping, or a ``SceneConfig``.
        name: Scene name when the mapping has no ``[scene] name`` (default: the MJCF file's
            stem, else ``"scene"``).

    Raises:
        ConfigError: The config breaks the schema or does not fit the model (the message says
            which key and lists the valid names).

    """
    xml: Path | None = None
    if isinstance(model, (str, Path)):
        xml = Path(model)
        model = _compile(xml)
    elif not isinstance(model, mujoco.MjModel):
        raise ConfigError(f"model must be a mujoco.MjModel or an MJCF path, got {type(model).__name__}")
    if isinstance(config, SceneConfig):
        cfg = config
    elif isinstance(config, Mapping):
        data = dict(config)
        tab = data.get("scene", {})
        if isinstance(tab, Mapping):  # else parse_config says it must be a table
            data["scene"] = {"name": name or (xml.stem if xml is not None else "scene"), **tab}
        cfg = parse_config(data, origin="<config dict>")
    else:
        raise ConfigError(f"config must be a mapping (TOML-shaped) or a SceneConfig, got {type(config).__name__}")
    return _resolve(model, cfg, xml)
