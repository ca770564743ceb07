"""``isf-robot plot``: static figures (PNG, SVG or PDF) from recordings or a tau file.

What is drawn follows from the inputs:

* one arm recording (``run --rrd``): ``min h`` over time with the on-intervals shaded, ``min
  Xi_on`` with the thresholds 0 and ``c``, and ``|u - u_nom|``;
* several arm recordings or a ``compare --rrd`` directory: ``min h`` over time per strategy
  (the lowest seed of each) above bars of duty cycle, on switches, intervention and ``min h``
  per strategy (mean, whiskers over the episodes);
* a satellite recording (``isf-satellite run --rrd``): ``r/R`` in the band and ``Xi`` with a
  star at each trigger over the first ``--hours`` (150, as in the paper);
* a tau file (``isf-satellite tau --out``): the samples, medians and the fitted ``tau_p``;
* a sweep file (``isf-robot sweep --output``): duty cycle vs intervention per scene, the Pareto
  front marked, cbf as the reference;
* a team recording (a scene with several arms, ``run --rrd``): the team's ``min h`` above a row per
  arm (the smallest barrier of its pairs with its own on-intervals shaded, ``|u_i - u_nom,i|``);
* several team recordings (``compare --rrd DIR`` on a team scene) or a team's ``compare --json``
  output: grouped bars of each arm's duty cycle, on switches, intervention and shortest off period
  per way of filtering (``isf/central``, ``isf/decentral``, ...).

matplotlib is the optional ``plots`` extra; without it the command says which extra to install.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from isf_robot.core import ConfigError

__all__ = ["register", "handle"]


def register(sub: Any) -> None:
    """Register ``plot`` on the ``isf-robot`` subparsers."""
    p = sub.add_parser(
        "plot", help="static figures (PNG/SVG/PDF) of recordings or a tau file (needs the 'plots' extra)",
        description="Draw a run (one arm recording), a comparison (several arm recordings or a "
                    "`compare --rrd` directory), a satellite run (its recording) or a tau file "
                    "(`isf-satellite tau --out`) with matplotlib.")
    p.add_argument("inputs", nargs="+", type=Path, metavar="INPUT",
                   help=".rrd recordings, directories of them, or one tau, sweep or team compare .json file")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="PATH",
                   help="figure file: .png, .svg or .pdf")
    p.add_argument("--hours", type=float, default=150.0,
                   help="satellite run: hours drawn from the start (default 150, as in the paper)")
    p.add_argument("--title", default=None, help="comparison: figure title (default: the scene)")
    p.set_defaults(handler=handle)


def handle(args: argparse.Namespace) -> int:
    """Check the output and matplotlib, read the inputs, draw, write atomically."""
    from isf_robot.plots import check_figure_path, require_matplotlib, save_figure

    check_figure_path(args.output)
    require_matplotlib()
    if not (math.isfinite(args.hours) and args.hours > 0):
        raise ConfigError(f"--hours must be a positive number, got {args.hours:g}")
    if any(p.suffix.lower() == ".json" for p in args.inputs):
        if len(args.inputs) != 1:
            raise ConfigError("a tau, sweep or team compare file is drawn alone: give one .json file, or .rrd "
                          "recordings")
        fig, what = _json(args.inputs[0])
    else:
        fig, what = _recordings(args)
    save_figure(fig, args.output)
    print(f"wrote {args.output}: {what}", file=sys.stderr)
    return 0


def _recordings(args: argparse.Namespace) -> tuple[Any, str]:
    from isf_robot.core.strategies import strategy_names
    from isf_robot.plots import OrbitSeries, RunSeries, StrategyBars, compare_figure, run_figure, satellite_figure
    from isf_robot.record.figure_data import arm_series, satellite_series, strategy_bars
    from isf_robot.record.replay import read_many
    from isf_robot.record.schema import run_level

    logs = read_many(args.inputs)
    kinds = sorted({log.kind for log in logs})
    if len(kinds) > 1:
        raise ConfigError(f"the inputs mix {' and '.join(kinds)} recordings; plot one kind at a time")
    kind = kinds[0]
    if kind == "satellite":
        if len(logs) > 1:
            raise ConfigError(f"one satellite recording at a time, got {len(logs)}")
        orbit = OrbitSeries(**satellite_series(logs[0]))
        return satellite_figure(orbit, args.hours), f"satellite run ({orbit.impulse_t_h.size} impulses in all)"
    if kind != "arm":
        raise ConfigError(f"cannot plot a {kind!r} recording; valid: arm or satellite recordings, or a tau file")
    teams = [log for log in logs if log.arms]
    if teams and len(teams) != len(logs):
        raise ConfigError(f"the inputs mix {len(teams)} team recording(s) (several arms) with {len(logs) - len(teams)} "
                          "of one arm; plot one kind at a time")
    if teams:
        return _team_recordings(args, logs)
    levels = sorted({run_level(log.info) for log in logs})
    if len(levels) > 1:
        raise ConfigError(f"the inputs mix {' and '.join(levels)}-level recordings (their commands, duty and "
                          "intervention are not comparable in one bar); plot one level at a time")
    if len(logs) == 1:
        run = RunSeries(**arm_series(logs[0]))
        return run_figure(run), f"run {run.label}"
    firsts: dict[str, Any] = {}
    for log in sorted(logs, key=lambda lg: int(lg.info.get("seed") or 0)):
        firsts.setdefault(str(log.info.get("strategy", "?")), log)
    bars = [StrategyBars(**b) for b in strategy_bars(logs, strategy_names())]
    runs = [RunSeries(**arm_series(firsts[b.strategy])) for b in bars]
    scenes = sorted({str(log.info.get("scene", "?")) for log in logs})
    title = args.title if args.title is not None else f"scene {', '.join(scenes)}"
    return compare_figure(runs, bars, title), f"comparison of {len(bars)} strategies over {len(logs)} recordings"


def _team_recordings(args: argparse.Namespace, logs: list[Any]) -> tuple[Any, str]:
    """One team recording: a row per arm; several: each arm's figures per way of filtering."""
    from isf_robot.core.strategies import strategy_names
    from isf_robot.plots import RunSeries, TeamBars, team_compare_figure, team_run_figure
    from isf_robot.record.figure_data import arm_series, team_arm_series, team_bars

    if len(logs) == 1:
        log = logs[0]
        team = RunSeries(**{**arm_series(log), "xi_t": np.zeros(0), "xi": np.zeros(0)})
        arms = [RunSeries(**a) for a in team_arm_series(log)]
        return team_run_figure(team, arms, list(log.arms)), f"team run {team.label}, {len(arms)} arms"
    scenes = sorted({str(log.info.get("scene", "?")) for log in logs})
    if len(scenes) > 1:
        raise ConfigError(f"team recordings of one scene at a time, got {', '.join(scenes)}")
    bars = [TeamBars(**b) for b in team_bars(logs, strategy_names())]
    title = args.title if args.title is not None else f"scene {scenes[0]}, per arm"
    return team_compare_figure(bars, title), (f"per-arm comparison of {len(bars)} way(s) of filtering over "
                                              f"{len(logs)} recordings")


