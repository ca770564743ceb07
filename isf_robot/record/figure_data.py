"""Series for the static figures, read back from recordings (``isf-robot plot``).

Each function returns plain arrays under the field names of the figure series in
:mod:`isf_robot.plots.data` (the command line builds those from them), so this layer depends
on neither matplotlib nor the plots package.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
from rerun.chunk import RrdReader

from .columns import read_columns
from .errors import RecordingReadError
from .replay import RunLog, arm_metrics, replay_metrics
from .schema import command_unit

__all__ = ["arm_series", "satellite_series", "strategy_bars", "run_label", "team_arm_series", "team_bars",
           "team_group"]


def run_label(log: RunLog) -> str:
    """``"<scene> <strategy> seed <seed>"`` (the parts the recording knows)."""
    info = log.info
    parts = [str(info[k]) for k in ("scene", "strategy", "trigger", "coordination") if info.get(k) is not None]
    if info.get("seed") is not None:
        parts.append(f"seed {info['seed']}")
    return " ".join(parts) or log.path.stem


def _recording_index(log: RunLog) -> int:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ids = [e.recording_id for e in RrdReader(log.path).recordings()]
    return ids.index(log.recording_id) if log.recording_id in ids else 0


def _scalars(log: RunLog, entity: str, optional: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``(sim_time [s], value)`` of a one-series ``Scalars`` entity (empty when ``optional`` and absent)."""
    try:
        cols = read_columns(log.path, entity, ["Scalars:scalars"], recording=_recording_index(log))
    except RecordingReadError as exc:
        if optional and "no time-indexed entity" in str(exc):
            return np.zeros(0), np.zeros(0)
        raise
    return np.asarray(cols["sim_time"], dtype=float), np.asarray(cols["Scalars:scalars"], dtype=float).reshape(-1)


def arm_series(log: RunLog) -> dict[str, Any]:
    """Fields of :class:`isf_robot.plots.RunSeries` from an arm recording.

    ``h`` is the logged true-geometry minimum barrier per step, ``correction`` the square root
    of the logged ``|u - u_nom|^2``, ``xi`` the ``/plots/xi/min`` series (absent for strategies
    without an on trigger), ``c`` the run's off margin.
    """
    if log.kind != "arm":
        raise RecordingReadError(log.path, f"recording {log.recording_id!r} is a {log.kind} run, not an arm run")
    s = log.steps
    xi_t, xi = _scalars(log, "/plots/xi/min", optional=True)
    c = log.info.get("c")
    return {
        "label": run_label(log), "strategy": str(log.info.get("strategy", "?")),
        "t": s["t"], "dt": s["dt"], "h": s["min_barrier"], "on": s["on"],
        "correction": np.sqrt(np.asarray(s["intervention_rate"], dtype=float)),
        "xi_t": xi_t, "xi": xi, "c": float(c) if isinstance(c, (int, float)) else float("nan"),
        "unit": command_unit(log.info),
    }



def satellite_series(log: RunLog) -> dict[str, Any]:
    """Fields of :class:`isf_robot.plots.OrbitSeries` from a satellite recording (times in hours)."""
    if log.kind != "satellite":
        raise RecordingReadError(log.path, f"recording {log.recording_id!r} is a {log.kind} run, not a satellite run")
    t, r = _scalars(log, "/plots/radius")
    xt, xi = _scalars(log, "/plots/xi/xi")
    band = log.info.get("band_over_R") or (1.6, 2.4)
    imp = log.impulses
    n = int(imp["t"].size) if "t" in imp else 0
    return {
        "label": f"satellite {run_label(log)}", "t_h": t / 3600.0, "r_over_R": r, "band": tuple(band),
        "xi_t_h": xt / 3600.0, "xi": xi,
        "impulse_t_h": np.asarray(imp["t"], dtype=float) / 3600.0 if n else np.zeros(0),
        "impulse_kind": tuple(str(k) for k in imp["kind"]) if n else (),
    }


def strategy_bars(logs: Sequence[RunLog], order: Sequence[str] = ()) -> list[dict[str, Any]]:
    """Fields of :class:`isf_robot.plots.StrategyBars` per strategy, from the replayed metrics of each episode.

    Args:
        logs: Arm recordings (any number of strategies and seeds).
        order: Strategies first in this order; others follow in order of appearance.

    """
    groups: dict[str, list[dict[str, Any]]] = {}
    for log in logs:
        groups.setdefault(str(log.info.get("strategy", "?")), []).append(replay_metrics(log))
    names = [n for n in order if n in groups] + [n for n in groups if n not in order]
    out = []
    for name in names:
        ms = groups[name]
        out.append({"strategy": name, **{k: np.array([float(m[k]) if m.get(k) is not None else np.nan for m in ms])
                                         for k in ("duty_cycle", "on_switches", "intervention", "min_barrier")}})
    return out


def team_group(log: RunLog) -> str:
    """``<strategy>/<coordination>`` of a team recording (``nominal`` alone: it filters nothing)."""
    strategy = str(log.info.get("strategy", "?"))
    way = log.info.get("coordination")
    return strategy if strategy == "nominal" or way is None else f"{strategy}/{way}"


def team_arm_series(log: RunLog) -> list[dict[str, Any]]:
    """Fields of :class:`isf_robot.plots.RunSeries` per arm of a team recording (:attr:`RunLog.arms`).

    Per arm: ``h`` the smallest barrier of the arm's pairs at each tick, ``on`` its own filter's mode,
    ``correction`` ``|u_i - u_nom,i|`` (the square root of its logged ``intervention_rate``).
    """
    if not log.arms:
        raise RecordingReadError(log.path, f"recording {log.recording_id!r} is not a team run (no per-arm columns)")
    out = []
    for name, a in log.arms.items():
        out.append({"label": f"{run_label(log)} {name}", "strategy": str(log.info.get("strategy", "?")),
                    "t": a["t"], "dt": a["dt"], "h": a["min_barrier"], "on": a["on"],
                    "correction": np.sqrt(np.asarray(a["intervention_rate"], dtype=float))})
    return out


def team_bars(logs: Sequence[RunLog], order: Sequence[str] = ()) -> list[dict[str, Any]]:
    """Fields of :class:`isf_robot.plots.TeamBars` per way of filtering (:func:`team_group`).

    Each episode's per-arm figures are replayed from its recording (:func:`~isf_robot.record.replay.arm_metrics`).

    Args:
        logs: Team recordings of one scene (any strategies, coordinations and seeds).
        order: Strategies first in this order, central before decentral; others follow in order of appearance.

    """
    groups: dict[str, list[list[dict[str, Any]]]] = {}
    arms: dict[str, tuple[str, ...]] = {}
    for log in logs:
        g = team_group(log)
        m = arm_metrics(log)
        groups.setdefault(g, []).append(m)
        arms.setdefault(g, tuple(a["name"] for a in m))
    rank = {s: i for i, s in enumerate(order)}
    ways = {"central": 0, "decentral": 1}
    seen = list(groups)
    names = sorted(groups, key=lambda g: (rank.get(g.split("/")[0], len(rank)),
                                          ways.get(g.partition("/")[2], len(ways)), seen.index(g)))
    out = []
    for g in names:
        eps = groups[g]
        out.append({"group": g, "arms": arms[g], **{
            k: np.array([[float(a[k]) if a.get(k) is not None else np.nan for a in ep] for ep in eps])
            for k in ("duty_cycle", "on_switches", "intervention", "min_off_s")}})
    return out
