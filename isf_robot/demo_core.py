"""The core demo: a planar single integrator driving past disc obstacles.

Three strategies on the same seeded scene: ``nominal`` (no filter), ``cbf`` (the standard
filter solved every step) and ``isf`` (the intermittent filter). Everything here uses only the
engine-free core. The robot ``x_dot = u`` is integrated exactly over each step (zero-order hold).

Safety of the sampled loop follows from convexity: each barrier ``h = |p - c|^2 - r^2`` is
convex, so over a step ``h(p + s dt u) >= h(p) + s dt dh/dp u``; with ``dt * alpha_gain <= 1``
the barrier condition at the sample keeps ``h >= 0`` along the whole step.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from .core import (
    DiscObstacleBarrier,
    Linear,
    MetricsAccumulator,
    SingleIntegrator,
    evaluate_barriers,
    lie_data,
)
from .core.exceptions import ConfigError
from .core.spec import FilterSpec
from .core.strategies import make_strategy, strategy_info, strategy_names
from .support.report import format_table as report_table
from .support.report import format_value, mean_std_cell

__all__ = ["DemoScene", "make_scene", "run_episode", "compare", "format_table", "MAX_STEPS"]

MAX_STEPS = 10_000_000
"""Longest core-demo episode in steps (the trajectory is stored per step)."""


@dataclass(frozen=True)
class DemoScene:
    """A seeded planar scene.

    Attributes:
        start: Start position [m], shape (2,).
        goal: Goal position [m], shape (2,).
        centers: Disc centres [m], shape (k, 2).
        radii: Disc radii [m], shape (k,).

    """

    start: np.ndarray
    goal: np.ndarray
    centers: np.ndarray
    radii: np.ndarray


def make_scene(seed: int, n_obstacles: int = 4) -> DemoScene:
    """Place ``n_obstacles`` discs across the straight path from (0, 0) to (10, 0)."""
    if n_obstacles < 1:
        raise ConfigError(f"n_obstacles must be >= 1, got {n_obstacles}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be a non-negative integer, got {seed!r}")
    rng = np.random.default_rng(seed)
    xs = np.linspace(2.0, 8.0, n_obstacles) + rng.uniform(-0.3, 0.3, n_obstacles)
    ys = rng.uniform(-0.35, 0.35, n_obstacles)
    radii = rng.uniform(0.5, 0.8, n_obstacles)
    return DemoScene(np.zeros(2), np.array([10.0, 0.0]), np.column_stack([xs, ys]), radii)


def nominal_command(x: np.ndarray, goal: np.ndarray, speed: float = 1.0, gain: float = 2.0) -> np.ndarray:
    """Go-to-goal proportional command saturated at ``speed`` [m/s]."""
    u = gain * (goal - x)
    n = float(np.hypot(u[0], u[1]))
    return u * (speed / n) if n > speed else u


def run_episode(
    strategy: str,
    seed: int,
    *,
    duration: float = 20.0,
    dt: float = 0.01,
    alpha_gain: float = 2.0,
    c: float = 1.0,
    b: float = 1.0,
    n_obstacles: int = 4,
    record: bool = False,
) -> dict[str, Any]:
    """Run one episode and return its figures (and the trajectory when ``record``)."""
    info = strategy_info(strategy)  # UnknownNameError listing the valid names
    if not (math.isfinite(duration) and duration > 0 and math.isfinite(dt) and dt > 0):
        raise ConfigError(f"duration and dt must be finite and > 0, got {duration}, {dt}")
    scene = make_scene(seed, n_obstacles)
    system = SingleIntegrator(2)
    barriers = [
        DiscObstacleBarrier(cc, r, name=f"disc{i}") for i, (cc, r) in enumerate(zip(scene.centers, scene.radii))
    ]
    alpha = Linear(alpha_gain)
    filt = (make_strategy(strategy, FilterSpec(alpha=alpha, c=c, b=b), system=system, barriers=barriers)
            if info.filters else None)
    steps = int(round(duration / dt))
    if steps > MAX_STEPS:
        raise ConfigError(f"duration {duration:g} s is {steps:.3g} steps of {dt:g} s; at most {MAX_STEPS:.0e}")
    x = scene.start.copy()
    acc = MetricsAccumulator()
    h_min = np.inf
    collisions = 0
    reached_at: float | None = None
    traj = np.empty((steps + 1, 2))
    traj[0] = x
    f0, g = system.f0(x), system.g(x)
    t_wall = time.perf_counter()
    for k in range(steps):
        t = k * dt
        u_nom = nominal_command(x, scene.goal)
        if filt is None:
            u, on, solved = u_nom, False, False
        else:
            step = filt.step_lie(t, lie_data(evaluate_barriers(barriers, x, t), f0, g), u_nom, x=x)
            u, on, solved = step.u, step.on, step.qp is not None
        acc.add(t, dt, on, u, u_nom, solved)
        x = x + dt * u
        traj[k + 1] = x
        d = x - scene.centers
        h = np.einsum("ij,ij->i", d, d) - scene.radii**2
        hm = float(h.min())
        h_min = min(h_min, hm)
        collisions += hm < 0.0
        if reached_at is None and float(np.hypot(*(x - scene.goal))) < 0.05:
            reached_at = t + dt
    wall = time.perf_counter() - t_wall
    m = acc.result()
    out: dict[str, Any] = {
        "strategy": strategy,
        "seed": seed,
        "duration_s": m.duration_s,
        "control_steps": m.control_steps,
        "duty_cycle": m.duty_cycle,
        "on_switches": m.on_switches,
        "mean_off_s": m.mean_off_s,
        "min_off_s": m.min_off_s,
        "min_barrier": h_min,
        "collisions": collisions,
        "goal_reached_s": reached_at,
        "intervention": m.intervention,
        "qp_solves": m.qp_solves,
        "wall_s": wall,
    }
    if record:
        out["trajectory"] = traj
        out["scene"] = scene
    return out


def compare(seeds: list[int], **kwargs: Any) -> dict[str, list[dict[str, Any]]]:
    """Run every strategy on every seed."""
    return {s: [run_episode(s, seed, **kwargs) for seed in seeds] for s in strategy_names()}


def _cell(values: list[Any], fmt: str) -> str:
    vals = [v for v in values if v is not None]
    if not vals:
        return "-"
    if len(vals) == 1:
        return format_value(float(vals[0]), fmt)
    return mean_std_cell(float(np.mean(vals)), float(np.std(vals)), fmt)


def format_table(results: dict[str, list[dict[str, Any]]]) -> str:
    """Plain-text table: mean ± std over episodes per strategy."""
    cols = [
        ("duty cycle", "duty_cycle", ".3f"),
        ("on-switches", "on_switches", ".1f"),
        ("mean off [s]", "mean_off_s", ".2f"),
        ("min off [s]", "min_off_s", ".2f"),
        ("min h [m^2]", "min_barrier", ".3f"),
        ("collisions", "collisions", ".1f"),
        ("goal at [s]", "goal_reached_s", ".2f"),
        ("intervention", "intervention", ".3f"),
        ("QP solves", "qp_solves", ".0f"),
        ("wall [ms]", "wall_ms", ".1f"),
    ]
    rows = []
    for strat, eps in results.items():
        for e in eps:
            e.setdefault("wall_ms", 1e3 * e["wall_s"])
        rows.append([strat] + [_cell([e[key] for e in eps], f) for _, key, f in cols])
    return report_table(["strategy"] + [c[0] for c in cols], rows, align_first_only=True)
