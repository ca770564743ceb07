"""Randomized stress benchmark of the safety filters on the arm scenes (issue 13), written to RESULTS.md.

    nice -n 19 python benchmarks/stress_bench.py [--episodes 1000] [--duration 3] [--jobs 2]
        [--scenes panda_pole panda_shelf panda_moving panda_servo] [--strategies cbf isf]
        [--seed 0] [--defaults] [--output stress.json] [--no-write] [--marker NAME]
    python benchmarks/stress_bench.py --report stress.json [--no-write] [--marker NAME]

``--episodes`` episodes per strategy, spread evenly over the scenes. Episode ``i`` of a scene is one
random draw (:func:`draw`), from the generator seeded with ``(seed, scene index, i)``, so every strategy
runs on the same perturbed scene, goals, start and obstacle phase (paired), and the same command gives
the same draws. The ranges (:data:`RANGES`):

* every static obstacle (a geom on the world body, or a non-mocap obstacle body) shifted by a uniform
  offset in ``[-0.05, 0.05]^3`` m; every moving obstacle's path shifted likewise;
* every goal shifted by a uniform offset in ``[-0.08, 0.08]^3`` m, on top of the seed's own jitter
  (start ``home + N(0, 0.05^2)`` rad per joint, goals +-3 cm in x and y, a random obstacle phase;
  :func:`~isf_robot.arm.episode.episode_setup`); a draw is drawn again when its start is not safe, or when
  the arm at rest already breaks the robust condition there (:func:`start_slack` < 0: some row has
  ``Lf h - |dh/dx| d_bar + alpha(h) < 0`` with ``u = 0``, e.g. a ball closing in on an arm a millimetre
  outside the margin). From such a start the filter must command an escape at once, which the arm at
  rest cannot follow within ``d_bar``: the tracking bound that Theorem 1 assumes fails from the first
  step, for every filter alike;
* filter parameters: ``alpha`` uniform in [2, 10] 1/s (both strategies, the same value); for isf
  ``c`` in [0.02, 0.15], ``b`` in [0.005, 0.05], ``blend`` in [0, 0.1] s, ``horizon`` in
  [0.1, 0.4] s with probability 3/4 (else no predictive off trigger) and, when there is a horizon,
  ``c_pred`` in [0.005, c] with probability 1/2; ``d_bar`` the scene's calibrated value.

``--defaults``: the same draws (the same generator, so the same offsets, goals and ``alpha``), but the
isf runs with the library's defaults: the scene's ``[filter]`` values for ``c``, ``b`` (and no ``c_pred``),
the hand-over and predictive horizon designed from the scene (:mod:`isf_robot.arm.filter_design`). Only
the scene perturbations and ``alpha`` (both strategies, the same value) are random. Written under the marker
``stress_bench_defaults`` (else ``stress_bench``; ``--marker`` names another).

Below the table, isf against cbf per scene and over all scenes: the ratios of the means (duty,
on-switches, intervention), goals (difference of the means), time to the k-th goal (:func:`goals_time`:
the same k for both strategies of a scene, an episode with fewer arrivals counting its whole duration),
and the isf episodes with an off period under 0.25 s. ``--report PATH`` renders the section again from an
``--output`` file without running anything.

Safety is judged on the true geometry at every physics step (:mod:`isf_robot.arm.monitor`): a
violation is a physics step with some pair's ``distance - margin < 0``. An episode that raises an
:class:`~isf_robot.core.exceptions.IsfError` counts as a failure (kept, with its message). Progress
goes to stderr; Ctrl-C stops the workers and keeps (reports and writes) the finished episodes.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import json
import math
import os
import signal
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import cpu_model, write_section  # noqa: E402

from isf_robot.arm import ArmSimulation, Scene, load_scene  # noqa: E402
from isf_robot.arm.collision import CollisionBarriers  # noqa: E402
from isf_robot.arm.compare import json_safe  # noqa: E402
from isf_robot.arm.episode import EpisodeSetup, episode_setup  # noqa: E402
from isf_robot.arm.joint_limits import JointLimitBarriers  # noqa: E402
from isf_robot.arm.params import resolve_params  # noqa: E402
from isf_robot.arm.sweep import goals_time  # noqa: E402
from isf_robot.core.exceptions import IsfError  # noqa: E402
from isf_robot.core.metrics import CHATTER_OFF_S  # noqa: E402
from isf_robot.core.robust import robust_slack  # noqa: E402
from isf_robot.support.files import write_text_atomic  # noqa: E402
from isf_robot.support.parallel import Interrupted, Terminated, run_tasks  # noqa: E402

SCENES = ("panda_pole", "panda_shelf", "panda_moving", "panda_servo")
RANGES: dict[str, Any] = {
    "obstacle_offset_m": 0.05, "goal_offset_m": 0.08, "alpha": (2.0, 10.0), "c": (0.02, 0.15),
    "b": (0.005, 0.05), "blend": (0.0, 0.1), "horizon": (0.1, 0.4), "p_horizon": 0.75, "c_pred_lo": 0.005,
    "p_c_pred": 0.5,
}
MAX_REDRAWS = 20


def draw(scene: Scene, seed: int, scene_index: int, i: int) -> dict[str, Any]:
    """The random draw of episode ``i`` of a scene: offsets, goals and filter parameters (plain values).

    The isf parameters are drawn in both modes (``--defaults`` ignores them), so both modes draw the
    same offsets, goals and ``alpha`` for an episode.
    """
    rng = np.random.default_rng([seed, scene_index, i])
    r = RANGES
    units = _obstacle_units(scene)
    d: dict[str, Any] = {
        "obstacles": {k: rng.uniform(-r["obstacle_offset_m"], r["obstacle_offset_m"], 3).tolist() for k in units},
        "moving": [rng.uniform(-r["obstacle_offset_m"], r["obstacle_offset_m"], 3).tolist()
                   for _ in scene.config.moving],
        "goals": rng.uniform(-r["goal_offset_m"], r["goal_offset_m"], scene.goal_positions.shape).tolist(),
        "alpha": float(rng.uniform(*r["alpha"])),
    }
    isf = {"c": float(rng.uniform(*r["c"])), "b": float(rng.uniform(*r["b"])),
           "blend": float(rng.uniform(*r["blend"])), "horizon": 0.0}
    if rng.uniform() < r["p_horizon"]:
        isf["horizon"] = float(rng.uniform(*r["horizon"]))
        if rng.uniform() < r["p_c_pred"]:
            isf["c_pred"] = float(rng.uniform(r["c_pred_lo"], isf["c"]))
    d["isf"] = isf
    return d


def _obstacle_units(scene: Scene) -> list[str]:
    """What a draw shifts: ``geom:<id>`` for obstacle geoms on the world body, ``body:<id>`` for other
    static obstacle bodies (mocap bodies move along their paths instead)."""
    m = scene.model
    out: list[str] = []
    for g in scene.obstacle_geom_ids.tolist():
        body = int(m.geom_bodyid[g])
        key = f"geom:{g}" if body == 0 else f"body:{body}"
        if (body == 0 or int(m.body_mocapid[body]) < 0) and key not in out:
            out.append(key)
    return out


def perturbed(scene: Scene, d: dict[str, Any]) -> Scene:
    """``scene`` (freshly loaded: its model is changed in place) with the draw's offsets and goals."""
    m = scene.model
    for key, off in d["obstacles"].items():
        kind, idx = key.split(":")
        arr = m.geom_pos if kind == "geom" else m.body_pos
        arr[int(idx)] += np.asarray(off)
    moving = []
    for mv, off in zip(scene.config.moving, d["moving"]):
        p = mv.path
        shift = np.asarray(off)
        if hasattr(p, "center"):
            p = dataclasses.replace(p, center=tuple((np.asarray(p.center) + shift).tolist()))
        else:
            p = dataclasses.replace(p, start=tuple((np.asarray(p.start) + shift).tolist()),
                                    end=tuple((np.asarray(p.end) + shift).tolist()))
        moving.append(dataclasses.replace(mv, path=p))
    cfg = dataclasses.replace(scene.config, moving=tuple(moving))
    return dataclasses.replace(scene, config=cfg, goal_positions=scene.goal_positions + np.asarray(d["goals"]))


