"""``isf-robot run`` and ``compare`` on a scene with several arms (``[[arm]]`` tables).

:mod:`isf_robot.cli.arm` hands a multi-arm scene here: the run goes through
:class:`~isf_robot.arm.multi_arm.MultiArmSimulation` with ``--coordination`` (``central`` or
``decentral``), and the output has one line per arm (duty cycle, switches, shortest off period,
intervention, goals, coordination steps and events) under the team's safety figures. ``compare --rrd DIR``
writes a recording per run (``<scene>-<strategy>-<coordination>-seed<seed>.rrd``), which ``replay`` and
``plot`` read per arm.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import numpy as np

from isf_robot.core.exceptions import ConfigError
from isf_robot.record.options import make_observer
from isf_robot.support.parallel import Interrupted, run_tasks
from isf_robot.support.report import format_value, to_jsonable, with_schema

__all__ = ["COORDINATION_HELP", "check_coordination", "team_simulation", "team_report", "team_compare"]

COORDINATION_HELP = ("with a scene of several arms: central (one filter over every arm's joints) or decentral "
                     "(one filter per arm, each with an equal share of every inter-arm row)")


def check_coordination(args: argparse.Namespace, scene: Any) -> None:
    """``--coordination`` only means something for a scene with several arms."""
    if getattr(args, "coordination", None) and not scene.arms:
        raise ConfigError(f"--coordination needs a scene with several arms ([[arm]] tables); {scene.name!r} has one")


def _arm_lines(r: Any) -> list[str]:
    out = [f"  {'arm':<8} {'duty':>6} {'on sw':>6} {'min off [s]':>11} {'interv.':>8} {'goals':>5} {'missed':>6} "
           f"{'coord. steps':>12} {'coord. events':>13}"]
    for a in r.arms:
        out.append(f"  {a['name']:<8} {a['duty_cycle']:>6.3f} {a['on_switches']:>6d} "
                   f"{format_value(a['min_off_s']):>11} {a['intervention']:>8.3f} {a['goals_reached']:>5d} "
                   f"{a['goals_missed']:>6d} {a['coordination_steps']:>12d} {a['coordination_events']:>13d}")
    return out


def team_simulation(args: argparse.Namespace, scene: Any, kwargs: dict[str, Any]) -> Any:
    """The simulation of a multi-arm scene for ``run`` and ``render`` (``--coordination``, default central)."""
    from isf_robot.arm.multi_arm import MultiArmSimulation

    return MultiArmSimulation(scene, args.filter, coordination=getattr(args, "coordination", None) or "central",
                              seed=args.seed, **kwargs)


def team_report(args: argparse.Namespace, sim: Any) -> int:
    """Run a multi-arm simulation; per-arm lines (or one JSON object)."""
    coordination = sim.coordination
    r = sim.run_team(args.duration)
    d = to_jsonable(r.as_dict())
    if args.json:
        print(json.dumps(with_schema("isf-robot-run", d)))
        return 0
    print(f"scene {d['scene']}, filter {d['filter']} ({coordination}), seed {d['seed']}: {d['duration_s']:.3f} s "
          f"simulated, {d['control_steps']} control steps in {d['wall_s']:.2f} s")
    print(f"  min barrier [m] (true geometry)  {format_value(d['min_barrier'])}; collision steps {d['collisions']}; "
          "clearance at ticks: " + ", ".join(f"{k} {format_value(v)}" for k, v in r.clearance.items())
          + f"; penetrating contacts {r.contacts}")
    print(f"  team duty {d['duty_cycle']:.3f}, QP solves {d['qp_solves']}, fallbacks {d['fallbacks']}, "
          f"d_bar {format_value(d['d_bar'])} rad/s")
    print("\n".join(_arm_lines(r)))
    return 0


def team_compare(args: argparse.Namespace, spec: Any, scene: Any, params: dict[str, Any]) -> int:
    """Every strategy x coordination on the same seeds: the team's violations and each arm's means.

    The episodes run as ``compare``'s do (:func:`~isf_robot.support.parallel.run_tasks` over
    :class:`~isf_robot.arm.compare.EpisodeTask` with its ``coordination``; ``--jobs`` worker processes). On
    Ctrl-C or SIGTERM the episodes that finished are printed, marked partial.
    """
    from isf_robot.arm.compare import EpisodeTask, run_task
    from isf_robot.arm.multi_arm import COORDINATIONS

    ways = [args.coordination] if args.coordination else list(COORDINATIONS)
    obs = make_observer(args, "arm")  # --rrd DIR: a recording per run, <scene>-<strategy>-<coordination>-seed<seed>.rrd
    if obs is not None:
        params = {**params, "observers": [obs]}
    keys = [(s, way) for s in args.filters for way in (ways if s != "nominal" else ways[:1])]
    seeds = range(args.seed, args.seed + args.episodes)
    tasks = [EpisodeTask(spec, s, seed, args.duration, params, "velocity", way) for s, way in keys for seed in seeds]
    done: dict[tuple[str, str, int], dict[str, Any]] = {}

    def keep(n: int, total: int, task: Any, r: dict[str, Any]) -> None:
        done[(task.strategy, task.coordination, task.seed)] = r
        if not args.quiet:
            print(f"[{n}/{total}] {task.strategy} {task.coordination} seed {task.seed}: violations "
                  f"{r['violations']}, min h {format_value(r['min_barrier'])} m, {r['wall_s']:.2f} s",
                  file=sys.stderr, flush=True)

    try:
        run_tasks(run_task, tasks, jobs=int(args.jobs), on_result=keep)
    except Interrupted:
        _print_team(args, scene, keys, seeds, done, partial=True)
        raise
    paths = getattr(obs, "paths", None)
    if paths:
        print(f"recordings: {len(paths)} file(s) in {args.rrd}", file=sys.stderr)
    _print_team(args, scene, keys, seeds, done, partial=False)
    return 0


def _print_team(args: argparse.Namespace, scene: Any, keys: list[tuple[str, str]], seeds: range,
                done: dict[tuple[str, str, int], dict[str, Any]], partial: bool) -> None:
    """The team comparison of the episodes in ``done`` (JSON or text)."""
    from isf_robot.arm.sweep import summarize_arms

    rows: dict[str, Any] = {}
    for strategy, way in keys:
        runs = [done[(strategy, way, seed)] for seed in seeds if (strategy, way, seed) in done]
        if not runs:
            continue
        rows[f"{strategy}/{way}" if strategy != "nominal" else strategy] = {
            "episodes": len(runs),
            "violations": sum(r["violations"] for r in runs),
            "collision_steps": sum(r["collisions"] for r in runs),
            "contacts": {k: sum(r["contacts"][k] for r in runs) for k in runs[0]["contacts"]},
            "min_barrier": min(r["min_barrier"] for r in runs),
            "step_us": float(np.mean([r["wall_s"] / max(1, r["control_steps"]) * 1e6 for r in runs])),
            "arms": summarize_arms(runs, min_off_key="min_off_s"),
        }
    out = {"scene": scene.name, "episodes": args.episodes, "seed0": args.seed, "partial": partial, "results": rows}
    if args.json:
        print(json.dumps(with_schema("isf-robot-compare-team", to_jsonable(out))), flush=True)
        return
    head = "PARTIAL (interrupted; means over the finished episodes) " if partial else ""
    print(f"{head}scene {scene.name}: {args.episodes} episodes from seed {args.seed} (means per arm; violations "
          "summed)")
    for key, row in rows.items():
        print(f"{key}: violations {row['violations']} (collision steps {row['collision_steps']}, contacts "
              f"{row['contacts']}), min barrier {format_value(row['min_barrier'])} m, {row['step_us']:.0f} us/step"
              + (f" ({row['episodes']} episodes)" if partial else ""))
        for a in row["arms"]:
            print(f"  {a['name']:<8} duty {a['duty_cycle']:.3f}  on switches {a['on_switches']:.1f}  min off "
                  f"{format_value(a['min_off_s'])} s  intervention {a['intervention']:.3f}  goals "
                  f"{a['goals_reached']:.1f} (missed {a['goals_missed']:.1f})  coordination "
                  f"{a['coordination_steps']:.0f} steps / {a['coordination_events']:.1f} events", flush=True)


