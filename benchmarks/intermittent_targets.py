"""The intermittent filter's targets: isf against cbf with the library's defaults, on the same seeds.

    nice -n 19 python benchmarks/intermittent_targets.py [--episodes 20] [--jobs 2] \
        [--scenes panda_pole panda_shelf panda_moving panda_servo ur5e_pole] [--json sweep.json] \
        [--backend processes|ray] [--marker intermittent_targets] [--no-write] [--shoot S]
    nice -n 19 python benchmarks/intermittent_targets.py --vendor [--episodes 20] [--jobs 2] [--no-write]

Runs ``cbf`` and ``isf`` with every scene's shipped parameters (no scene sets the intermittent
options: the hand-over and the predictive horizon are designed from the scene,
:mod:`isf_robot.arm.filter_design`; ``d_bar`` as the scene resolves it: config or the tracking
calibration) on seeds 0..N-1 at the scene's full episode length, through
:func:`isf_robot.arm.sweep.run_sweep`, and writes one table per target into RESULTS.md between
the ``<!-- MARKER:start -->`` / ``<!-- MARKER:end -->`` markers (``--no-write``: print only).
``--json`` also writes the whole sweep (every episode) for ``isf-robot plot pareto``.
``--shoot S``: the isf runs with maneuvers by shooting over ``S`` seconds (:mod:`isf_robot.core.shooting`),
written under the marker ``shooting_targets`` unless ``--marker`` names another.
``--vendor``: instead of the shipped scenes, the arms written here the way vendors ship them
(:data:`VENDOR`, ``benchmarks/vendor_arms/``: collision meshes, position servos or torque motors, joint
friction and armature; each config is what ``isf-robot init`` writes, with no ``[filter]``), written
under the marker ``intermittent_targets_vendor`` unless ``--marker`` names another.

Targets: duty <= 0.6x cbf; on-switches <= 1.5x cbf; shortest off period >= 0.25 s in every
episode; goals >= cbf's (mean, within 0.1); time to the goals <= cbf's + 5 % (the sweep's
``goals_time_s``, defined in :mod:`isf_robot.arm.sweep`); intervention <= 1.2x cbf; zero
violations on the true geometry; tracking error q99 <= the d_bar in use in every episode.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import cpu_model, write_section  # noqa: E402

from isf_robot.arm.compare import SceneSpec  # noqa: E402
from isf_robot.arm.sweep import SweepPoint, format_sweep, run_sweep  # noqa: E402
from isf_robot.support.files import write_text_atomic  # noqa: E402
from isf_robot.support.report import with_schema  # noqa: E402

SCENES = ("panda_pole", "panda_shelf", "panda_moving", "panda_servo", "ur5e_pole")
VENDOR_DIR = ROOT / "benchmarks" / "vendor_arms"
VENDOR = ("vendor_panda_servo", "vendor_panda_position", "vendor_ur5e_torque")
"""The vendor-style arms of ``--vendor``: ``VENDOR_DIR/<name>.xml`` and ``.toml``."""


def vendor_specs(names: list[str] | tuple[str, ...] = VENDOR) -> list[SceneSpec]:
    """The :class:`SceneSpec` of each vendor-style arm (by file, in any process)."""
    return [SceneSpec(model=str(VENDOR_DIR / f"{n}.xml"), config=str(VENDOR_DIR / f"{n}.toml")) for n in names]


def _f(v: Any, fmt: str = ".3f") -> str:
    return "-" if v is None else format(v, fmt)


def targets(cbf: dict[str, Any], isf: dict[str, Any], k: Any = "?") -> list[tuple[str, str, bool | None]]:
    """``(target, figure, met)`` rows for one scene (met ``None``: not measurable)."""
    out: list[tuple[str, str, bool | None]] = []

    def ratio(key: str, limit: float, name: str) -> None:
        a, b = isf.get(key), cbf.get(key)
        if a is None or not b:
            out.append((name, f"isf {_f(a)}, cbf {_f(b)}", None))
            return
        r = a / b
        met = r <= limit
        how = "met" if met else f"missed by {r - limit:.2f}"
        out.append((name, f"{r:.2f}x ({_f(a)} vs {_f(b)}), {how}", met))

    ratio("duty_cycle", 0.6, "duty <= 0.6x cbf")
    ratio("on_switches", 1.5, "on-switches <= 1.5x cbf")
    offs = [r["min_off_s"] for r in isf["runs"] if r.get("min_off_s") is not None]
    short = min(offs) if offs else None
    met = short is None or short >= 0.25
    n_short = sum(1 for v in offs if v < 0.25)
    out.append(("shortest off period >= 0.25 s in every episode",
                "no complete off period" if short is None else
                f"{short:.3f} s, " + ("met" if met else f"missed by {0.25 - short:.3f} s "
                                      f"({n_short} of {len(isf['runs'])} episodes below)"), met))
    g_i, g_c = isf["goals_reached"], cbf["goals_reached"]
    met = g_i >= g_c - 0.1
    t_i, t_c = isf.get("goals_time_s"), cbf.get("goals_time_s")
    times = "" if t_i is None else f"; time to goal {k}: {_f(t_i, '.2f')} vs {_f(t_c, '.2f')} s"
    out.append(("goals >= cbf's (within 0.1)",
                f"{g_i:.2f} vs {g_c:.2f}, " + ("met" if met else f"missed by {g_c - 0.1 - g_i:.2f}") + times, met))
    ratio("goals_time_s", 1.05, "time to the goals <= cbf's + 5 %")  # (always a row: the table is by position)
    ratio("intervention", 1.2, "intervention <= 1.2x cbf")
    v = isf["violations"]
    out.append(("zero violations (true geometry)", f"{v} (cbf {cbf['violations']}), " + ("met" if v == 0 else "missed"),
                v == 0))
    runs = isf["runs"]
    cov = sum(1 for r in runs if r["d_bar_covered"])
    worst = max(runs, key=lambda r: r["tracking_error_q99"] / r["d_bar"])
    cbf_cov = sum(1 for r in cbf["runs"] if r["d_bar_covered"])
    out.append(("tracking error q99 <= d_bar", f"{cov} of {len(runs)} episodes (worst {worst['tracking_error_q99']:.3f}"
                f" vs {worst['d_bar']:.3f}), " + ("met" if cov == len(runs) else "missed")
                + f"; cbf {cbf_cov} of {len(cbf['runs'])}", cov == len(runs)))
    return out


def report(sweep: dict[str, Any], command: str, load: tuple[float, float, float], wall: float,
           params: str = "shipped parameters") -> str:
    """The RESULTS.md section: the sweep tables and the targets table (``params``: what the scenes ran with)."""
    per = {}
    for sc in sweep["scenes"]:
        rows = {r["strategy"]: r for r in sc["points"]}
        if "cbf" in rows and "isf" in rows:
            per[sc["scene"]] = targets(rows["cbf"], rows["isf"], sc.get("goals_time_k", "?"))
    names = list(per)
    when = (f"Measured {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC on {cpu_model()} "
            f"(load average before {load[0]:.2f}, {wall / 60:.1f} min)" if wall > 0 else
            "Tables of earlier runs of this script (--json files given to --merge, every episode kept there)")
    lines = [f"{when}, seeds {sweep['seeds'][0]}-{sweep['seeds'][-1]} per scene, each scene's full episode "
             f"length and {params}:",
             "", "```", command, "```", "", "```", format_sweep(sweep), "```", ""]
    if names:
        lines += ["| target | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
        for i, (name, _, _) in enumerate(per[names[0]]):
            lines.append(f"| {name} | " + " | ".join(per[n][i][1] for n in names) + " |")
        met = {n: sum(1 for _, _, m in per[n] if m) for n in names}
        lines += ["", "Targets met: " + ", ".join(f"{n} {met[n]} of {len(per[n])}" for n in names) + "."]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--episodes", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--backend", default="processes")
    ap.add_argument("--json", default=None, metavar="PATH")
    ap.add_argument("--marker", default=None, help="RESULTS.md section (default intermittent_targets, "
                                                   "with --shoot shooting_targets)")
    ap.add_argument("--shoot", type=float, default=0.0, metavar="S",
                    help="isf with maneuvers by shooting over S seconds (default 0: off)")
    ap.add_argument("--vendor", action="store_true",
                    help="the vendor-style arms of benchmarks/vendor_arms instead of the shipped scenes "
                         "(--scenes then names them: " + ", ".join(VENDOR) + ")")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--merge", nargs="*", default=[], metavar="PATH",
                    help="sweep JSON files (--json of earlier runs) whose scenes join the report; "
                         "with --episodes 0 nothing new runs")
    args = ap.parse_args()
    marker = args.marker or ("shooting_targets" if args.shoot else
                             "intermittent_targets_vendor" if args.vendor else "intermittent_targets")
    if args.vendor:
        names = [n for n in args.scenes if n not in SCENES] or list(VENDOR)
        specs = vendor_specs(names)
    else:
        specs = [SceneSpec(name=n) for n in args.scenes]
    isf = SweepPoint("isf", {"shoot": args.shoot} if args.shoot else {})
    load = os.getloadavg()
    t0 = time.perf_counter()
    kw: dict[str, Any] = {}
    if args.backend != "processes":
        kw["backend"] = args.backend

    def progress(done: int, total: int, task: Any, r: Any) -> None:
        print(f"[{done}/{total}] {r['scene']} {r['filter']} seed {r['seed']}: duty {r['duty_cycle']:.3f}",
              file=sys.stderr, flush=True)

    sweep: dict[str, Any] = {"partial": False, "seeds": list(range(args.episodes)), "scenes": []}
    if args.episodes > 0:
        sweep = run_sweep(specs, [SweepPoint("cbf"), isf],
                          list(range(args.episodes)), duration=args.duration, jobs=args.jobs, progress=progress,
                          **kw)
    for path in args.merge:  # earlier runs' scenes (a scene run here wins)
        old = json.loads(Path(path).read_text(encoding="utf-8"))
        have = {sc["scene"] for sc in sweep["scenes"]}
        sweep["scenes"] += [sc for sc in old["scenes"] if sc["scene"] not in have]
        sweep["seeds"] = sweep["seeds"] or old["seeds"]
    wall = time.perf_counter() - t0 if args.episodes > 0 else 0.0
    if args.json:
        write_text_atomic(args.json, json.dumps(with_schema("isf-robot-sweep", sweep), indent=1) + "\n")
    cmd = "nice -n 19 python benchmarks/intermittent_targets.py " + " ".join(sys.argv[1:])
    params = ("the library's defaults (no [filter] table: FilterSpec's defaults, d_bar calibrated, hand-over "
              "and horizon designed from the scene)" if args.vendor else "shipped parameters")
    body = report(sweep, cmd.strip(), load, wall, params)
    print(body)
    if not args.no_write:
        write_section(ROOT / "RESULTS.md", f"<!-- {marker}:start -->", f"<!-- {marker}:end -->", body,
                      write=write_text_atomic)


if __name__ == "__main__":
    main()