def start_slack(scene: Scene, setup: EpisodeSetup, alpha: float, d_bar: float) -> float:
    """The smallest ``Xi_on`` at the episode's start with the arm at rest (``u = 0``), over every row.

    ``Lf h - |dh/dx| d_bar + alpha h`` (:func:`~isf_robot.core.robust.robust_slack`) of the pairs within the
    cut-off (``Lf h``: the moving obstacles' part of ``dh/dt`` at the start) and the joint limits; ``inf``
    without rows.
    """
    data = mujoco.MjData(scene.model)
    data.qpos[scene.qpos_adr] = setup.q0
    scene.set_moving_obstacles(data, setup.time_offset)
    mujoco.mj_forward(scene.model, data)
    lin = scene.mocap_velocities(setup.time_offset)[0] if len(scene.config.moving) else None
    rows = CollisionBarriers.from_scene(scene).rows(data, JointLimitBarriers.from_scene(scene), lin)
    if not rows.h.size:
        return math.inf
    grad_norm = rows.grad_norm if rows.grad_norm is not None else np.linalg.norm(rows.grad, axis=1)
    lf = rows.lf if rows.lf is not None else np.zeros(rows.h.size)
    return float(np.min(robust_slack(lf, 0.0, grad_norm, d_bar, alpha * rows.h)))


