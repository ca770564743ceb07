"""Reading a scene's TOML file into a :class:`~isf_robot.arm.config_schema.SceneConfig`.

Parsing checks types, shapes and signs and rejects unknown keys (the message lists the valid
ones and names the file and the table); the schema is documented in ``models/README.md``.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from isf_robot.core.exceptions import ConfigError

from .config_schema import (
    BarrierConfig,
    ControlConfig,
    FilterConfig,
    GainsConfig,
    Goal,
    ObstacleConfig,
    RobotConfig,
    SceneConfig,
    TaskConfig,
)
from .paths import CirclePath, LinearBouncePath, MovingObstacle, ObstaclePath

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["parse_config", "load_config"]


class _Reader:
    """Typed access to one TOML table, with errors naming the file and the key."""

    def __init__(self, table: Mapping[str, Any], where: str, origin: str) -> None:
        self.table = table
        self.where = where
        self.origin = origin
        self.used: set[str] = set()

    def _err(self, key: str, msg: str) -> ConfigError:
        return ConfigError(f"{self.origin}: [{self.where}] {key}: {msg}")

    def has(self, key: str) -> bool:
        return key in self.table

    def raw(self, key: str, default: Any = ...) -> Any:
        self.used.add(key)
        if key not in self.table:
            if default is ...:
                raise self._err(key, "missing (required)")
            return default
        return self.table[key]

    def string(self, key: str, default: Any = ...) -> Any:
        v = self.raw(key, default)
        if v is not default and not isinstance(v, str):
            raise self._err(key, f"expected a string, got {v!r}")
        return v

    def boolean(self, key: str, default: bool) -> bool:
        v = self.raw(key, default)
        if not isinstance(v, bool):
            raise self._err(key, f"expected true or false, got {v!r}")
        return v

    def number(self, key: str, default: Any = ..., *, positive: bool = False,
               nonneg: bool = False) -> float:
        v = self.raw(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise self._err(key, f"expected a finite number, got {v!r}")
        if positive and v <= 0:
            raise self._err(key, f"must be > 0, got {v}")
        if nonneg and v < 0:
            raise self._err(key, f"must be >= 0, got {v}")
        return float(v)

    def numbers(self, key: str, default: Any = ..., *, length: int | None = None) -> Any:
        v = self.raw(key, default)
        if v is default:
            return v
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            v = [v]
        if not isinstance(v, list) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v
        ):
            raise self._err(key, f"expected a list of finite numbers, got {v!r}")
        if length is not None and len(v) != length:
            raise self._err(key, f"expected {length} numbers, got {len(v)}")
        return tuple(float(x) for x in v)

    def strings(self, key: str, default: Any = ...) -> Any:
        v = self.raw(key, default)
        if v is default:
            return v
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v) or not v:
            raise self._err(key, f"expected a non-empty list of strings, got {v!r}")
        if len(set(v)) != len(v):
            raise self._err(key, f"names repeat: {v!r}")
        return tuple(v)

    def sub(self, key: str, required: bool = False) -> _Reader:
        v = self.raw(key, ... if required else {})
        if not isinstance(v, Mapping):
            raise self._err(key, "expected a table")
        return _Reader(v, f"{self.where}.{key}" if self.where else key, self.origin)

    def finish(self) -> None:
        unknown = sorted(set(self.table) - self.used)
        if unknown:
            raise ConfigError(
                f"{self.origin}: unknown key(s) {unknown} in [{self.where or 'top level'}]; "
                f"valid keys: {sorted(self.used)}"
            )


def _goal(tab: Any, origin: str, i: int) -> Goal:
    if not isinstance(tab, Mapping):
        raise ConfigError(f"{origin}: [[task.goals]] entry {i} must be a table")
    r = _Reader(tab, f"task.goals[{i}]", origin)
    site = r.string("site", None)
    pos = r.numbers("pos", None, length=3)
    dwell = r.number("dwell", 0.0, nonneg=True)
    r.finish()
    if (site is None) == (pos is None):
        raise ConfigError(f"{origin}: [task.goals[{i}]] give exactly one of 'pos' or 'site'")
    return Goal(position=pos if pos is not None else (math.nan,) * 3, dwell=dwell, site=site)


def _path(r: _Reader) -> ObstaclePath:
    kind = r.string("type")
    if kind == "circle":
        normal = np.asarray(r.numbers("normal", (0.0, 0.0, 1.0), length=3))
        if np.linalg.norm(normal) < 1e-9:
            raise r._err("normal", "must be non-zero")
        period = r.number("period")
        if period == 0.0:
            raise r._err("period", "must be non-zero")
        return CirclePath(
            center=r.numbers("center", length=3),
            radius=r.number("radius", positive=True),
            period=period,
            normal=tuple(float(x) for x in normal / np.linalg.norm(normal)),  # type: ignore[arg-type]
            phase=r.number("phase", 0.0),
        )
    if kind == "linear_bounce":
        start = r.numbers("start", length=3)
        end = r.numbers("end", length=3)
        if np.linalg.norm(np.subtract(end, start)) < 1e-9:
            raise r._err("end", "must differ from 'start'")
        return LinearBouncePath(start=start, end=end, speed=r.number("speed", positive=True),
                                phase=r.number("phase", 0.0))
    raise r._err("type", f"unknown path type {kind!r}; valid types: 'circle', 'linear_bounce'")


def _group(r: _Reader) -> int | None:
    v = r.raw("geom_group", None)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 5:
        raise r._err("geom_group", f"expected an integer 0..5 (MuJoCo geom group), got {v!r}")
    return int(v)


def _home(r: _Reader, n: int | None) -> tuple[float, ...] | str | None:
    v = r.raw("home", None)
    if isinstance(v, str):
        if not v:
            raise r._err("home", "expected a keyframe name or a list of numbers, got ''")
        return v
    return r.numbers("home", None, length=n)  # type: ignore[no-any-return]


def parse_config(data: Mapping[str, Any], origin: str = "<config>",
                 source: Path | None = None, default_name: str | None = None) -> SceneConfig:
    """Build a :class:`SceneConfig` from a parsed TOML mapping.

    Args:
        data: The TOML document as a mapping.
        origin: Label for error messages (usually the file path).
        source: The file it came from, stored in the result.
        default_name: Scene name used when ``[scene] name`` is absent (the file stem).

    Returns:
        The configuration.

    Raises:
        ConfigError: A key is missing, unknown or has the wrong type or value.

    """
    top = _Reader(data, "", origin)

    s = top.sub("scene", required=True)
    name = s.string("name", default_name if default_name is not None else ...)
    description = s.string("description", "")
    model = s.string("model", f"{name}.xml")
    s.finish()

    r = top.sub("robot", required=True)
    joints = r.strings("joints", ())
    robot = RobotConfig(
        joints=joints,
        ee_site=r.string("ee_site", None),
        ee_body=r.string("ee_body", None),
        ee_offset=r.numbers("ee_offset", (0.0, 0.0, 0.0), length=3),
        geoms=r.strings("geoms", ()),
        bodies=r.strings("bodies", ()),
        subtree=r.string("subtree", None),
        geom_group=_group(r),
        home=_home(r, len(joints) or None),
        self_collision=r.boolean("self_collision", False),
    )
    if (robot.ee_site is None) == (robot.ee_body is None):
        raise ConfigError(f"{origin}: [robot] give exactly one of 'ee_site' or 'ee_body'")
    if r.has("ee_offset") and robot.ee_body is None:
        raise ConfigError(f"{origin}: [robot] ee_offset needs ee_body (a site has its own position)")
    if not (robot.geoms or robot.bodies or robot.subtree):
        raise ConfigError(f"{origin}: [robot] give the robot's geoms: 'geoms', 'bodies' and/or 'subtree'")
    r.finish()

    o = top.sub("obstacles", required=True)
    obstacles = ObstacleConfig(geoms=o.strings("geoms", ()), bodies=o.strings("bodies", ()),
                               subtree=o.string("subtree", None), geom_group=_group(o))
    if not (obstacles.geoms or obstacles.bodies or obstacles.subtree or obstacles.geom_group is not None):
        raise ConfigError(f"{origin}: [obstacles] give 'geoms', 'bodies', 'subtree' and/or 'geom_group'")
    o.finish()

    t = top.sub("task", required=True)
    goals_raw = t.raw("goals")
    if not isinstance(goals_raw, list) or not goals_raw:
        raise ConfigError(f"{origin}: [task] goals: expected a non-empty array of tables")
    task = TaskConfig(
        goals=tuple(_goal(g, origin, i) for i, g in enumerate(goals_raw)),
        loop=t.boolean("loop", True),
        tolerance=t.number("tolerance", 0.02, positive=True),
        duration=t.number("duration", 10.0, positive=True),
    )
    t.finish()

    b = top.sub("barrier")
    d = BarrierConfig()
    barrier = BarrierConfig(
        margin=b.number("margin", d.margin, nonneg=True),
        self_margin=b.number("self_margin", d.self_margin, nonneg=True),
        joint_margin=b.number("joint_margin", d.joint_margin, nonneg=True),
        cutoff=b.number("cutoff", d.cutoff, positive=True),
    )
    b.finish()

    g = top.sub("gains")
    dg = GainsConfig()
    known = {"task_kp", "dls_damping", "max_ee_speed", "max_joint_speed", "joint_kp",
             "tracking_kp", "tracking_kd"}
    extra = {k: g.numbers(k) if isinstance(v, list) else g.number(k)
             for k, v in g.table.items() if k not in known}
    gains = GainsConfig(
        task_kp=g.number("task_kp", dg.task_kp, positive=True),
        dls_damping=g.number("dls_damping", dg.dls_damping, nonneg=True),
        max_ee_speed=g.number("max_ee_speed", dg.max_ee_speed, positive=True),
        max_joint_speed=g.number("max_joint_speed", dg.max_joint_speed, positive=True),
        joint_kp=g.number("joint_kp", dg.joint_kp, positive=True),
        tracking_kp=g.numbers("tracking_kp", dg.tracking_kp),
        tracking_kd=g.numbers("tracking_kd", dg.tracking_kd),
        extra=MappingProxyType(extra),
    )
    for key in ("tracking_kp", "tracking_kd"):
        n = len(getattr(gains, key))
        if joints and n not in (1, len(joints)):
            raise ConfigError(f"{origin}: [gains] {key}: expected 1 or {len(joints)} numbers, got {n}")
    g.finish()

    f = top.sub("filter")
    df = FilterConfig()
    filt = FilterConfig(
        alpha=f.number("alpha", df.alpha, positive=True),
        c=f.number("c", df.c, positive=True),
        b=f.number("b", df.b, positive=True),
        d_bar=f.number("d_bar", df.d_bar, nonneg=True),
        min_off=f.number("min_off", df.min_off, nonneg=True),
        blend=f.number("blend", df.blend, nonneg=True),
        horizon=f.number("horizon", df.horizon, nonneg=True),
        c_pred=f.number("c_pred", df.c_pred, nonneg=True),
    )
    f.finish()

    c = top.sub("control")
    control = ControlConfig(period=c.number("period", ControlConfig().period, positive=True))
    c.finish()

    moving_raw = top.raw("moving", [])
    if not isinstance(moving_raw, list):
        raise ConfigError(f"{origin}: 'moving' must be an array of tables ([[moving]])")
    moving = []
    for i, m in enumerate(moving_raw):
        if not isinstance(m, Mapping):
            raise ConfigError(f"{origin}: [[moving]] entry {i} must be a table")
        mr = _Reader(m, f"moving[{i}]", origin)
        moving.append(MovingObstacle(body=mr.string("body"), path=_path(mr)))
        mr.finish()
    top.finish()

    return SceneConfig(name=name, description=description, model=model, robot=robot,
                       obstacles=obstacles, task=task, barrier=barrier, gains=gains,
                       filter=filt, control=control, moving=tuple(moving), source=source)


def load_config(path: str | Path) -> SceneConfig:
    """Read and parse a scene's TOML file.

    Args:
        path: The TOML file.

    Returns:
        The configuration.

    Raises:
        ConfigError: The file is missing, is not valid TOML, or breaks the schema; the
            message names the file.

    """
    path = Path(path)
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError as exc:
        raise ConfigError(f"scene config file not found: {path}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: malformed TOML: {exc}") from exc
    return parse_config(data, origin=str(path), source=path, default_name=path.stem)
