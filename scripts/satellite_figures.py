"""The paper's satellite figures, regenerated (docs/figures/satellite_*.png, data in satellite_figures.json).

Usage::

    python scripts/satellite_figures.py                 # regenerate the PNGs and the data file
    python scripts/satellite_figures.py --check         # rerun, compare the data (not pixels), write nothing

Figures (valid truth field, the paper's Kepler controller, seed 0, inclination 45 deg, spin on):

* ``satellite_greedy_150h.png`` / ``satellite_maneuver_150h.png``: r(t) with the band [1.6R, 2.4R]
  and Xi(t) with a star at each impulse over the first 150 h (the paper's Fig. 3/4 layout), drawn
  by :func:`isf_robot.plots.satellite_figure`;
* ``satellite_tau.png``: the tau_p data (time from an impulse to the next greedy trigger, every
  sample per radius), medians and the quadratic fit, from the committed tau file
  ``docs/figures/satellite_tau_kepler.json`` (``isf-satellite tau --samples 100``), drawn by
  :func:`isf_robot.plots.tau_figure`;
* ``satellite_inter_event.png``: histogram of the inter-event times of the greedy and the
  maneuver run over ``--hours`` (default 150 h, the figure window), log-spaced bins, with the shortest measured
  interval and the sampled MIET bound.

The data behind them (impulse times and kinds, counts, the histogram, the tau medians and fit)
go to ``satellite_figures.json``; ``--check`` recomputes them and compares with that file:
counts and kinds exactly, times to 1e-6 relative (the runs are deterministic on one machine; a
different BLAS may change the chaotic orbits, which ``--check`` then reports). Needs the
``plots`` extra (matplotlib). About half a CPU-minute.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"
TAU_FILE = FIGURES / "satellite_tau_kepler.json"
DATA_FILE = FIGURES / "satellite_figures.json"
WINDOW_H = 150.0
BINS_H = np.logspace(-3, 2, 41)
"""Histogram bins: 1e-3 h (3.6 s) to 100 h, 8 per decade."""


def _observer_base() -> type:
    from isf_robot.core import Observer

    return Observer


class _Collect(_observer_base()):  # type: ignore[misc]
    """Observer keeping r(t), Xi(t) and the impulses (plain lists)."""

    def __init__(self) -> None:
        self.t: list[float] = []
        self.r: list[float] = []
        self.xi: list[float] = []
        self.events: list[tuple[float, str]] = []

    def on_start(self, info: Any) -> None:
        self.R = float(info["R_m"])

    def on_step(self, s: Any) -> None:
        self.t.append(s.t)
        self.r.append(s.r)
        self.xi.append(s.xi)

    def on_event(self, e: Any) -> None:
        self.events.append((float(e.t), str(e.kind)))



def _run(trigger: str, hours: float, tau_path: Path) -> tuple[_Collect, Any]:
    from satellite.control.tau import load_tau
    from satellite.gravity.fields import load_field
    from satellite.orbit.model import InitialOrbit, OrbitModel
    from satellite.orbit.simulate import simulate

    col = _Collect()
    res = simulate(trigger, hours, initial=InitialOrbit(seed=0, inclination_deg=45.0),
                   model=OrbitModel(load_field("table")), tau=load_tau(tau_path) if trigger == "maneuver" else None,
                   observers=[col], sample_interval_s=120.0, body_mesh=False, contact="count")
    return col, res


def compute(hours: float) -> tuple[dict[str, Any], dict[str, _Collect]]:
    """The figures' data (JSON-ready) and the two runs' samples."""
    from satellite.control.tau import load_tau

    doc: dict[str, Any] = {"settings": {"seed": 0, "inclination_deg": 45.0, "gravity": "table", "hours": hours,
                                        "controller": "kepler", "tau_file": TAU_FILE.relative_to(ROOT).as_posix()},
                           "bins_h": BINS_H.tolist()}
    cols = {}
    for trig in ("greedy", "maneuver"):
        print(f"satellite_figures: {trig} run, {hours:g} h", file=sys.stderr, flush=True)
        col, res = _run(trig, hours, TAU_FILE)
        cols[trig] = col
        t_h = np.array([t for t, _ in col.events]) / 3600.0
        iet = np.diff(t_h)
        doc[trig] = {"triggers": res.triggers, "kinds": res.kinds, "impulse_t_h": t_h.tolist(),
                     "impulse_kind": [k for _, k in col.events], "min_h": res.min_h,
                     "triggers_first_150h": int(np.sum(t_h <= WINDOW_H)),
                     "min_inter_event_h": res.min_inter_event_h, "mean_inter_event_h": res.mean_inter_event_h,
                     "miet_bound_h": res.miet_bound_h, "surface_contacts": (res.contact or {}).get("surface_contacts"),
                     "histogram": np.histogram(iet, BINS_H)[0].tolist()}
    fit = load_tau(TAU_FILE)
    tau_doc = json.loads(TAU_FILE.read_text())
    doc["tau"] = {"radii_over_R": tau_doc["radii_over_R"],
                  "medians_h": np.median(np.asarray(tau_doc["times_h"], float), axis=1).tolist(),
                  "fit_coef_s": list(map(float, fit.coef))}
    return doc, cols


def _series(col: _Collect, trig: str, doc: dict[str, Any]) -> Any:
    from isf_robot.plots import OrbitSeries
    from satellite.orbit.model import BAND_INNER, BAND_OUTER

    t_h = np.asarray(col.t) / 3600.0
    d = doc[trig]
    label = f"{trig}, Kepler controller, exact field, seed 0: {d['triggers_first_150h']} impulses in {WINDOW_H:g} h"
    return OrbitSeries(label, t_h, np.asarray(col.r) / col.R, (BAND_INNER, BAND_OUTER), t_h, np.asarray(col.xi),
                       np.asarray(d["impulse_t_h"]), tuple(d["impulse_kind"]))


def _histogram(doc: dict[str, Any]) -> Any:
    from isf_robot.plots.output import new_figure

    fig = new_figure(7.0, 4.0)
    ax = fig.subplots()
    colors = {"greedy": "#1f77b4", "maneuver": "#d62728"}
    for trig in ("greedy", "maneuver"):
        d = doc[trig]
        ax.stairs(d["histogram"], BINS_H, color=colors[trig], lw=1.5,
                  label=f"{trig}: {d['triggers']} impulses, mean {d['mean_inter_event_h']:.2f} h")
        ax.axvline(d["min_inter_event_h"], color=colors[trig], ls=":", lw=1.0,
                   label=f"{trig}: shortest {d['min_inter_event_h'] * 3600:.0f} s")
    ax.axvline(doc["greedy"]["miet_bound_h"], color="k", ls="--", lw=1.0,
               label=f"sampled MIET bound {doc['greedy']['miet_bound_h'] * 3600:.2g} s")
    ax.set_xscale("log")
    ax.set_xlabel("time between impulses [h]")
    ax.set_ylabel("count")
    ax.set_title(f"inter-event times, seed 0, {doc['settings']['hours']:g} h", fontsize=10, loc="left")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return fig


def _tau_figure() -> Any:
    from isf_robot.plots import TauSamples, tau_figure
    from satellite.control.tau import load_tau
    from satellite.orbit.model import BAND_CENTRE, BAND_INNER, BAND_OUTER

    fit = load_tau(TAU_FILE)
    d = json.loads(TAU_FILE.read_text())
    r = np.linspace(BAND_INNER, BAND_OUTER, 161)
    s = 1.0 - ((r - BAND_CENTRE) / (BAND_OUTER - BAND_CENTRE)) ** 2
    tau_h = np.array([fit.tau_p(float(si) * fit.h_max) for si in s]) / 3600.0
    times = np.asarray(d["times_h"], float)
    label = f"tau_p, exact field, Kepler controller: {times.shape[1]} samples per radius, quadratic fit in h"
    return tau_figure(TauSamples(np.asarray(d["radii_over_R"], float), times, float(d["max_hours"]), r, tau_h,
                                 label=label))


def _diff(old: Any, new: Any, path: str = "") -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        out = [f"{path}/{k}: only in one" for k in set(old) ^ set(new)]
        for k in sorted(set(old) & set(new)):
            out += _diff(old[k], new[k], f"{path}/{k}")
        return out
    if isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            return [f"{path}: length {len(old)} -> {len(new)}"]
        return [m for i, (a, b) in enumerate(zip(old, new)) for m in _diff(a, b, f"{path}[{i}]")][:20]
    if isinstance(old, float) and isinstance(new, float):
        same = math.isclose(old, new, rel_tol=1e-6, abs_tol=1e-12) or (math.isnan(old) and math.isnan(new))
        return [] if same else [f"{path}: {old!r} -> {new!r}"]
    return [] if old == new else [f"{path}: {old!r} -> {new!r}"]


def main(argv: list[str] | None = None) -> int:
    """Regenerate the figures and their data, or (--check) compare the data."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--hours", type=float, default=WINDOW_H, help="length of the two runs (default 150 h)")
    p.add_argument("--check", action="store_true", help="recompute the data and compare with the committed file")
    a = p.parse_args(argv)
    if not (math.isfinite(a.hours) and a.hours >= WINDOW_H):
        p.error(f"--hours must be >= {WINDOW_H:g}")
    doc, cols = compute(a.hours)
    new = json.loads(json.dumps(doc))
    if a.check:
        old = json.loads(DATA_FILE.read_text())
        diffs = _diff(old, new)
        for line in diffs:
            print(f"differs: {line}")
        print("satellite figures data: " + ("differs" if diffs else "identical"))
        return 1 if diffs else 0
    from isf_robot.plots.output import save_figure
    from isf_robot.support.files import write_text_atomic

    FIGURES.mkdir(parents=True, exist_ok=True)
    for trig in ("greedy", "maneuver"):
        from isf_robot.plots import satellite_figure

        save_figure(satellite_figure(_series(cols[trig], trig, doc), WINDOW_H), FIGURES / f"satellite_{trig}_150h.png")
    save_figure(_tau_figure(), FIGURES / "satellite_tau.png")
    save_figure(_histogram(doc), FIGURES / "satellite_inter_event.png")
    write_text_atomic(DATA_FILE, json.dumps(new, indent=1) + "\n")
    print(f"written to {FIGURES.relative_to(ROOT)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