def run_one(task: dict[str, Any]) -> dict[str, Any]:
    """Run one episode (a worker's function); failures are returned, not raised."""
    out: dict[str, Any] = {"scene": task["scene"], "strategy": task["strategy"], "index": task["index"]}
    t0 = time.perf_counter()
    base = load_scene(task["scene"])
    redraws, at_rest, d = 0, 0, None
    for redraws in range(MAX_REDRAWS):  # a draw whose start is not safe (or not robustly so at rest) is drawn again
        d = draw(base, task["seed"], task["scene_index"], task["index"] + 100_000 * redraws)
        scene = perturbed(load_scene(task["scene"]), d)
        try:
            setup = episode_setup(scene, task["index"])
        except IsfError:
            continue
        if start_slack(scene, setup, d["alpha"], task["d_bar"]) >= 0.0:
            break
        at_rest += 1
    else:
        out.update(failure=f"no safe start in {MAX_REDRAWS} draws", wall_s=time.perf_counter() - t0)
        return out
    assert d is not None
    values = dict(d["isf"]) if task["strategy"] == "isf" and not task.get("defaults") else {}
    try:
        params = resolve_params(scene, alpha=d["alpha"], d_bar=task["d_bar"], **values)
        if task["strategy"] == "isf" and task.get("defaults"):  # what the library chose, for the record
            values = {k: getattr(params, k) for k in ("c", "b", "blend", "horizon", "c_pred")}
        res = ArmSimulation(scene, task["strategy"], seed=task["index"], params=params).run(task["duration"])
        out.update(json_safe(res.as_dict()))
        out.pop("timings", None)
    except IsfError as exc:
        out["failure"] = f"{type(exc).__name__}: {exc}".splitlines()[0][:300]
    out.update(redraws=redraws, redraws_at_rest=at_rest, draw={"alpha": d["alpha"], **values},
               wall_s=time.perf_counter() - t0)
    return out


