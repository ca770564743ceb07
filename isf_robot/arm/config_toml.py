"""Reading a scene's TOML file into a :class:`~isf_robot.arm.config_schema.SceneConfig`.

Parsing checks types, shapes and signs and rejects unknown keys (the message lists the valid
ones and names the file and the table); the schema is documented in ``models/README.md``.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from isf_robot.core.exceptions import ConfigError
from isf_robot.core.spec import NAMES as SPEC_NAMES
from isf_robot.core.spec import FilterSpec

from .config_schema import (
    LEVELS,
    ArmConfig,
    BarrierConfig,
    ControlConfig,
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

__all__ = ["parse_config", "load_config", "unknown_message", "TABLES", "SECTION_KEYS"]

SECTION_KEYS: dict[str, tuple[str, ...]] = {
    "scene": ("name", "description", "model"),
    "robot": ("joints", "ee_site", "ee_body", "ee_offset", "geoms", "bodies", "subtree", "geom_group", "home",
              "self_collision"),
    "obstacles": ("geoms", "bodies", "subtree", "geom_group"),
    "task": ("goals", "loop", "tolerance", "duration"),
    "task.goals": ("site", "pos", "dwell"),
    "barrier": ("margin", "self_margin", "joint_margin", "cutoff"),
    "gains": ("task_kp", "dls_damping", "max_ee_speed", "max_joint_speed", "max_joint_acc", "joint_kp",
              "tracking_kp", "tracking_kd", "goal_timeout", "extra"),
    "filter": (*SPEC_NAMES, "level"),
    "control": ("period",),
    "moving.circle": ("body", "type", "center", "radius", "period", "normal", "phase"),
    "moving.linear_bounce": ("body", "type", "start", "end", "speed", "phase"),
    "arm": ("name", "prefix", "like", "joints", "geoms", "ee_site", "home", "goals", "self_collision"),
}
"""The keys each table of a scene's TOML file may have (``models/README.md`` documents them)."""
TABLES = ("scene", "robot", "obstacles", "task", "barrier", "gains", "filter", "control", "moving", "arm")
"""The top-level tables, in the order the schema lists them (``moving`` and ``arm`` are arrays of tables)."""
_ARRAY_TABLES = ("moving", "arm")


class _Reader:
    """Typed access to one TOML table, with errors naming the file and the key."""

    def __init__(self, table: Mapping[str, Any], where: str, origin: str,
                 keys: Sequence[str] | None = None, label: str | None = None) -> None:
        self.table = table
        self.where = where
        self.origin = origin
        self.label = label if label is not None else f"[{where}]"
        self.used: set[str] = set()
        if keys is not None:
            self.only(keys)

    def only(self, keys: Sequence[str]) -> None:
        """Raise on the first key of the table that is not in ``keys`` (before any value is read)."""
        for key, value in self.table.items():
            if key not in keys:
                if not self.where and not isinstance(value, (Mapping, list)):
                    raise ConfigError(f"{self.origin}: {key!r} = {value!r} outside any table; a scene file's "
                                      f"top level holds only the tables {', '.join(map(_table_name, keys))}")
                raise ConfigError(f"{self.origin}: {unknown_message(key, keys, self.label if self.where else '')}")

    def _err(self, key: str, msg: str) -> ConfigError:
        if not self.where:
            return ConfigError(f"{self.origin}: table [{key}]: {msg}")
        return ConfigError(f"{self.origin}: {self.label} {key}: {msg}")

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

    def sub(self, key: str, keys: Sequence[str] | None, required: bool = False) -> _Reader:
        v = self.raw(key, ... if required else {})
        if not isinstance(v, Mapping):
            raise self._err(key, "expected a table")
        return _Reader(v, f"{self.where}.{key}" if self.where else key, self.origin, keys)

    def finish(self) -> None:
        """Raise on a key of the table that no reader asked for (every section also checks on entry)."""
        self.only(sorted(self.used))


