"""Parameter sweeps: strategies x filter parameters x scenes x seeds, summarised with a Pareto front.

A sweep is a list of :class:`SweepPoint` (a strategy and the filter parameters it overrides), run
on every scene and seed. Every point of a scene runs on the same seeds (same initial configuration,
goal jitter and obstacle phase per seed) with the same ``d_bar`` (resolved once per scene: flag,
config or the tracking calibration). Episodes run through :func:`isf_robot.support.parallel.run_tasks`
(local processes or Ray; Ctrl-C keeps what finished) and every result is a plain JSON-ready dict, so the
same seeds give the same numbers whatever the number of workers.

Per scene and point, :func:`summarize_point` gives the means over episodes plus the worst episode's
figures the issue's targets need (shortest off period over all episodes, violations, whether the
``d_bar`` in use covered the tracking error in every episode); :func:`pareto_front` marks the points
no other point beats on every objective of :data:`OBJECTIVES` at once.

A scene with several arms (``[[arm]]`` tables) runs each point once per way of filtering (``central``,
``decentral``: :func:`team_points`, the label ``isf/central c=0.1``) through
:class:`~isf_robot.arm.multi_arm.MultiArmSimulation`; its rows are the team's figures (duty: a filter on;
violations: collision steps plus penetrating contacts) plus each arm's (``arms``: its own filter's duty,
switches and shortest off period, its intervention, goals and coordination; :func:`summarize_arms`), and
each row's ratios to cbf are to cbf of the same way of filtering.

Time to complete the goals (``goals_time_s``): the scene's goal sequence has ``n`` goals and every
episode reports the time of each arrival (``goal_times_s``). Per scene, ``k`` (``goals_time_k``)
is ``n`` if every episode of every point reached ``n`` goals, else the fewest arrivals any episode
of the scene made (at least 1); ``goals_time_s`` of a point is the mean over its episodes of the
time of the k-th arrival, an episode with fewer than k arrivals counting as its whole duration
(``goals_time_censored`` counts them). So it is the time to complete the goals when every point
completes them, else the time to the k-th goal, the same k for every point of the scene.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from isf_robot.core import ConfigError, UnknownNameError
from isf_robot.core.spec import PARAMETERS as SPEC_PARAMETERS
from isf_robot.core.strategies import strategy_info
from isf_robot.support.parallel import MAX_JOBS, Interrupted, check_backend, run_tasks
from isf_robot.support.report import format_table

from .compare import EpisodeTask, SceneSpec, json_safe, level_params, make_simulation, run_task, simulation_type
from .multi_arm import COORDINATIONS
from .records import FilterParams

__all__ = ["SweepPoint", "SweepTask", "grid_points", "random_points", "run_sweep", "summarize_point",
           "summarize_arms", "team_points",
           "pareto_front", "goals_time", "format_sweep", "PARAMETERS", "OBJECTIVES", "MAX_SWEEP_EPISODES"]

PARAMETERS = tuple(q.name for q in SPEC_PARAMETERS if q.swept)
"""Filter parameters a sweep can vary: the :class:`~isf_robot.core.FilterSpec` fields marked ``swept``."""

_INTERMITTENT_ONLY = frozenset(q.name for q in SPEC_PARAMETERS if q.intermittent)

OBJECTIVES: tuple[tuple[str, int], ...] = (
    ("duty_cycle", -1), ("on_switches", -1), ("min_off_all_s", +1), ("intervention", -1),
    ("goals_reached", +1), ("goals_time_s", -1), ("violations", -1),
)
"""``(key, sense)`` of the Pareto front: -1 smaller is better, +1 larger is better."""

MAX_SWEEP_EPISODES = 1_000_000


@dataclass(frozen=True)
class SweepPoint:
    """One setting of a sweep: a strategy and the filter parameters it sets (others: the scene's)."""

    strategy: str
    values: Mapping[str, float] = field(default_factory=dict)
    coordination: str | None = None
    """A scene with several arms: ``central`` or ``decentral`` (``None``: one arm)."""

    @property
    def label(self) -> str:
        """``strategy[/coordination] k=v ...`` (the values in :data:`PARAMETERS` order)."""
        parts = [f"{k}={self.values[k]:g}" for k in PARAMETERS if k in self.values]
        head = self.strategy if self.coordination is None else f"{self.strategy}/{self.coordination}"
        return " ".join([head] + parts)


def team_points(points: Sequence[SweepPoint], coordinations: Sequence[str]) -> list[SweepPoint]:
    """The points of a scene with several arms: each point once per way of filtering (``nominal``: once)."""
    out = []
    for pt in points:
        ways = coordinations if strategy_info(pt.strategy).filters else coordinations[:1]
        out += [SweepPoint(pt.strategy, pt.values, way) for way in ways]
    return out


def _check_values(name: str, values: Sequence[float]) -> None:
    if name not in PARAMETERS:
        raise ConfigError(f"unknown sweep parameter {name!r}; valid: {', '.join(PARAMETERS)}")
    if not values:
        raise ConfigError(f"sweep parameter {name} has no values")


def grid_points(strategies: Sequence[str], grid: Mapping[str, Sequence[float]]) -> list[SweepPoint]:
    """Every combination of the grid's values per strategy (a strategy gets only the parameters it uses)."""
    for k, v in grid.items():
        _check_values(k, v)
        bad = [x for x in v if k == "predict_every" and not (math.isfinite(x) and x >= 1 and int(x) == x)]
        if bad:
            raise ConfigError(f"--predict-every takes whole numbers of control steps >= 1, got {bad[0]:g}")
    out: list[SweepPoint] = []
    for s in strategies:
        info = strategy_info(s)
        keys = [k for k in grid if info.filters and (info.intermittent or k not in _INTERMITTENT_ONLY)]
        for combo in itertools.product(*(grid[k] for k in keys)):
            out.append(SweepPoint(s, dict(zip(keys, combo))))
    return out


def random_points(strategies: Sequence[str], ranges: Mapping[str, tuple[float, float]], n: int,
                  seed: int = 0) -> list[SweepPoint]:
    """Random sweep points.

    ``n`` points per intermittent strategy drawn uniformly from ``ranges`` (log-uniform for a range
    spanning more than a factor 10 with both ends > 0); other strategies get one point each at the
    ranges' midpoints of the parameters they use. ``predict_every`` is rounded to a whole number.
    """
    if n < 1:
        raise ConfigError(f"--random must be >= 1, got {n}")
    for k, (lo, hi) in ranges.items():
        _check_values(k, [lo, hi])
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ConfigError(f"sweep range of {k} must be LO:HI with LO <= HI, got {lo}:{hi}")
    rng = np.random.default_rng(seed)

    def draw(k: str, lo: float, hi: float) -> float:
        v = (math.exp(rng.uniform(math.log(lo), math.log(hi))) if lo > 0 and hi > 10 * lo
             else float(rng.uniform(lo, hi)))
        return float(round(v)) if k == "predict_every" else v

    out: list[SweepPoint] = []
    for s in strategies:
        info = strategy_info(s)
        if info.intermittent:
            out += [SweepPoint(s, {k: draw(k, *r) for k, r in ranges.items()}) for _ in range(n)]
        else:
            keys = [k for k in ranges if info.filters and k not in _INTERMITTENT_ONLY]
            out.append(SweepPoint(s, {k: 0.5 * (ranges[k][0] + ranges[k][1]) for k in keys}))
    return out


@dataclass(frozen=True)
class SweepTask:
    """One episode of a sweep (picklable): the scene's index, the point's index (among the scene's) and the episode."""

    scene: int
    point: int
    episode: EpisodeTask
    label: str = ""
    """The point's label (:attr:`SweepPoint.label`)."""


def run_sweep_task(task: SweepTask) -> dict[str, Any]:
    """Run one episode of a sweep (used by the worker processes)."""
    return run_task(task.episode)


def _params_of(scene: Any, base: FilterParams, point: SweepPoint, level: str = "velocity") -> FilterParams:
    v = dict(point.values)
    every = v.pop("predict_every", None)
    p = level_params(scene, level, d_bar=base.d_bar, predict_every=every, **v)  # (whole: grid_points, random_points)
    return p.replace(d_bar_source=base.d_bar_source)


def summarize_point(runs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Means over episodes, plus the worst episode's figures (see the module docstring)."""
    def mean(key: str) -> float | None:
        vals = [float(r[key]) for r in runs if r.get(key) is not None and math.isfinite(float(r[key]))]
        return float(np.mean(vals)) if vals else None

    offs = [r["min_off_s"] for r in runs if r.get("min_off_s") is not None]
    bounds = [r["off_bound_min_s"] for r in runs if r.get("off_bound_min_s") is not None]
    out: dict[str, Any] = {k: mean(k) for k in (
        "duty_cycle", "on_switches", "min_off_s", "intervention", "goals_reached", "goals_missed",
        "tracking_error_q99", "switch_jump_max", "qp_solves", "wall_s")}
    out.update(
        episodes=len(runs),
        min_off_all_s=min(offs) if offs else None,  # the shortest complete off period of any episode
        off_bound_min_s=min(bounds) if bounds else None,
        # (a team's: collision steps plus penetrating contacts of any kind)
        violations=int(sum(int(r.get("violations", r["collisions"])) for r in runs)),
        min_barrier=min(float(r["min_barrier"]) for r in runs) if runs else None,
        d_bar=runs[0]["d_bar"] if runs else None,
        d_bar_covered_all=all(bool(r["d_bar_covered"]) for r in runs),
        seeds=sorted(int(r["seed"]) for r in runs),
    )
    if runs and runs[0].get("arms"):
        out["arms"] = summarize_arms(runs)
    return out


def summarize_arms(runs: Sequence[Mapping[str, Any]], min_off_key: str = "min_off_all_s") -> list[dict[str, Any]]:
    """A team's episodes: each arm's means and its shortest off period of all episodes.

    Means of the duty, switches, intervention, goals, coordination and short off periods; the shortest off
    period under ``min_off_key`` (``compare`` names it ``min_off_s``).
    """
    out = []
    for i, first in enumerate(runs[0]["arms"]):
        arms = [r["arms"][i] for r in runs]
        offs = [a["min_off_s"] for a in arms if a.get("min_off_s") is not None]
        row: dict[str, Any] = {"name": first["name"], min_off_key: min(offs) if offs else None}
        for key in ("duty_cycle", "on_switches", "intervention", "goals_reached", "goals_missed",
                    "coordination_steps", "coordination_events", "short_offs"):
            row[key] = float(np.mean([float(a[key]) for a in arms]))
        out.append(row)
    return out


def goals_time(points: Sequence[Sequence[Mapping[str, Any]]], n_goals: int) -> tuple[int, list[dict[str, Any]]]:
    """``k`` and, per point, ``goals_time_s``/``goals_time_censored`` (see the module docstring).

    ``points`` are the episodes' results of each point of one scene (``goal_times_s``,
    ``duration_s``); a point without episodes gets ``None``.
    """
    counts = [len(r.get("goal_times_s") or ()) for runs in points for r in runs]
    k = max(1, min([int(n_goals)] + counts)) if counts else max(1, int(n_goals))
    out = []
    for runs in points:
        times = [(r["goal_times_s"][k - 1] if len(r.get("goal_times_s") or ()) >= k else None, r["duration_s"])
                 for r in runs]
        out.append({"goals_time_s": float(np.mean([t if t is not None else d for t, d in times])) if times else None,
                    "goals_time_censored": sum(1 for t, _ in times if t is None)})
    return k, out


def _objective(row: Mapping[str, Any], key: str, sense: int) -> float:
    v = row.get(key)
    if v is None:  # no complete off period: the best case for min off (never switched back on)
        return math.inf if key == "min_off_all_s" else -math.inf * sense
    return float(v) * sense


def pareto_front(rows: Sequence[Mapping[str, Any]]) -> list[bool]:
    """Whether each row is on the Pareto front of :data:`OBJECTIVES` among ``rows``."""
    vals = [[_objective(r, k, s) for k, s in OBJECTIVES] for r in rows]
    front = []
    for i, a in enumerate(vals):
        dominated = any(all(x >= y for x, y in zip(b, a)) and any(x > y for x, y in zip(b, a))
                        for j, b in enumerate(vals) if j != i)
        front.append(not dominated)
    return front


ProgressFn = Callable[[int, int, SweepTask, Mapping[str, Any]], None]


def run_sweep(specs: Sequence[SceneSpec], points: Sequence[SweepPoint], seeds: Sequence[int], *,
              duration: float | None = None, jobs: int = 1, d_bar: float | None = None,
              progress: ProgressFn | None = None, backend: str = "processes",
              address: str | None = None, level: str = "velocity",
              coordinations: Sequence[str] | None = None) -> dict[str, Any]:
    """Run every point on every scene and seed; return the JSON-ready sweep (see :func:`_summary`).

    ``level``: ``"velocity"`` or ``"torque"`` (:func:`~isf_robot.arm.compare.simulation_type`; at the
    torque level ``d_bar`` is in rad/s^2, calibrated by the torque calibration when not given).

    ``coordinations``: on a scene with several arms, each point runs once per way of filtering
    (:data:`~isf_robot.arm.multi_arm.COORDINATIONS`, default every way; :func:`team_points`), and its
    row adds each arm's figures (``arms``, :func:`summarize_arms`). Scenes of one arm ignore it.

    ``backend``/``address``: where the episodes run (:func:`isf_robot.support.parallel.run_tasks`:
    local processes, or Ray); the numbers do not depend on it nor on ``jobs``.

    Raises:
        ConfigError: Bad parameters (checked for every scene and point before any episode runs).
        Interrupted: Ctrl-C / SIGTERM; ``exc.partial`` is the sweep of the finished episodes.

    """
    if not points:
        raise ConfigError("no sweep points")
    if not seeds:
        raise ConfigError("no seeds")
    if not 1 <= int(jobs) <= MAX_JOBS:
        raise ConfigError(f"--jobs must be between 1 and {MAX_JOBS}, got {jobs}")
    n = len(specs) * len(points) * len(seeds)
    if n > MAX_SWEEP_EPISODES:
        raise ConfigError(f"{n} episodes asked for; at most {MAX_SWEEP_EPISODES} per sweep")
    check_backend(backend, address)  # a missing Ray extra is said before any episode runs
    simulation_type(level)  # (an unknown level: said before any scene loads)
    ways = list(COORDINATIONS) if coordinations is None else list(coordinations)
    for way in ways:
        if way not in COORDINATIONS:
            raise UnknownNameError("coordination", way, list(COORDINATIONS))
    if not ways:
        raise ConfigError("no coordination")
    tasks: list[SweepTask] = []
    names: list[tuple[str, int]] = []
    scene_points: list[list[SweepPoint]] = []
    for i, spec in enumerate(specs):
        scene = spec.load()
        names.append((scene.name, len(scene.goal_positions)))
        if scene.arms and level != "velocity":
            raise ConfigError(f"the {level} level runs a scene with one arm; {scene.name} has {len(scene.arms)} "
                              "arms (sweep it at the velocity level)")
        pts = team_points(points, ways) if scene.arms else list(points)
        scene_points.append(pts)
        base = level_params(scene, level, d_bar=d_bar)
        for j, pt in enumerate(pts):
            fp = _params_of(scene, base, pt, level)
            make_simulation(scene, pt.strategy, level, pt.coordination, int(seeds[0]),  # (validates)
                            params=fp).control_steps(duration)
            tasks += [SweepTask(i, j, EpisodeTask(spec, pt.strategy, int(s), duration, {"params": fp}, level,
                                                  pt.coordination), pt.label) for s in seeds]
    if coordinations is not None and not any(pt.coordination for pts in scene_points for pt in pts):
        raise ConfigError("--coordination needs a scene with several arms ([[arm]] tables); "
                          f"{', '.join(n for n, _ in names)} {'has' if len(names) == 1 else 'have'} one")
    if len(tasks) > MAX_SWEEP_EPISODES:  # (a team scene runs each point once per way of filtering)
        raise ConfigError(f"{len(tasks)} episodes asked for (a scene with several arms runs each point once per "
                          f"way of filtering); at most {MAX_SWEEP_EPISODES} per sweep")
    results: dict[tuple[int, int], list[dict[str, Any]]] = {}

    def keep(done: int, total: int, task: SweepTask, r: dict[str, Any]) -> None:
        results.setdefault((task.scene, task.point), []).append(r)
        if progress is not None:
            progress(done, total, task, r)

    def summary(partial: bool) -> dict[str, Any]:
        out = _summary(names, scene_points, list(seeds), results, partial)
        if level != "velocity":  # (the velocity level's output as it was)
            out["level"] = level
        return out

    try:
        run_tasks(run_sweep_task, tasks, jobs=int(jobs), on_result=keep, backend=backend, address=address)
    except Interrupted as exc:
        exc.partial = summary(True)
        raise
    return summary(False)


def _summary(names: list[tuple[str, int]], scene_points: Sequence[Sequence[SweepPoint]], seeds: list[int],
             results: Mapping[tuple[int, int], list[dict[str, Any]]], partial: bool) -> dict[str, Any]:
    scenes = []
    for i, (name, n_goals) in enumerate(names):
        points = scene_points[i]
        rows = []
        done = [(pt, sorted(runs, key=lambda r: r["seed"])) for j, pt in enumerate(points)
                if (runs := results.get((i, j)))]
        goal_k, times = goals_time([runs for _, runs in done], n_goals)
        for (pt, runs), t in zip(done, times):
            rows.append({"strategy": pt.strategy, "values": dict(pt.values), "label": pt.label,
                         **({} if pt.coordination is None else {"coordination": pt.coordination}),
                         **summarize_point(runs), **t, "runs": runs})
        for r, on in zip(rows, pareto_front(rows)):
            r["pareto"] = on
            # the standard filter of the same coordination (a team's central and decentral rows: each its own)
            cbf = next((c for c in rows if c["strategy"] == "cbf" and c.get("coordination") == r.get("coordination")),
                       None)
            if cbf is not None:
                r["vs_cbf"] = {k: (None if r[k] is None or not cbf[k] else r[k] / cbf[k])
                               for k in ("duty_cycle", "on_switches", "intervention")}
                r["vs_cbf"]["goals_diff"] = (None if r["goals_reached"] is None or cbf["goals_reached"] is None
                                             else r["goals_reached"] - cbf["goals_reached"])
        scenes.append({"scene": name, "goals": n_goals, "goals_time_k": goal_k, "n_points": len(points),
                       "points": rows})
    return json_safe({"partial": partial, "seeds": seeds, "objectives": [k for k, _ in OBJECTIVES],
                      "scenes": scenes})


_COLUMNS = (("duty_cycle", "duty", ".3f"), ("on_switches", "switches", ".1f"),
            ("min_off_all_s", "min off [s]", ".3f"), ("off_bound_min_s", "bound [s]", ".3f"),
            ("intervention", "interv.", ".3f"), ("goals_reached", "goals", ".2f"), ("goals_time_s", "t goals", ".2f"),
            ("violations", "viol.", "d"), ("switch_jump_max", "jump", ".3f"),
            ("tracking_error_q99", "err q99", ".3f"))


def _cell(v: Any, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def format_sweep(sweep: Mapping[str, Any]) -> str:
    """One table per scene: a row per point, ``*`` on the Pareto front, ratios to cbf when it ran."""
    out = []
    for sc in sweep["scenes"]:
        rows = []
        for r in sc["points"]:
            ratio = r.get("vs_cbf") or {}
            rows.append([("* " if r["pareto"] else "  ") + r["label"]]
                        + ([f"{r['episodes']}/{len(sweep['seeds'])}"] if sweep["partial"] else [])
                        + [_cell(r.get(k), f) for k, _, f in _COLUMNS]
                        + [_cell(ratio.get(k), ".2f") for k in ("duty_cycle", "on_switches", "intervention")]
                        + ["yes" if r["d_bar_covered_all"] else "no"])
        n_seeds = len(sweep["seeds"])
        if sweep["partial"]:
            done = sum(int(r["episodes"]) for r in sc["points"])
            total = n_seeds * int(sc.get("n_points", len(sc["points"])))
            head = (f"PARTIAL (interrupted) scene {sc['scene']}: {done} of {total} episodes finished "
                    f"({len(sc['points'])} of {sc.get('n_points', len(sc['points']))} points have one; "
                    f"'runs': the point's finished episodes of {n_seeds}), means over them")
        else:
            head = f"scene {sc['scene']}: {n_seeds} seed(s) per point, means"
        title = (head + f" (min off: shortest over episodes; t goals: time of goal {sc.get('goals_time_k', '-')} of "
                 f"{sc.get('goals', '-')} [s]; * Pareto front)")
        out.append(format_table(["point"] + (["runs"] if sweep["partial"] else []) + [h for _, h, _ in _COLUMNS]
                                + ["duty/cbf", "sw/cbf", "int/cbf", "d_bar ok"], rows, title=title))
        arm_rows = [[r["label"], a["name"]] + [_cell(a.get(k), f) for k, _, f in _ARM_COLUMNS]
                    for r in sc["points"] for a in r.get("arms") or ()]
        if arm_rows:
            out.append(format_table(["point", "arm"] + [h for _, h, _ in _ARM_COLUMNS], arm_rows,
                                    title=f"scene {sc['scene']}, per arm (its own filter's duty, switches and "
                                          "off periods; intervention over its joints; means, min off: shortest)"))
    return "\n\n".join(out)


_ARM_COLUMNS = (("duty_cycle", "duty", ".3f"), ("on_switches", "switches", ".1f"),
                ("min_off_all_s", "min off [s]", ".3f"), ("intervention", "interv.", ".3f"),
                ("goals_reached", "goals", ".2f"), ("coordination_steps", "coord. steps", ".0f"),
                ("coordination_events", "coord. events", ".1f"))
