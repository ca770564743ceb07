"""Satellite benchmark: 2400 h greedy run and the default tau data collection.

Usage: ``python benchmarks/satellite_bench.py [--repeats 5] [--tau-repeats 3] [--out BENCHMARKS.md]``.

Targets (issue 9): a 2400 h greedy run with the degree-8 field and spin in under 10 s on one
core; the default tau collection (100 samples x 17 radii) in under 2 minutes on 2 cores.
Medians of repeated runs are reported. Only the section between the
``<!-- satellite-bench:start -->`` and ``<!-- satellite-bench:end -->`` markers of the output
file is rewritten (the file is created if absent).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from _common import cpu_model, write_section  # noqa: E402  (benchmarks/ is on sys.path when run as a script)

from satellite.model import InitialOrbit, OrbitModel  # noqa: E402
from satellite.simulate import simulate  # noqa: E402
from satellite.tau import collect_tau, fit_tau  # noqa: E402

START = "<!-- satellite-bench:start -->"
END = "<!-- satellite-bench:end -->"




def bench(repeats: int, tau_repeats: int, workers: int) -> str:
    model = OrbitModel()
    greedy = []
    for _ in range(repeats):
        res = simulate("greedy", 2400.0, initial=InitialOrbit(seed=0), model=model)
        greedy.append(res)
    g_wall = [r.wall_s for r in greedy]
    taus = []
    for _ in range(tau_repeats):
        t0 = time.perf_counter()
        data = collect_tau(100, workers=workers)
        taus.append(time.perf_counter() - t0)
    fit = fit_tau(data, model.h_max, model.R)
    tp = fit.describe()
    man = []
    for _ in range(repeats):
        man.append(simulate("maneuver", 2400.0, initial=InitialOrbit(seed=0), model=model, tau=fit))
    m_wall = [r.wall_s for r in man]
    g = greedy[0]
    m = man[0]
    lines = [
        "## Satellite (`benchmarks/satellite_bench.py`)",
        "",
        f"Machine: {platform.platform()}; CPU {cpu_model()}; {os.cpu_count()} cores; Python "
        f"{platform.python_version()}. Date (UTC): {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M}.",
        "BLAS threads pinned to 1. Wall times are medians of the repeats listed. Load average at the end "
        f"(1/5/15 min): {', '.join(f'{v:.2f}' for v in os.getloadavg())} (a shared machine: other jobs may run).",
        "",
        "| case | target | median wall | all repeats [s] | result |",
        "|---|---|---|---|---|",
        f"| 2400 h greedy run, degree-8 field, spin, seed 0, one process | < 10 s | "
        f"**{statistics.median(g_wall):.2f} s** | {', '.join(f'{w:.2f}' for w in g_wall)} | "
        f"{g.triggers} impulses, {g.nfev} RHS evaluations, min h {g.min_h:.0f} m^2 |",
        f"| default tau collection (100 samples x 17 radii), {workers} processes | < 120 s | "
        f"**{statistics.median(taus):.1f} s** | {', '.join(f'{w:.1f}' for w in taus)} | "
        f"fit coefficients (s) {', '.join(f'{c:.4g}' for c in tp['coef_s'])} |",
        f"| 2400 h maneuver run (that fit), seed 0, one process | - | "
        f"**{statistics.median(m_wall):.2f} s** | {', '.join(f'{w:.2f}' for w in m_wall)} | "
        f"{m.triggers} impulses {m.kinds} |",
        "",
        f"Per RHS evaluation (greedy run, whole loop included): {1e6 * statistics.median(g_wall) / g.nfev:.1f} us.",
    ]
    return "\n".join(lines)




def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--tau-repeats", type=int, default=3)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--out", default=str(Path(__file__).resolve().parent.parent / "BENCHMARKS.md"))
    a = p.parse_args()
    body = bench(a.repeats, a.tau_repeats, a.workers)
    write_section(Path(a.out), START, END, body)
    print(body)


if __name__ == "__main__":
    main()
