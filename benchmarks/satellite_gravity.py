"""Satellite gravity models: accuracy against the exact polyhedron field over the band, and speed.

Usage: ``python benchmarks/satellite_gravity.py [--points 300] [--repeats 3] [--table FILE.npz]
[--json FILE.json] [--out BENCHMARKS.md] [--skip-runs]``.

Accuracy (for REPRODUCTION.md, printed as a markdown table and written with ``--json``): at radii
1.6R .. 2.4R (``--points`` random directions each) and at points uniform in the band's volume,
the error of the degree-8 series (``sh8``) and of the default model (``table``) is
``|a_model - a_exact| / |a_exact - a_Kepler|``, a fraction of the non-Kepler part. Points inside
the body (solid angle 4 pi) are reported apart: an orbit there has hit the surface. The
points within 40 m of the surface (Euclidean distance; where the fine boxes correct the shell
table) are also reported apart, and a second sample aimed at the surface near the long-axis tips
gives the error by distance to the surface (0-1, 1-3, 3-10, 10-25, 25-40 m). Needs the shape
file ``../shared/data/itokawa/itokawa_low.obj``.

Speed (the ``<!-- satellite-gravity:start -->`` section of ``--out``): the median cost of one
body-frame acceleration (the integrator's scalar call) for each model, and the median wall and
CPU time of a 2400 h greedy run (seed 0, spin, one process, the CLI's defaults) with ``table`` and
with ``sh8``, alternating, side by side. Target (issue 14): a 2400 h run with the default field in
<= 10 s on one core.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from _common import cpu_model, write_section  # noqa: E402

from satellite.gravity.fields import exact_itokawa, load_field  # noqa: E402
from satellite.gravity.table import GravityTable  # noqa: E402
from satellite.shape.closest import ClosestPoints  # noqa: E402

RADII = (1.6, 1.7, 1.8, 1.9, 2.0, 2.2, 2.4)
START = "<!-- satellite-gravity:start -->"
END = "<!-- satellite-gravity:end -->"


def _stats(e: np.ndarray) -> dict[str, float | int]:
    if e.size == 0:
        return {"n": 0}
    return {"n": int(e.size), "median": float(np.median(e)), "p99": float(np.percentile(e, 99)),
            "max": float(e.max())}


def _pct(d: dict) -> str:  # type: ignore[type-arg]
    if not d["n"]:
        return "-"
    return f"{100 * d['median']:.3g} / {100 * d['p99']:.3g} / {100 * d['max']:.3g} %"


def accuracy(points: int, seed: int, table: GravityTable, exact) -> dict:  # type: ignore[no-untyped-def,type-arg]
    """Errors of sh8 and the table against the exact field (see the module docstring)."""
    sh8 = load_field("sh8")
    R = sh8.r_ref_m
    rng = np.random.default_rng(seed)
    sets = {}
    for k in RADII:
        u = rng.normal(size=(points, 3))
        sets[f"{k}R"] = u / np.linalg.norm(u, axis=1)[:, None] * k * R
    u = rng.normal(size=(5 * points, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    sets["band volume"] = u * np.cbrt(rng.uniform(1.6**3, 2.4**3, len(u)))[:, None] * R
    closest = ClosestPoints(exact.field.vertices, exact.field.faces)
    out: dict[str, dict[str, object]] = {}
    for name, p in sets.items():
        v = exact.field.evaluate(p)
        inside = v.solid_angle > 2 * np.pi
        near = closest.query(p)[1] < 40.0
        kep = -exact.gm * p / (np.linalg.norm(p, axis=1) ** 3)[:, None]
        nk = np.linalg.norm(v.acceleration - kep, axis=1)
        row: dict[str, object] = {"points": len(p), "inside_fraction": float(inside.mean()),
                                  "near_fraction": float((near & ~inside).mean())}
        for mname, model in (("sh8", sh8), ("table", table)):
            e = np.linalg.norm(model.acceleration_batch(p) - v.acceleration, axis=1) / nk
            row[mname] = {"outside": _stats(e[~inside]), "outside_near": _stats(e[~inside & near]),
                          "inside": _stats(e[inside])}
        out[name] = row
    return out


BINS = (0.0, 1.0, 3.0, 10.0, 25.0, 40.0)


def near_surface(points: int, seed: int, table: GravityTable, exact) -> dict:  # type: ignore[no-untyped-def,type-arg]
    """Errors of sh8 and the table at points outside the body near the long-axis tips, by distance to the surface."""
    sh8 = load_field("sh8")
    lo, hi = table.fast_radii
    rng = np.random.default_rng(seed)
    v = exact.field.vertices
    tips = v[np.linalg.norm(v, axis=1) > 1.45 * sh8.r_ref_m]
    closest = ClosestPoints(v, exact.field.faces)
    chosen: list[np.ndarray] = []
    dist: list[np.ndarray] = []
    for d0, d1 in zip(BINS[:-1], BINS[1:]):
        c = tips[rng.integers(len(tips), size=20 * points)]
        u = rng.normal(size=c.shape)
        u /= np.linalg.norm(u, axis=1)[:, None]
        p = c + u * rng.uniform(d0, d1, len(c))[:, None]
        r = np.linalg.norm(p, axis=1)
        p = p[(r >= 1.6 * sh8.r_ref_m) & (r >= lo) & (r <= hi)]
        d = closest.query(p)[1]
        p, d = p[(d >= d0) & (d < d1)], d[(d >= d0) & (d < d1)]
        out_mask = exact.field.evaluate(p[: 2 * points]).solid_angle < 2 * np.pi
        chosen.append(p[: 2 * points][out_mask][:points])
        dist.append(d[: 2 * points][out_mask][:points])
    p, d = np.concatenate(chosen), np.concatenate(dist)
    a = exact.field.acceleration(p)
    nk = np.linalg.norm(a + exact.gm * p / (np.linalg.norm(p, axis=1) ** 3)[:, None], axis=1)
    res: dict[str, dict[str, object]] = {}
    for d0, d1 in zip(BINS[:-1], BINS[1:]):
        m = (d >= d0) & (d < d1)
        res[f"{d0:g}-{d1:g} m"] = {
            name: _stats(np.linalg.norm(model.acceleration_batch(p[m]) - a[m], axis=1) / nk[m])
            for name, model in (("sh8", sh8), ("table", table))}
    return res


def near_table(res: dict) -> str:  # type: ignore[type-arg]
    lines = ["| distance to the surface (points) | sh8: median / p99 / max | table: median / p99 / max |",
             "|---|---|---|"]
    for name, row in res.items():
        lines.append(f"| {name} ({row['table']['n']}) | {_pct(row['sh8'])} | {_pct(row['table'])} |")
    return "\n".join(lines)


def accuracy_table(res: dict) -> str:  # type: ignore[type-arg]
    lines = ["| points | inside body | within 40 m of the surface | sh8: median / p99 / max | "
             "table: median / p99 / max | table within 40 m: max | table inside the body: max |",
             "|---|---|---|---|---|---|---|"]
    def mx(d: dict) -> str:  # type: ignore[type-arg]
        return f"{100 * d['max']:.3g} %" if d["n"] else "-"

    for name, row in res.items():
        t = row["table"]
        lines.append(f"| {name} ({row['points']}) | {100 * row['inside_fraction']:.1f} % | "
                     f"{100 * row['near_fraction']:.1f} % | {_pct(row['sh8']['outside'])} | {_pct(t['outside'])} | "
                     f"{mx(t['outside_near'])} | {mx(t['inside'])} |")
    return "\n".join(lines)


def _per_call_us(model, pts: np.ndarray, repeats: int = 5) -> float:  # type: ignore[no-untyped-def]
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for q in pts:
            model.acceleration(q)
        runs.append((time.perf_counter() - t0) / len(pts) * 1e6)
    return statistics.median(runs)


def speed(table: GravityTable, exact, repeats: int, runs: bool) -> str:  # type: ignore[no-untyped-def]
    from satellite.orbit.model import InitialOrbit, OrbitModel
    from satellite.orbit.simulate import simulate

    sh8 = load_field("sh8")
    R = sh8.r_ref_m
    rng = np.random.default_rng(1)
    u = rng.normal(size=(4000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    band = u * rng.uniform(1.6, 2.4, len(u))[:, None] * R
    in_box = np.zeros(len(band), bool)
    if table.fine is not None:
        in_box = np.abs(table.fine.at_batch(band)).max(axis=1) > 0
    closest = ClosestPoints(exact.field.vertices, exact.field.faces)
    d = closest.query(band)[1]
    close = band[(d < 30.0) & in_box][:200]
    far = band[~in_box][:2000]
    cost = {"sh8 (band)": _per_call_us(sh8, band[:2000]), "table, outside the fine boxes": _per_call_us(table, far),
            "table, within 30 m of the surface (in a fine box)": _per_call_us(table, close),
            "exact polyhedron": _per_call_us(exact, band[:20], 1)}
    lines = ["## Satellite gravity models (`benchmarks/satellite_gravity.py`)", "",
             f"Machine: {platform.platform()}; CPU {cpu_model()}; {os.cpu_count()} cores; Python "
             f"{platform.python_version()}. Date (UTC): {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M}. "
             "BLAS threads pinned to 1.", "",
             "| one body-frame acceleration (scalar call, median of repeats) | us |", "|---|---|"]
    lines += [f"| {k} | {v:.1f} |" for k, v in cost.items()]
    if runs:
        walls: dict[str, list[float]] = {"table": [], "sh8": []}
        cpus: dict[str, list[float]] = {"table": [], "sh8": []}
        res = {}
        for _ in range(repeats):
            for name in walls:
                model = OrbitModel(load_field(name))
                c0 = time.process_time()
                r = simulate("greedy", 2400.0, initial=InitialOrbit(seed=0), model=model, contact="count")
                cpus[name].append(time.process_time() - c0)
                walls[name].append(r.wall_s)
                res[name] = r
        mt, ms = statistics.median(walls["table"]), statistics.median(walls["sh8"])
        lines += ["", "| 2400 h greedy run, seed 0, spin, contact count, one process | target | median wall | "
                  "all repeats [s] | median CPU [s] | RHS evaluations | impulses |", "|---|---|---|---|---|---|---|"]
        for name, med in (("table", mt), ("sh8", ms)):
            lines.append(f"| `--gravity {name}` | {'<= 10 s' if name == 'table' else '-'} | **{med:.2f} s** | "
                         f"{', '.join(f'{w:.2f}' for w in walls[name])} | {statistics.median(cpus[name]):.2f} | "
                         f"{res[name].nfev} | {res[name].triggers} |")
        lines += ["", f"Ratio table / sh8 (median wall): {mt / ms:.2f}; (median CPU): "
                  f"{statistics.median(cpus['table']) / statistics.median(cpus['sh8']):.2f}. Load average at the end "
                  f"(1/5/15 min): {', '.join(f'{v:.2f}' for v in os.getloadavg())} (a shared machine: other jobs may "
                  "run)."]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--table", help="table file (default: the committed one)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", help="write the accuracy results here")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent.parent / "BENCHMARKS.md"))
    ap.add_argument("--skip-accuracy", action="store_true")
    ap.add_argument("--skip-runs", action="store_true", help="no 2400 h runs (per-call costs only)")
    a = ap.parse_args()
    exact = exact_itokawa()
    if exact is None:
        raise SystemExit("needs the shape file ../shared/data/itokawa/itokawa_low.obj")
    table = GravityTable.load(a.table, exact=exact) if a.table else load_field("table")
    if not a.skip_accuracy:
        t0 = time.time()
        res = accuracy(a.points, a.seed, table, exact)
        print(f"accuracy: {time.time() - t0:.0f} s\n" + accuracy_table(res) + "\n", flush=True)
        res_near = near_surface(max(a.points // 3, 20), a.seed + 5, table, exact)
        print("near the surface (tips):\n" + near_table(res_near) + "\n", flush=True)
        if a.json:
            Path(a.json).write_text(json.dumps({"table": str(a.table or "committed"), "grid": table.grid.describe(),
                                                "seed": a.seed, "results": res, "near_surface": res_near}, indent=1)
                                     + "\n", encoding="utf-8")
    body = speed(table, exact, a.repeats, not a.skip_runs)
    write_section(Path(a.out), START, END, body)
    print(body)


if __name__ == "__main__":
    main()