def _fmt(v: float, spec: str) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def summarize(results: list[dict[str, Any]], scenes: list[str], strategies: list[str]) -> list[dict[str, Any]]:
    """One row per scene and strategy (and one over all scenes)."""
    rows = []
    for sc in scenes + ["all"]:
        for st in strategies:
            rs = [r for r in results if r["strategy"] == st and (sc == "all" or r["scene"] == sc)]
            if not rs:
                continue
            ok = [r for r in rs if "failure" not in r]

            def mean(k: str, rows_: list[dict[str, Any]] = ok) -> float:
                vals = [float(r[k]) for r in rows_ if r.get(k) is not None]
                return statistics.fmean(vals) if vals else float("nan")

            offs = [float(r["min_off_s"]) for r in ok if r.get("min_off_s") is not None]
            rows.append({
                "scene": sc, "strategy": st, "episodes": len(rs), "failures": len(rs) - len(ok),
                "violation_episodes": sum(1 for r in ok if int(r["collisions"]) > 0),
                "violation_steps": sum(int(r["collisions"]) for r in ok),
                "min_clearance_m": min((float(r["min_barrier"]) for r in ok), default=float("nan")),
                "duty": mean("duty_cycle"), "switches": mean("on_switches"),
                "min_off_s": min(offs) if offs else float("nan"),
                "goals": mean("goals_reached"), "intervention": mean("intervention"),
                "fallback_episodes": sum(1 for r in ok if int(r["fallbacks"]) > 0),
                "fallback_steps": sum(int(r["fallbacks"]) for r in ok),
                "relaxations": sum(int(r["relaxations"]) for r in ok),
                "d_bar_covered": sum(1 for r in ok if r.get("d_bar_covered")) / max(1, len(ok)),
                "err_q99": mean("tracking_error_q99"), "wall_s": mean("wall_s", rs),
            })
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    head = ("| scene | strategy | episodes | failures | violations (episodes / steps) | min true clearance [m] | "
            "duty | on-switches | shortest off [s] | goals | intervention | fallbacks (episodes / steps) | "
            "relaxations | d_bar covered | err q99 [rad/s] | wall/episode [s] |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['strategy']} | {r['episodes']} | {r['failures']} | {r['violation_episodes']} / "
            f"{r['violation_steps']} | {_fmt(r['min_clearance_m'], '.4f')} | {_fmt(r['duty'], '.3f')} | "
            f"{_fmt(r['switches'], '.2f')} | {_fmt(r['min_off_s'], '.3f')} | {_fmt(r['goals'], '.2f')} | "
            f"{_fmt(r['intervention'], '.3f')} | {r['fallback_episodes']} / {r['fallback_steps']} | "
            f"{r['relaxations']} | {r['d_bar_covered'] * 100:.0f}% | {_fmt(r['err_q99'], '.3f')} | "
            f"{_fmt(r['wall_s'], '.2f')} |")
    return "\n".join(lines)


def ratios(results: list[dict[str, Any]], scenes: list[str], n_goals: dict[str, int]) -> list[dict[str, Any]]:
    """isf against cbf per scene (and ``all``): ratios of the means, goals, time to the k-th goal, short offs.

    The time to the k-th goal is :func:`~isf_robot.arm.sweep.goals_time` over both strategies' episodes of a
    scene (k the same for both); over all scenes, the mean of the scenes' times weighted by episodes.
    """
    out = []
    times: dict[str, dict[str, Any]] = {}
    for sc in scenes:
        pts = [[r for r in results if r["scene"] == sc and r["strategy"] == st and "failure" not in r]
               for st in ("cbf", "isf")]
        if all(pts):
            k, (tc, ti) = goals_time(pts, n_goals.get(sc, 1))
            times[sc] = {"k": k, "cbf": tc["goals_time_s"], "isf": ti["goals_time_s"], "n": len(pts[1])}
    for sc in scenes + ["all"]:
        pts = [[r for r in results if r["strategy"] == st and (sc == "all" or r["scene"] == sc) and "failure" not in r]
               for st in ("cbf", "isf")]
        if not all(pts):
            continue
        cbf, isf = pts

        def m(rows_: list[dict[str, Any]], key: str) -> float:
            return statistics.fmean(float(r[key]) for r in rows_)

        row: dict[str, Any] = {"scene": sc, "episodes": len(isf)}
        for key, name in (("duty_cycle", "duty"), ("on_switches", "switches"), ("intervention", "intervention")):
            a, b = m(isf, key), m(cbf, key)
            row[name] = a / b if b > 0 else float("nan")
        row["goals_isf"], row["goals_cbf"] = m(isf, "goals_reached"), m(cbf, "goals_reached")
        use = [times[s] for s in (scenes if sc == "all" else [sc]) if s in times]
        if use:
            n = sum(t["n"] for t in use)
            tc = sum(t["cbf"] * t["n"] for t in use) / n
            ti = sum(t["isf"] * t["n"] for t in use) / n
            row.update(time_cbf=tc, time_isf=ti, time=ti / tc if tc > 0 else float("nan"),
                       k=use[0]["k"] if len(use) == 1 else None)
        offs = [float(r["min_off_s"]) for r in isf if r.get("min_off_s") is not None]
        row["short_off_episodes"] = sum(1 for v in offs if v < CHATTER_OFF_S)
        row["min_off_s"] = min(offs) if offs else float("nan")
        row["violation_episodes"] = sum(1 for r in isf if int(r["collisions"]) > 0)
        out.append(row)
    return out