def _team_compare(doc: dict[str, Any], path: Path) -> tuple[Any, str]:
    """The output of ``compare --json`` on a team scene: each arm's means per way of filtering."""
    from isf_robot.plots import TeamBars, team_compare_figure

    try:
        bars = []
        for group, row in doc["results"].items():
            arms = row["arms"]
            bars.append(TeamBars(group, tuple(str(a["name"]) for a in arms), **{
                k: np.array([[np.nan if a.get(k) is None else float(a[k]) for a in arms]])
                for k in TeamBars.FIELDS}))
        title = f"scene {doc['scene']}, per arm (means over {int(doc['episodes'])} episode(s))"
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise ConfigError(f"{path}: not the output of `isf-robot compare --json` on a team scene ({exc})") from None
    return team_compare_figure(bars, title), f"per-arm comparison of {len(bars)} way(s) of filtering"


def _json(path: Path) -> tuple[Any, str]:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: cannot read JSON ({exc})") from None
    if isinstance(doc, dict) and str(doc.get("schema", "")).startswith("isf-robot-sweep/"):
        return sweep_figure(doc)
    if isinstance(doc, dict) and str(doc.get("schema", "")).startswith("isf-robot-compare-team/"):
        return _team_compare(doc, path)
    return _tau(path)


def sweep_figure(doc: Any) -> tuple[Any, str]:
    """The Pareto figure of a sweep document, and what it shows."""
    from isf_robot.plots import pareto_figure, sweep_scenes

    scenes = sweep_scenes(doc)
    n = sum(len(v) for v in scenes.values())
    return pareto_figure(scenes), f"Pareto figure, {n} points of {len(scenes)} scene(s)"


def _tau(path: Path) -> tuple[Any, str]:
    from isf_robot.plots import TauSamples, tau_figure
    from satellite.control.tau import load_tau
    from satellite.orbit.model import BAND_CENTRE, BAND_INNER, BAND_OUTER

    fit = load_tau(path)  # checks the format and the fit, one-line errors
    doc = json.loads(path.read_text(encoding="utf-8"))
    try:
        radii = np.asarray(doc["radii_over_R"], dtype=float)
        times = np.asarray(doc["times_h"], dtype=float)
        max_hours = float(doc["max_hours"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"{path}: tau file lacks its samples (radii_over_R, times_h, max_hours): {exc}") from None
    r = np.linspace(BAND_INNER, BAND_OUTER, 161)
    s = 1.0 - ((r - BAND_CENTRE) / (BAND_OUTER - BAND_CENTRE)) ** 2  # h / h_max of the band barrier
    tau_h = np.array([fit.tau_p(float(si) * fit.h_max) for si in s]) / 3600.0
    n = times.shape[1] if times.ndim == 2 else 0
    label = f"time to trigger, {n} samples per radius, fit of degree {len(fit.coef) - 1} in h"
    tau = TauSamples(radii, times, max_hours, r, tau_h, label=label)
    return tau_figure(tau), f"tau data of {radii.size} radii"
