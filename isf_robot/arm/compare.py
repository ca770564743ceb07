"""Comparing the strategies over seeded episodes, optionally in parallel processes.

Every strategy runs on the same seeds (same initial configuration, goal jitter and obstacle
phase per seed) and the same filter parameters, resolved once in the calling process
(:func:`~isf_robot.arm.params.resolve_params`: arguments, then the scene's ``[filter]``, then the
tracking calibration for ``d_bar``). Workers receive only plain values (scene name or file
paths, the resolved :class:`~isf_robot.arm.records.FilterParams`) and rebuild the scene, so the
pool works with the ``spawn`` start method and no worker calibrates.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from isf_robot.core import ConfigError
from isf_robot.core.strategies import strategy_info, strategy_names
from isf_robot.support.parallel import MAX_JOBS, Interrupted, run_tasks
from isf_robot.support.report import format_table as _table
from isf_robot.support.report import mean_std_cell, to_jsonable

from .config_schema import LEVELS
from .multi_arm import MultiArmSimulation
from .params import resolve_params
from .records import FilterParams
from .scene import Scene, load_scene, load_scene_from_files
from .sim import ArmSimulation
from .torque_sim import TorqueSimulation, resolve_torque_params

__all__ = [
    "SceneSpec",
    "EpisodeTask",
    "Comparison",
    "SUMMARY_KEYS",
    "run_task",
    "compare_strategies",
    "summarize",
    "format_table",
    "format_levels",
    "json_safe",
    "FILTER_KEYS",
    "simulation_type",
    "level_params",
]

MAX_EPISODES = 1_000_000
"""Most episodes (strategies x seeds) in one comparison."""

# Keyword arguments that are filter parameters (resolved once by :func:`resolve_params`).
FILTER_KEYS = ("alpha", "c", "b", "d_bar")

# Per-run keys averaged in a comparison (mean and standard deviation over episodes).
SUMMARY_KEYS: tuple[str, ...] = (
    "duration_s", "control_steps", "duty_cycle", "on_switches", "mean_off_s", "min_off_s", "short_offs",
    "min_barrier", "collisions", "goals_reached", "goals_missed", "intervention", "qp_solves",
    "fallbacks", "relaxations", "min_joint_barrier", "tracking_error_q99", "qp_time_median_us",
    "d_bar", "wall_s",
)


@dataclass(frozen=True)
class SceneSpec:
    """How to load a scene in any process: a shipped name, or an MJCF and a TOML path.

    Attributes:
        name: Shipped scene name, or ``None``.
        model: MJCF path, or ``None``.
        config: TOML path, or ``None``.

    """

    name: str | None = None
    model: str | None = None
    config: str | None = None

    def __post_init__(self) -> None:
        files = self.model is not None or self.config is not None
        if self.name is not None and files:
            raise ConfigError("give either a scene name or --model and --config, not both")
        if self.name is None and (self.model is None or self.config is None):
            raise ConfigError("give a scene name (--scene NAME) or both --model PATH.xml and "
                              "--config PATH.toml")

    def load(self) -> Scene:
        """Load the scene (errors are :class:`~isf_robot.core.ConfigError` subclasses)."""
        if self.name is not None:
            return load_scene(self.name)
        assert self.model is not None and self.config is not None  # checked in __post_init__
        return load_scene_from_files(self.model, self.config)


@dataclass(frozen=True)
class EpisodeTask:
    """One episode to run (picklable).

    Attributes:
        spec: The scene.
        strategy: ``nominal``, ``cbf`` or ``isf``.
        seed: Episode seed.
        duration: Simulated time [s] (``None``: the scene's).
        params: Keyword arguments for :class:`~isf_robot.arm.ArmSimulation` (``params=`` the
            resolved :class:`FilterParams`, ``control_period``, ``observers``, ...).
        level: ``"velocity"`` (:class:`~isf_robot.arm.ArmSimulation`) or ``"torque"``
            (:class:`~isf_robot.arm.torque_sim.TorqueSimulation`).
        coordination: A scene with several arms: how they are filtered (``central`` or ``decentral``,
            :class:`~isf_robot.arm.multi_arm.MultiArmSimulation`; the result adds each arm's figures);
            ``None`` for one arm.

    """

    spec: SceneSpec
    strategy: str
    seed: int
    duration: float | None
    params: Mapping[str, Any] = field(default_factory=dict)
    level: str = "velocity"
    coordination: str | None = None


def simulation_type(level: str) -> type[ArmSimulation]:
    """The simulation of a level (:data:`~isf_robot.arm.config_schema.LEVELS`).

    Raises:
        ConfigError: An unknown level (the message lists the valid ones).

    """
    if level not in LEVELS:
        raise ConfigError(f"unknown level {level!r}; valid: {', '.join(LEVELS)}")
    return TorqueSimulation if level == "torque" else ArmSimulation


def level_params(scene: Scene, level: str, *args: Any, **options: Any) -> FilterParams:
    """The filter parameters of a level: :func:`resolve_params` or :func:`resolve_torque_params` (its ``d_bar``)."""
    simulation_type(level)
    return (resolve_torque_params if level == "torque" else resolve_params)(scene, *args, **options)


def make_simulation(scene: Scene, strategy: str, level: str, coordination: str | None, seed: int,
                    **kwargs: Any) -> Any:
    """One episode's simulation: a team's (:class:`MultiArmSimulation`) with a way of filtering, else the level's."""
    if coordination is not None:
        return MultiArmSimulation(scene, strategy, coordination=coordination, seed=seed, **kwargs)
    return simulation_type(level)(scene, strategy, seed=seed, **kwargs)


def run_task(task: EpisodeTask) -> dict[str, Any]:
    """Run one episode and return its JSON-ready result (used by the worker processes)."""
    scene = task.spec.load()
    kwargs = dict(task.params)
    if not isinstance(kwargs.get("params"), FilterParams):
        kwargs["params"] = level_params(scene, task.level, *(kwargs.pop(k, None) for k in FILTER_KEYS))
    sim = make_simulation(scene, task.strategy, task.level, task.coordination, task.seed, **kwargs)
    res = sim.run_team(task.duration) if task.coordination is not None else sim.run(task.duration)
    return json_safe(res.as_dict())


json_safe = to_jsonable
"""JSON-ready values with non-finite floats as ``None`` (:func:`isf_robot.support.report.to_jsonable`)."""


def _stats(values: Sequence[Any]) -> tuple[float | None, float | None, int]:
    vals = [float(v) for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)
            and math.isfinite(float(v))]
    if not vals:
        return None, None, 0
    return float(np.mean(vals)), float(np.std(vals)), len(vals)


def summarize(runs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Mean of every :data:`SUMMARY_KEYS` entry over runs, plus ``std`` and ``episodes``.

    Runs where a key is ``None`` (e.g. ``min_off_s`` without a complete off period) are left
    out of that key's mean; ``count`` says how many runs each mean is over.
    """
    out: dict[str, Any] = {}
    std: dict[str, float | None] = {}
    count: dict[str, int] = {}
    for key in SUMMARY_KEYS:
        m, s, c = _stats([r.get(key) for r in runs])
        out[key] = m
        std[key] = s
        count[key] = c
    out["std"] = std
    out["count"] = count
    out["episodes"] = list(runs)
    return out


@dataclass(frozen=True)
class Comparison:
    """Result of :func:`compare_strategies`.

    Attributes:
        scene: Scene name.
        episodes: Episodes per strategy.
        seeds: The seeds used.
        results: Per strategy, :func:`summarize` of its runs (runs sorted by seed).

    """

    scene: str
    episodes: int
    seeds: tuple[int, ...]
    results: Mapping[str, Mapping[str, Any]]
    partial: bool = False
    level: str = "velocity"

    def as_dict(self) -> dict[str, Any]:
        """``{"scene", "episodes", "seeds", "partial", "results": {strategy: {key: mean, ..., "episodes": [...]}}}``.

        ``partial`` is true when the comparison was interrupted: the means are over the episodes
        that finished (``count`` per key, ``episodes`` lists them; ``finished`` counts them per
        strategy, of ``episodes``).
        """
        out = {"scene": self.scene, "episodes": self.episodes, "seeds": list(self.seeds),
               "partial": self.partial, "finished": self.finished(), "results": self.results}
        if self.level != "velocity":  # (the velocity level's output as it was)
            out["level"] = self.level
        return json_safe(out)

    def finished(self) -> dict[str, int]:
        """Episodes that finished, per strategy (``episodes`` each unless ``partial``)."""
        return {s: len(res.get("episodes", ())) for s, res in self.results.items()}


ProgressFn = Callable[[int, int, EpisodeTask, Mapping[str, Any]], None]


def compare_strategies(
    spec: SceneSpec,
    episodes: int,
    *,
    strategies: Sequence[str] | None = None,
    duration: float | None = None,
    seed0: int = 0,
    jobs: int = 1,
    params: Mapping[str, Any] | None = None,
    progress: ProgressFn | None = None,
    level: str = "velocity",
) -> Comparison:
    """Run every strategy on seeds ``seed0 .. seed0 + episodes - 1`` and summarise.

    The scene and the parameters are checked in this process before any worker starts, so bad
    input fails fast with a clear error.

    Args:
        spec: The scene.
        episodes: Episodes per strategy, >= 1.
        strategies: Registered strategy names to compare, no repeats (default: all,
            :func:`isf_robot.core.strategies.strategy_names`).
        duration: Simulated time per episode [s] (``None``: the scene's).
        seed0: First seed.
        jobs: Worker processes (1: run here, sequentially).
        params: Filter parameters (``alpha``, ``c``, ``b``, ``d_bar``: resolved here once, with
            the calibration if ``d_bar`` is unknown) and extra
            :class:`~isf_robot.arm.ArmSimulation` keyword arguments.
        progress: Called after each episode as ``progress(done, total, task, result)``.
        level: ``"velocity"`` or ``"torque"`` (:func:`simulation_type`; the torque level's ``d_bar`` is
            its own, :func:`~isf_robot.arm.torque_sim.resolve_torque_params`).

    Returns:
        The :class:`Comparison`.

    Raises:
        Interrupted: Ctrl-C or SIGTERM: workers are stopped, ``exc.partial`` is the
            :class:`Comparison` of the episodes that finished (``partial=True``).

    """
    if int(episodes) < 1:
        raise ConfigError(f"--episodes must be >= 1, got {episodes}")
    if not 1 <= int(jobs) <= MAX_JOBS:
        raise ConfigError(f"--jobs must be between 1 and {MAX_JOBS}, got {jobs}")
    n_tasks = int(episodes) * len(list(strategies or strategy_names()))
    if n_tasks > MAX_EPISODES:
        raise ConfigError(f"{n_tasks} episodes asked for; at most {MAX_EPISODES} per comparison "
                          "(split a larger study into comparisons over seed ranges with --seed)")
    strategies = list(strategy_names() if strategies is None else strategies)
    if not strategies:
        raise ConfigError("no strategies to compare")
    for s in strategies:
        strategy_info(s)  # UnknownNameError listing the valid names
    if len(set(strategies)) != len(strategies):
        raise ConfigError(f"strategies repeat: {strategies}")
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise ConfigError(f"duration must be a positive number of seconds, got {duration}")
    sim_type = simulation_type(level)
    scene = spec.load()
    params = dict(params or {})
    if not isinstance(params.get("params"), FilterParams):
        params["params"] = level_params(scene, level, *(params.pop(k, None) for k in FILTER_KEYS))
    # validates the control period and the rest before any worker starts
    sim_type(scene, strategies[0], seed=seed0, **params).control_steps(duration)
    seeds = tuple(range(int(seed0), int(seed0) + int(episodes)))
    # strategies in reverse order (by default the registry's: the unfiltered first, the intermittent last), so the
    # longer episodes start first and the short ones fill the workers' ends (the last worker idles less)
    tasks = [EpisodeTask(spec, s, seed, duration, params, level) for s in reversed(strategies) for seed in seeds]
    results: dict[tuple[str, int], dict[str, Any]] = {}

    def summary(partial: bool) -> Comparison:
        res = {s: summarize([results[(s, seed)] for seed in seeds if (s, seed) in results]) for s in strategies}
        return Comparison(scene=scene.name, episodes=int(episodes), seeds=seeds, results=res, partial=partial,
                          level=level)

    def keep(done: int, total: int, task: EpisodeTask, r: dict[str, Any]) -> None:
        results[(task.strategy, task.seed)] = r
        if progress is not None:
            progress(done, total, task, r)

    try:
        run_tasks(run_task, tasks, jobs=int(jobs), on_result=keep)
    except Interrupted as exc:
        exc.partial = summary(partial=True)
        raise
    return summary(partial=False)


# ----------------------------------------------------------------------------- table

_COLUMNS: tuple[tuple[str, str, str], ...] = (
    # (key, header, format)
    ("duty_cycle", "duty cycle", ".3f"),
    ("on_switches", "switches", ".1f"),
    ("mean_off_s", "mean off [s]", ".3f"),
    ("min_off_s", "min off [s]", ".3f"),
    ("short_offs", "offs < 0.25 s", ".1f"),
    ("min_barrier", "min h [m]", ".4f"),
    ("collisions", "collisions", ".1f"),
    ("goals_reached", "goals", ".2f"),
    ("intervention", "intervention", ".3f"),
    ("qp_solves", "QP solves", ".0f"),
    ("wall_s", "wall [s]", ".3f"),
)


def format_table(comp: Comparison) -> str:
    """Plain-text table, one row per strategy: mean ± standard deviation over episodes.

    An interrupted comparison's title says how many episodes finished per strategy.

    ``-`` marks a mean over no episode (e.g. no complete off period in any run). Below the table, a
    ``chatter:`` line per strategy whose episodes had off periods under 0.25 s, with the change that
    would stop it.
    """
    rows = [[strategy, *cells] for strategy, cells in _cells(comp)]
    if comp.partial:
        done = ", ".join(f"{s}: {n} of {comp.episodes} episodes finished" for s, n in comp.finished().items())
        title = (f"PARTIAL (interrupted; means over the finished episodes) scene {comp.scene}, seeds "
                 f"{comp.seeds[0]}..{comp.seeds[-1]} (mean ± std); {done}")
    else:
        title = (f"scene {comp.scene}: {comp.episodes} episode(s) per strategy, seeds "
                 f"{comp.seeds[0]}..{comp.seeds[-1]} (mean ± std)")
    if comp.level != "velocity":
        title += f"; {comp.level} level"
    return _table(["strategy"] + [h for _, h, _ in _COLUMNS], rows, title=title) + _chatter_lines(comp)


def format_levels(comps: Sequence[Comparison]) -> str:
    """One table of a scene compared at several levels (same seeds): a row per level and strategy.

    As :func:`format_table`; the intervention's unit is the level's (below the table).
    """
    first = comps[0]
    rows = [[comp.level, strategy, *cells] for comp in comps for strategy, cells in _cells(comp)]
    title = (f"scene {first.scene}: {first.episodes} episode(s) per strategy and level, seeds "
             f"{first.seeds[0]}..{first.seeds[-1]} (mean ± std)")
    partial = [c for c in comps if c.partial]
    if partial:
        done = "; ".join(f"{c.level} " + ", ".join(f"{s}: {n} of {c.episodes}" for s, n in c.finished().items())
                         for c in comps)
        title = f"PARTIAL (interrupted; means over the finished episodes) {title}; finished: {done}"
    out = _table(["level", "strategy"] + [h for _, h, _ in _COLUMNS], rows, title=title)
    out += ("\nintervention: the integral of |u - u_nom|^2, in rad^2/s at the velocity level (u: joint velocities) "
            "and N^2 m^2 s at the torque level (u: joint torques); min h on the true geometry at both")
    return out + "".join(_chatter_lines(c, f"{c.level} ") for c in comps)


def _cells(comp: Comparison) -> list[tuple[str, list[str]]]:
    """Per strategy, its table cells (mean ± std of each column)."""
    out = []
    for strategy, res in comp.results.items():
        std = res.get("std", {})
        out.append((strategy, [mean_std_cell(res.get(k), std.get(k), f) for k, _, f in _COLUMNS]))
    return out


def _chatter_lines(comp: Comparison, prefix: str = "") -> str:
    """A ``chatter:`` line per strategy with off periods under 0.25 s in some episode."""
    out = ""
    for strategy, res in comp.results.items():
        hit = [e["chatter"] for e in res.get("episodes", ()) if e.get("chatter")]
        if hit:
            first = hit[0].removeprefix("chatter: ")
            out += f"\nchatter: {prefix}{strategy} in {len(hit)} of {len(res['episodes'])} episodes; first: {first}"
    return out
