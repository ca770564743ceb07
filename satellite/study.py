"""Greedy versus maneuver triggers on the same initial orbits (the paper's comparison, repeated).

Run as ``python -m satellite.study --tau FILE.json --seeds 10 --hours 2400 --out FILE.json``.
Every seed gives one initial orbit (:class:`satellite.model.InitialOrbit`); both triggers start
from it. Surface contact is counted in every run (``contact="count"``: the orbit is unchanged,
passes through the shape are reported per row). ``--rtol-check`` adds a second greedy run with a
tighter tolerance (1e-11), whose
difference from the first measures how much of a count difference is numerical (the orbits are
chaotic; any change of the integration path changes the trigger sequence).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from satellite.controller import ControlParams
from satellite.fields import DEFAULT_GRAVITY, load_field
from satellite.files import write_text_atomic
from satellite.model import InitialOrbit, OrbitModel
from satellite.simulate import IntegratorSettings, simulate
from satellite.tau import load_tau
from satellite.triggers import Trigger

__all__ = ["compare", "main"]


def _one(args: tuple[Any, ...]) -> dict[str, Any]:
    trigger, seed, hours, tau_path, spin, scale, alpha_gain, inclination, rtol, gravity = args
    tau = load_tau(tau_path) if trigger.needs_tau else None
    res = simulate(
        trigger, hours, initial=InitialOrbit(seed=seed, inclination_deg=inclination),
        model=OrbitModel(load_field(gravity), spin=spin, disturbance_scale=scale),
        control=ControlParams(alpha_gain=alpha_gain),
        tau=tau, integrator=IntegratorSettings(rtol=rtol), miet_samples=200, contact="count",
    )
    out = res.summary()
    out.pop("settings")
    out["rtol"] = rtol
    return out


def compare(
    seeds: Sequence[int],
    hours: float,
    tau_path: str,
    *,
    spin: bool = True,
    disturbance_scale: float = 1.0,
    alpha_gain: float | None = None,
    inclination_deg: float = 45.0,
    rtol_check: bool = False,
    workers: int | None = None,
    gravity: str = "sh8",
) -> dict[str, Any]:
    """Run greedy and maneuver triggers from the same initial orbits.

    Returns:
        JSON-ready dict: ``rows`` (one per seed with both counts), ``reduction`` statistics
        (``1 - maneuver / greedy``: mean, sample standard deviation, min, max, count of seeds with
        fewer maneuver triggers) and the settings.

    """
    jobs = []
    for s in seeds:
        runs = ((Trigger.GREEDY, 1e-10), (Trigger.MANEUVER, 1e-10)) + (((Trigger.GREEDY, 1e-11),) if rtol_check else ())
        for trig, rtol in runs:
            jobs.append(
                (trig, int(s), float(hours), tau_path, spin, disturbance_scale, alpha_gain, inclination_deg, rtol,
                 gravity)
            )
    with ProcessPoolExecutor(max_workers=workers or os.cpu_count() or 1) as pool:
        results = list(pool.map(_one, jobs))
    rows = []
    for s in seeds:
        mine = [r for r in results if r["seed"] == s]
        g = next(r for r in mine if r["trigger"] is Trigger.GREEDY and r["rtol"] == 1e-10)
        m = next(r for r in mine if r["trigger"] is Trigger.MANEUVER)
        row = {
            "seed": s,
            "greedy": g["triggers"],
            "maneuver": m["triggers"],
            "maneuver_kinds": m["kinds"],
            "reduction": 1.0 - m["triggers"] / g["triggers"] if g["triggers"] else math.nan,
            "greedy_min_h": g["min_h"],
            "maneuver_min_h": m["min_h"],
            "greedy_r_range": [g["r_min_over_R"], g["r_max_over_R"]],
            "maneuver_r_range": [m["r_min_over_R"], m["r_max_over_R"]],
            "greedy_dv": g["total_dv"],
            "maneuver_dv": m["total_dv"],
            "greedy_wall_s": g["wall_s"],
            "maneuver_wall_s": m["wall_s"],
            "greedy_surface_contacts": g.get("surface_contacts"),
            "maneuver_surface_contacts": m.get("surface_contacts"),
            "greedy_min_clearance_m": g.get("min_pass_clearance_m"),
            "maneuver_min_clearance_m": m.get("min_pass_clearance_m"),
        }
        tight = [r for r in mine if r["trigger"] is Trigger.GREEDY and r["rtol"] == 1e-11]
        if tight:
            row["greedy_rtol1e-11"] = tight[0]["triggers"]
        rows.append(row)
    red = np.array([r["reduction"] for r in rows])
    out: dict[str, Any] = {
        "hours": hours,
        "tau": tau_path,
        "spin": spin,
        "disturbance_scale": disturbance_scale,
        "gravity": gravity,
        "alpha_gain": alpha_gain,
        "inclination_deg": inclination_deg,
        "rows": rows,
        "reduction": {
            "mean": float(red.mean()),
            "std": float(red.std(ddof=1)) if red.size > 1 else 0.0,
            "min": float(red.min()),
            "max": float(red.max()),
            "seeds_with_fewer_maneuver_triggers": int(np.sum(red > 0)),
            "seeds": len(rows),
        },
    }
    if rtol_check:
        noise = np.array([1.0 - r["greedy_rtol1e-11"] / r["greedy"] for r in rows])
        sd = float(noise.std(ddof=1)) if noise.size > 1 else 0.0
        out["greedy_rtol_noise"] = {"mean": float(noise.mean()), "std": sd}
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command line of the study (``python -m satellite.study``)."""
    p = argparse.ArgumentParser(prog="python -m satellite.study", description=__doc__.splitlines()[0])
    p.add_argument("--tau", required=True, help="tau file from `isf-satellite tau`")
    p.add_argument("--seeds", type=int, default=10, help="number of initial orbits (seeds 0..N-1)")
    p.add_argument("--hours", type=float, default=2400.0)
    p.add_argument("--no-spin", action="store_true")
    p.add_argument("--disturbance-scale", type=float, default=1.0)
    p.add_argument("--alpha-gain", type=float, default=None)
    p.add_argument("--inclination", type=float, default=45.0)
    p.add_argument("--rtol-check", action="store_true")
    p.add_argument("--workers", type=int, default=None)
    p.add_argument("--gravity", default=DEFAULT_GRAVITY, help="truth gravity model (default: table)")
    p.add_argument("--out", required=True)
    a = p.parse_args(argv)
    load_tau(a.tau)
    load_field(a.gravity)
    res = compare(
        list(range(a.seeds)), a.hours, a.tau, spin=not a.no_spin, disturbance_scale=a.disturbance_scale,
        alpha_gain=a.alpha_gain, inclination_deg=a.inclination, rtol_check=a.rtol_check, workers=a.workers,
        gravity=a.gravity,
    )
    write_text_atomic(a.out, json.dumps(res, indent=1) + "\n")
    sys.stdout.write(json.dumps(res["reduction"]) + "\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