def unknown_message(key: str, valid: Sequence[str], where: str = "") -> str:
    """``unknown key 'k' in [where]; valid keys: ...; did you mean 'x'?`` (tables at the top level).

    Args:
        key: The unknown key.
        valid: The keys (at the top level: the tables) allowed there.
        where: The table as the file writes it (``"[gains]"``); ``""`` for the top level, whose
            keys are tables.

    """
    close = difflib.get_close_matches(key, list(valid), n=1, cutoff=0.6)
    if not where:
        tables = ", ".join(_table_name(k) for k in valid)
        hint = f"; did you mean {_table_name(close[0])}?" if close else ""
        return f"unknown table [{key}]; valid: {tables}{hint}"
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return f"unknown key {key!r} in {where}; valid keys: {', '.join(valid)}{hint}"


def _table_name(key: str) -> str:
    return f"[[{key}]]" if key in _ARRAY_TABLES else f"[{key}]"


def _goal(tab: Any, origin: str, i: int, where: str = "[[task.goals]]") -> Goal:
    label = f"{where} goal {i + 1}"
    if not isinstance(tab, Mapping):
        raise ConfigError(f"{origin}: {label} must be a table")
    r = _Reader(tab, "task.goals", origin, SECTION_KEYS["task.goals"], label=label)
    site = r.string("site", None)
    pos = r.numbers("pos", None, length=3)
    dwell = r.number("dwell", 0.0, nonneg=True)
    r.finish()
    if (site is None) == (pos is None):
        raise ConfigError(f"{origin}: {label}: give exactly one of 'pos' or 'site'")
    return Goal(position=pos if pos is not None else (math.nan,) * 3, dwell=dwell, site=site)


def _arms(raw: Any, origin: str) -> tuple[ArmConfig, ...]:
    """The ``[[arm]]`` tables: names given without the arm's ``prefix`` get it.

    ``like = "<arm>"`` takes that arm's joints, geoms, end-effector site, home and goals (as the file
    writes them, before prefixing) for every key the table leaves out.
    """
    if not isinstance(raw, list) or not raw:
        raise ConfigError(f"{origin}: 'arm' must be a non-empty array of tables ([[arm]])")
    written: dict[str, dict[str, Any]] = {}
    arms = []
    for i, tab in enumerate(raw):
        if not isinstance(tab, Mapping):
            raise ConfigError(f"{origin}: [[arm]] entry {i + 1} must be a table")
        r = _Reader(tab, "arm", origin, SECTION_KEYS["arm"], label=f"[[arm]] entry {i + 1}")
        name = r.string("name")
        if not name or name in written:
            raise r._err("name", f"must be a non-empty name no other arm has, got {name!r}")
        r.label = f"[[arm]] {name!r}"
        like = r.string("like", None)
        if like is not None and like not in written:
            raise r._err("like", f"names no arm before this one; valid: {sorted(written)}")
        base = written.get(like, {}) if like is not None else {}
        prefix = r.string("prefix", "")
        own = {"joints": r.strings("joints", None), "geoms": r.strings("geoms", None),
               "ee_site": r.string("ee_site", None), "home": r.numbers("home", None),
               "goals": r.raw("goals", None), "self_collision": r.boolean("self_collision", False)
               if r.has("self_collision") else None}
        vals: dict[str, Any] = {k: v if v is not None else base.get(k) for k, v in own.items()}
        for key in ("joints", "geoms", "ee_site", "goals"):
            if vals[key] is None:
                raise r._err(key, "missing (required, or take it from another arm with 'like')")
        if vals["home"] is not None and len(vals["home"]) != len(vals["joints"]):
            raise r._err("home", f"expected {len(vals['joints'])} numbers (one per joint), got {len(vals['home'])}")
        goals_raw = vals["goals"]
        if not isinstance(goals_raw, list) or not goals_raw:
            raise r._err("goals", "expected a non-empty array of tables ([[arm.goals]])")
        r.finish()
        written[name] = vals

        def pre(n: str, prefix: str = prefix) -> str:
            return n if n.startswith(prefix) else prefix + n

        goals = []
        for j, g in enumerate(goals_raw):
            goal = _goal(g, origin, j, where=f"[[arm]] {name!r}")
            goals.append(Goal(goal.position, goal.dwell, None if goal.site is None else pre(goal.site)))
        arms.append(ArmConfig(name=name, prefix=prefix, joints=tuple(map(pre, vals["joints"])),
                              geoms=tuple(map(pre, vals["geoms"])), ee_site=pre(vals["ee_site"]),
                              home=vals["home"], goals=tuple(goals),
                              self_collision=bool(vals["self_collision"])))
    if len({a.self_collision for a in arms}) > 1:
        raise ConfigError(f"{origin}: [[arm]] self_collision: give every arm the same value (per arm: "
                          f"{ {a.name: a.self_collision for a in arms} })")
    homes = [a.home is None for a in arms]
    if any(homes) and not all(homes):
        raise ConfigError(f"{origin}: [[arm]] give 'home' for every arm or for none "
                          f"(missing: {[a.name for a in arms if a.home is None]})")
    return tuple(arms)