def ratio_table(rows: list[dict[str, Any]]) -> str:
    head = ("| scene | isf episodes | duty isf/cbf (target <= 0.6) | on-switches isf/cbf (<= 1.5) | "
            "intervention isf/cbf (<= 1.2) | goals isf vs cbf (>= cbf - 0.1) | time to k-th goal isf/cbf "
            "(<= 1.05) | isf episodes with an off period < 0.25 s (target 0) | isf violation episodes |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        if "time" in r:
            k = f"k = {r['k']}: " if r.get("k") else ""
            t = f"{r['time']:.3f} ({k}{r['time_isf']:.2f} vs {r['time_cbf']:.2f} s)"
        else:
            t = "-"
        lines.append(
            f"| {r['scene']} | {r['episodes']} | {_fmt(r['duty'], '.2f')} | {_fmt(r['switches'], '.2f')} | "
            f"{_fmt(r['intervention'], '.2f')} | {r['goals_isf']:.2f} vs {r['goals_cbf']:.2f} | {t} | "
            f"{r['short_off_episodes']} (shortest {_fmt(r['min_off_s'], '.3f')} s) | {r['violation_episodes']} |")
    return "\n".join(lines)


def _terminated(signum: int, frame: Any) -> None:
    raise Terminated()


def render(payload: dict[str, Any]) -> str:
    """The RESULTS.md section of a run (``payload``: what ``--output`` writes)."""
    a = payload["args"]
    results = payload["episodes"]
    rows = summarize(results, list(a["scenes"]), list(a["strategies"]))
    cmd = ("nice -n 19 python benchmarks/stress_bench.py " + " ".join(
        [f"--episodes {a['episodes']}", f"--duration {a['duration']:g}", f"--jobs {a['jobs']}",
         "--scenes " + " ".join(a["scenes"]), "--strategies " + " ".join(a["strategies"]), f"--seed {a['seed']}"]
        + (["--defaults"] if a.get("defaults") else [])))
    mode = ("isf with the library's defaults (the scene's `[filter]` values, hand-over and horizon designed "
            "from the scene; isf parameters as used: " + "; ".join(
                f"{sc} " + ", ".join(f"{k} {v:g}" for k, v in payload["isf_defaults"][sc].items() if v is not None)
                for sc in a["scenes"] if sc in payload.get("isf_defaults", {})) + ")"
            if a.get("defaults") else "isf parameters drawn at random (ranges: see the script's docstring)")
    body = [
        "", f"`{cmd}`", "",
        f"Started {payload['started']} on {payload['cpu']} ({payload['cpus']} logical CPUs, shared), "
        f"{len(results)} of {payload['tasks']} episodes{' (interrupted: partial)' if payload['partial'] else ''}, "
        f"{a['duration']:g} s each, {payload['wall_s'] / 60:.1f} min wall in all, load average at the end "
        f"{payload['load_end']:.1f}. d_bar per scene (calibrated): "
        + ", ".join(f"{k} {v:.4f}" for k, v in payload["d_bar"].items()) + f" rad/s. Mode: {mode}.",
        "", table(rows), ""]
    at_rest = {sc: sum(r.get("redraws_at_rest", 0) for r in results if r["scene"] == sc and r["strategy"] == st)
               for sc in a["scenes"] for st in a["strategies"][:1]}
    if any(at_rest.values()):
        body += ["Draws made again because the arm at rest broke the robust condition at the start (`start_slack` "
                 "< 0; the same draws for every strategy): " + ", ".join(f"{k} {v}" for k, v in at_rest.items())
                 + ".", ""]
    if "cbf" in a["strategies"] and "isf" in a["strategies"]:
        body += ["isf against cbf on the same draws (means over the episodes; the targets in brackets):", "",
                 ratio_table(ratios(results, list(a["scenes"]), payload.get("n_goals", {}))), ""]
    return "\n".join(body)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=1000, help="episodes per strategy (over all scenes)")
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time per episode [s]")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--strategies", nargs="+", default=["cbf", "isf"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--defaults", action="store_true",
                    help="isf with the library's defaults; only the scene perturbations and alpha are drawn")
    ap.add_argument("--output", type=Path, default=None, help="write every episode's result here (JSON)")
    ap.add_argument("--report", type=Path, default=None, metavar="PATH",
                    help="render the section from an --output file of an earlier run (runs nothing)")
    ap.add_argument("--marker", default=None,
                    help="RESULTS.md section (default stress_bench, with --defaults stress_bench_defaults)")
    ap.add_argument("--no-write", action="store_true", help="do not write RESULTS.md")
    args = ap.parse_args()
    if args.report is not None:
        payload = json.loads(args.report.read_text(encoding="utf-8"))
        _write(payload, args.marker or _marker(payload["args"].get("defaults")), args.no_write)
        return
    # Ctrl-C and SIGTERM stop the batch even when started in the background (where SIGINT is ignored)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _terminated)
    if args.episodes < 1 or not (args.duration > 0) or args.jobs < 1:
        ap.error("--episodes and --jobs must be >= 1 and --duration > 0")
    per_scene = -(-args.episodes // len(args.scenes))
    bases = {sc: load_scene(sc) for sc in args.scenes}
    d_bars = {sc: resolve_params(bases[sc]).d_bar for sc in args.scenes}  # calibrated once per scene
    defaults = {sc: {k: getattr(p, k) for k in ("c", "b", "blend", "horizon", "c_pred")}
                for sc, p in ((sc, resolve_params(bases[sc], d_bar=d_bars[sc])) for sc in args.scenes)}
    tasks = [{"scene": sc, "scene_index": j, "strategy": st, "index": i, "seed": args.seed,
              "duration": args.duration, "d_bar": d_bars[sc], "defaults": args.defaults}
             for i in range(per_scene) for j, sc in enumerate(args.scenes) for st in args.strategies]
    t0 = time.time()
    started = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")

    def progress(done: int, total: int, task: dict[str, Any], r: dict[str, Any]) -> None:
        if "failure" in r:
            msg = f"FAILED {r['failure'][:100]}"
        else:
            msg = (f"viol {r['collisions']}, min h {r['min_barrier']:.4f}, duty {r['duty_cycle']:.3f}, "
                   f"switches {r['on_switches']}, goals {r['goals_reached']}")
        eta = (time.time() - t0) / done * (total - done)
        print(f"[{done}/{total}] {task['scene']} {task['strategy']} #{task['index']}: {msg}, "
              f"{r['wall_s']:.1f} s (eta {eta / 60:.0f} min)", file=sys.stderr, flush=True)

    partial = False
    try:
        done = run_tasks(run_one, tasks, jobs=args.jobs, on_result=progress)
    except Interrupted as exc:
        done, partial = exc.done, True
        print(f"interrupted: keeping {len(done)} finished episode(s)", file=sys.stderr)
    results = [r for _, r in done]
    payload = {
        "schema": "isf-robot-stress/2", "partial": partial, "ranges": RANGES,
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "d_bar": d_bars, "isf_defaults": defaults, "n_goals": {sc: len(b.goal_positions) for sc, b in bases.items()},
        "tasks": len(tasks), "started": started, "cpu": cpu_model(), "cpus": os.cpu_count(),
        "wall_s": time.time() - t0, "load_end": os.getloadavg()[0],
        "summary": summarize(results, list(args.scenes), list(args.strategies)), "episodes": results}
    if args.output is not None:
        write_text_atomic(args.output, json.dumps(json_safe(payload), indent=1))
    _write(payload, args.marker or _marker(args.defaults), args.no_write)
    if partial:
        sys.exit(130)


def _marker(defaults: bool | None) -> str:
    return "stress_bench_defaults" if defaults else "stress_bench"


def _write(payload: dict[str, Any], marker: str, no_write: bool) -> None:
    body = render(payload)
    print(body)
    if not no_write:
        write_section(ROOT / "RESULTS.md", f"<!-- {marker}:start -->", f"<!-- {marker}:end -->", body,
                      write_text_atomic)


if __name__ == "__main__":
    main()