def _arms_robot(arms: tuple[ArmConfig, ...]) -> RobotConfig:
    """The robot of a scene with several arms: every arm's joints and geoms, in ``[[arm]]`` order."""
    home = None if arms[0].home is None else tuple(x for a in arms for x in a.home)  # type: ignore[union-attr]
    return RobotConfig(joints=tuple(j for a in arms for j in a.joints), ee_site=arms[0].ee_site,
                       geoms=tuple(g for a in arms for g in a.geoms), home=home,
                       self_collision=arms[0].self_collision)


def _path(r: _Reader) -> ObstaclePath:
    kind = r.string("type")
    if kind in ("circle", "linear_bounce"):
        r.only(SECTION_KEYS[f"moving.{kind}"])
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
    top = _Reader(data, "", origin, TABLES)

    s = top.sub("scene", SECTION_KEYS["scene"], required=True)
    name = s.string("name", default_name if default_name is not None else ...)
    description = s.string("description", "")
    model = s.string("model", f"{name}.xml")
    s.finish()

    arms = _arms(top.raw("arm"), origin) if top.has("arm") else ()
    if arms and top.has("robot"):
        raise ConfigError(f"{origin}: give the arms either in [[arm]] tables or as one [robot], not both")
    r = top.sub("robot", SECTION_KEYS["robot"], required=not arms)
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
    if arms:
        robot, joints = _arms_robot(arms), _arms_robot(arms).joints
    if (robot.ee_site is None) == (robot.ee_body is None):
        raise ConfigError(f"{origin}: [robot] give exactly one of 'ee_site' or 'ee_body'")
    if r.has("ee_offset") and robot.ee_body is None:
        raise ConfigError(f"{origin}: [robot] ee_offset needs ee_body (a site has its own position)")
    if not (robot.geoms or robot.bodies or robot.subtree):
        raise ConfigError(f"{origin}: [robot] give the robot's geoms: 'geoms', 'bodies' and/or 'subtree'")
    r.finish()

    o = top.sub("obstacles", SECTION_KEYS["obstacles"], required=True)
    obstacles = ObstacleConfig(geoms=o.strings("geoms", ()), bodies=o.strings("bodies", ()),
                               subtree=o.string("subtree", None), geom_group=_group(o))
    if not (obstacles.geoms or obstacles.bodies or obstacles.subtree or obstacles.geom_group is not None):
        raise ConfigError(f"{origin}: [obstacles] give 'geoms', 'bodies', 'subtree' and/or 'geom_group'")
    o.finish()

    t = top.sub("task", SECTION_KEYS["task"], required=True)
    if arms and t.has("goals"):
        raise ConfigError(f"{origin}: [task] goals: a scene with [[arm]] tables gives each arm's goals in its table")
    goals_raw = t.raw("goals") if not arms else [None]
    if not isinstance(goals_raw, list) or not goals_raw:
        raise ConfigError(f"{origin}: [task] goals: expected a non-empty array of tables")
    task = TaskConfig(
        goals=tuple(g for a in arms for g in a.goals) if arms else tuple(
            _goal(g, origin, i) for i, g in enumerate(goals_raw)),
        loop=t.boolean("loop", True),
        tolerance=t.number("tolerance", 0.02, positive=True),
        duration=t.number("duration", 10.0, positive=True),
    )
    t.finish()

    b = top.sub("barrier", SECTION_KEYS["barrier"])
    d = BarrierConfig()
    barrier = BarrierConfig(
        margin=b.number("margin", d.margin, nonneg=True),
        self_margin=b.number("self_margin", d.self_margin, nonneg=True),
        joint_margin=b.number("joint_margin", d.joint_margin, nonneg=True),
        cutoff=b.number("cutoff", d.cutoff, positive=True),
    )
    b.finish()

    g = top.sub("gains", SECTION_KEYS["gains"])
    dg = GainsConfig()
    x = g.sub("extra", None)  # the user's own entries: any key, numbers only
    extra = {k: x.numbers(k) if isinstance(v, list) else x.number(k) for k, v in x.table.items()}
    gains = GainsConfig(
        task_kp=g.number("task_kp", dg.task_kp, positive=True),
        dls_damping=g.number("dls_damping", dg.dls_damping, nonneg=True),
        max_ee_speed=g.number("max_ee_speed", dg.max_ee_speed, positive=True),
        max_joint_speed=g.number("max_joint_speed", dg.max_joint_speed, positive=True),
        max_joint_acc=g.number("max_joint_acc", dg.max_joint_acc, positive=True),
        joint_kp=g.number("joint_kp", dg.joint_kp, positive=True),
        tracking_kp=g.numbers("tracking_kp", dg.tracking_kp),
        tracking_kd=g.numbers("tracking_kd", dg.tracking_kd),
        goal_timeout=g.number("goal_timeout", dg.goal_timeout, positive=True),
        extra=MappingProxyType(extra),
    )
    if arms and len({len(a.joints) for a in arms}) == 1:  # one arm's gains stand for every arm's
        per_arm = len(arms[0].joints)
        gains = dataclasses.replace(gains, **{key: getattr(gains, key) * len(arms)
                                              for key in ("tracking_kp", "tracking_kd")
                                              if len(getattr(gains, key)) == per_arm > 1})
    for key in ("tracking_kp", "tracking_kd"):
        n = len(getattr(gains, key))
        if joints and n not in (1, len(joints)):
            raise ConfigError(f"{origin}: [gains] {key}: expected 1 or {len(joints)} numbers, got {n}")
    g.finish()

    f = top.sub("filter", SECTION_KEYS["filter"])
    level = f.string("level", LEVELS[0])
    if level not in LEVELS:
        raise ConfigError(f"{origin}: [filter] level: unknown {level!r}; valid: {', '.join(LEVELS)}")
    try:
        filt = FilterSpec.from_mapping({name: f.raw(name) for name in SPEC_NAMES if f.has(name)},
                                       where=f"{origin}: [filter]")
    except ConfigError as e:
        raise ConfigError(str(e) if str(e).startswith(origin) else f"{origin}: [filter] {e}") from None
    f.finish()

    c = top.sub("control", SECTION_KEYS["control"])
    control = ControlConfig(period=c.number("period", ControlConfig().period, positive=True))
    c.finish()

    moving_raw = top.raw("moving", [])
    if not isinstance(moving_raw, list):
        raise ConfigError(f"{origin}: 'moving' must be an array of tables ([[moving]])")
    moving = []
    for i, m in enumerate(moving_raw):
        if not isinstance(m, Mapping):
            raise ConfigError(f"{origin}: [[moving]] entry {i + 1} must be a table")
        mr = _Reader(m, "moving", origin, label=f"[[moving]] entry {i + 1}")
        moving.append(MovingObstacle(body=mr.string("body"), path=_path(mr)))
        mr.finish()
    top.finish()

    return SceneConfig(name=name, description=description, model=model, robot=robot,
                       obstacles=obstacles, task=task, barrier=barrier, gains=gains,
                       filter=filt, control=control, moving=tuple(moving), source=source, arms=arms,
                       level=level)


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
