"""Every study figure of REPRODUCTION.md, from the shipped code, in one command.

Usage::

    python benchmarks/satellite_reproduction.py                 # run every part, then write REPRODUCTION.md's tables
    python benchmarks/satellite_reproduction.py --parts headline  # one part (the others' committed results are kept)
    python benchmarks/satellite_reproduction.py --render          # only rewrite the tables from the committed results
    python benchmarks/satellite_reproduction.py --check           # rerun the small check subset, compare (about 1 min)

Parts (each a paired study, :func:`satellite.study.paired.run_study`, over the same 51 starts: seeds
0-16 x inclinations 15, 45, 75 deg; the Kepler controller's tau_p fit
``docs/figures/satellite_tau_kepler.json``, the shooting controller's
``docs/figures/satellite_tau_shooting.json``):

* ``headline``: 2400 h (the paper's length), greedy, maneuver and periodic (every 0.25 h), Kepler controller;
* ``shooting``: 240 h, greedy, maneuver and periodic (every hour) with the shooting controller, and
  greedy and maneuver with the Kepler controller, paired;
* ``shooting2400``: 2400 h, greedy and maneuver with the shooting controller, the 17 starts at 45 deg;
* ``sensitivity``: 240 h greedy, Kepler controller, one setting changed at a time (no spin, disturbance
  x0.25 and x0.5, the degree-8 series, alpha x0.1, the shooting controller) against the default;
* ``check``: 24 h, 3 starts, greedy / maneuver / periodic: small enough to rerun in CI (``--check``).

Three more parts regenerate the other figures: ``tau`` (the two tau_p files, ``isf-satellite tau``;
the studies read them, so it runs first), ``field`` (the default field's largest error against the
exact one, ``benchmarks/satellite_field_worst.py``) and ``figures`` (``scripts/satellite_figures.py``:
the paper's Figs. 2-4 and their data, ``docs/figures/satellite_figures.json``).

Each part's study document is written to ``docs/figures/satellite_repro_<part>.json`` (atomically,
after every orbit; an interrupted part resumes from it with ``--resume``). The tables between the
``<!-- repro:NAME:start -->`` / ``end`` markers of REPRODUCTION.md are rendered from those files.

``--check`` reruns the ``check`` part and compares every run with the committed file: impulse counts
and kinds exactly, ``total_dv``, ``min_h`` and the physical flight to a relative ``1e-4`` (the measured
spread of last-bit rounding between CPUs over 12-24 h; ``tests/golden``). Exit status 1 on a difference.

Use ``--workers 1`` on a shared machine (the default); the whole set takes about four hours of one core.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from isf_robot.support.files import write_text_atomic
from satellite.orbit.model import OrbitModel
from satellite.study.paired import StudyConfig, StudySettings, run_study
from satellite.study.stats import paired_comparison, plain_change

ROOT = Path(__file__).resolve().parent.parent
FIGURES = ROOT / "docs" / "figures"
DOC = ROOT / "REPRODUCTION.md"
SCHEMA = "isf-satellite-reproduction/1"
TAU = {"kepler": str(FIGURES / "satellite_tau_kepler.json"), "shooting": str(FIGURES / "satellite_tau_shooting.json")}
STARTS = [(s, inc) for inc in (15.0, 45.0, 75.0) for s in range(17)]
CHECK_STARTS = [(0, 45.0), (1, 15.0), (2, 75.0)]
CHECK_RTOL = 1e-4
SHOOTING_PERIOD_H = 1.0
"""The shooting controller's periodic baseline: every hour (the Kepler controller's needs 0.25 h)."""
PAPER_TRIGGERS = {"greedy": 267, "maneuver": 215}
"""The paper's counts over 2400 h (one orbit, Figs. 3 and 4)."""


@dataclass(frozen=True)
class Study:
    """One study of a part: its configurations, starts and settings."""

    name: str
    configs: tuple[StudyConfig, ...]
    settings: StudySettings
    starts: tuple[tuple[int, float], ...] = tuple(STARTS)
    label: str = ""


@dataclass(frozen=True)
class Part:
    name: str
    studies: tuple[Study, ...] = field(default_factory=tuple)


def _kepler(*trig: str, period: float = 0.25) -> tuple[StudyConfig, ...]:
    return tuple(StudyConfig(t, "kepler", period if t == "periodic" else None) for t in trig)


def parts() -> dict[str, Part]:
    """The parts and their studies."""
    gain = OrbitModel().mean_motion_centre()
    base240 = StudySettings(hours=240.0, tau=TAU)
    sens = [("default", base240), ("no spin", replace(base240, spin=False)),
            ("disturbance x0.25", replace(base240, disturbance_scale=0.25)),
            ("disturbance x0.5", replace(base240, disturbance_scale=0.5)),
            ("degree-8 series field", replace(base240, gravity="sh8")),
            ("alpha x0.1", replace(base240, alpha_gain=0.1 * gain))]
    return {
        "headline": Part("headline", (Study("headline", _kepler("greedy", "maneuver", "periodic"),
                                            StudySettings(hours=2400.0, tau=TAU)),)),
        "shooting": Part("shooting", (Study("shooting", (StudyConfig("greedy", "shooting"),
                                                         StudyConfig("maneuver", "shooting"),
                                                         *_kepler("greedy", "maneuver"),
                                                         StudyConfig("periodic", "shooting", SHOOTING_PERIOD_H)),
                                            base240),)),
        "shooting2400": Part("shooting2400", (Study("shooting 2400 h", (StudyConfig("greedy", "shooting"),
                                                                        StudyConfig("maneuver", "shooting")),
                                                    StudySettings(hours=2400.0, tau=TAU),
                                                    tuple(s for s in STARTS if s[1] == 45.0)),)),
        "sensitivity": Part("sensitivity", tuple(Study(f"sensitivity {k}", _kepler("greedy"), s, label=k)
                                                 for k, s in sens)),
        "check": Part("check", (Study("check", _kepler("greedy", "maneuver", "periodic"),
                                      StudySettings(hours=24.0, tau=TAU), tuple(CHECK_STARTS)),)),
    }


TAU_COMMANDS = {
    "kepler": ["tau", "--samples", "100"],
    "shooting": ["tau", "--samples", "20", "--max-hours", "48", "--controller", "shooting"],
}
"""``isf-satellite`` arguments that make each controller's tau_p file (``--out`` and ``--workers`` added)."""
OTHER_PARTS = ("tau", "field", "figures")


def run_other(name: str, workers: int) -> None:
    """The parts that are not studies: the tau_p files, the field's worst error, the figures."""
    if name == "tau":
        from satellite.cli import main as satellite_main

        for ctrl, args in TAU_COMMANDS.items():
            code = satellite_main([*args, "--workers", str(workers), "--out", TAU[ctrl]])
            if code:
                raise SystemExit(f"isf-satellite {' '.join(args)} failed ({code})")
    elif name == "field":
        import satellite_field_worst

        doc = satellite_field_worst.run(1500, 8, 0)
        write_text_atomic(part_file("field"), json.dumps(doc, indent=1) + "\n")
    elif name == "figures":
        subprocess.run([sys.executable, str(ROOT / "scripts" / "satellite_figures.py")], check=True)


def part_file(name: str) -> Path:
    return FIGURES / f"satellite_repro_{name}.json"


def _rel_tau(settings: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(settings)
    out["tau"] = {k: str(Path(v).relative_to(ROOT)) for k, v in settings["tau"].items()}
    return out


def run_part(part: Part, workers: int, resume: bool, quiet: bool) -> dict[str, Any]:
    """Run a part's studies; write its file after every orbit (marked partial until done)."""
    path = part_file(part.name)
    old = json.loads(path.read_text()) if resume and path.exists() else {"studies": {}}
    docs: dict[str, Any] = dict(old.get("studies", {}))

    def save(partial: bool) -> None:
        write_text_atomic(path, json.dumps({"schema": SCHEMA, "part": part.name, "partial": partial,
                                            "studies": docs}, separators=(",", ":")) + "\n")

    for st in part.studies:
        done = docs.get(st.name, {}).get("runs", [])

        def progress(k: int, n: int, task: Any, run: Mapping[str, Any], _name: str = st.name) -> None:
            if not quiet:
                print(f"[{part.name}] {_name}: {k}/{n} {task.config.label} seed {task.seed} "
                      f"inc {task.inclination_deg:g}: {run['triggers']} impulses", file=sys.stderr, flush=True)

        def checkpoint(doc: dict[str, Any], _name: str = st.name) -> None:
            docs[_name] = _slim(doc)
            save(True)

        doc = run_study(list(st.configs), list(st.starts), st.settings, jobs=workers, done_runs=done,
                        progress=progress, checkpoint=checkpoint)
        docs[st.name] = _slim(doc)
        save(True)
    save(False)
    return docs


def _slim(doc: dict[str, Any]) -> dict[str, Any]:
    out = dict(doc)
    out["settings"] = _rel_tau(doc["settings"])
    out["runs"] = [{k: (round(v, 6) if isinstance(v, float) else v) for k, v in r.items() if k != "x0"}
                   for r in doc["runs"]]
    for r in out["runs"]:  # (the comparisons above used them unrounded; kept for --resume, 0.36 s / 1e-7 m/s)
        r["impulses_physical"] = [[round(t, 4), round(dv, 7)] for t, dv in r.get("impulses_physical") or []]
    return json.loads(json.dumps(out, default=float))


# -- rendering ---------------------------------------------------------------------------------
def _load(name: str) -> dict[str, Any] | None:
    p = part_file(name)
    return json.loads(p.read_text())["studies"] if p.exists() else None


def _summary(doc: Mapping[str, Any], label: str) -> Mapping[str, Any]:
    return next(c["summary"] for c in doc["configs"] if c["label"] == label)


def _cmp(doc: Mapping[str, Any], a: str, b: str) -> Mapping[str, Any]:
    for c in doc["comparisons"]:
        if c["a"] == a and c["b"] == b:
            return c
    by: dict[str, list[dict[str, Any]]] = {}
    for r in doc["runs"]:
        by.setdefault(r["config"], []).append(r)
    return {"a": a, "b": b, **paired_comparison(by.get(a, []), by.get(b, []))}


def _ms(s: Mapping[str, Any] | None, fmt: str = ".1f") -> str:
    if not s or s.get("mean") is None:
        return "-"
    return f"{format(s['mean'], fmt)} (sd {format(s['sd'], fmt)})"


def _partial(doc: Mapping[str, Any]) -> str:
    return f" (partial: {doc['orbits_done']} of {doc['orbits_total']} orbits)" if doc.get("partial") else ""


def _partial_note(doc: Mapping[str, Any]) -> str:
    return f"\n\nPartial: {doc['orbits_done']} of {doc['orbits_total']} orbits." if doc.get("partial") else ""


def table_paper(studies: Mapping[str, Any]) -> str:
    head = studies.get("headline", {}).get("headline")
    shoot = studies.get("shooting", {}).get("shooting")
    lines = ["| paper (one orbit, 2400 h) | ours | where |", "|---|---|---|"]
    if head:
        g, m = _summary(head, "greedy/kepler"), _summary(head, "maneuver/kepler")
        gm = _cmp(head, "maneuver/kepler", "greedy/kepler")
        gp = _cmp(head, "greedy/kepler", "periodic 0.25h/kepler")
        n = head["orbits_total"] // 3
        lines += [
            f"| greedy: {PAPER_TRIGGERS['greedy']} triggers (one per {2400 / PAPER_TRIGGERS['greedy']:.1f} h) | "
            f"before the first surface contact: {_ms(g['physical_per_100h'], '.1f')} per 100 h over {n} orbits "
            f"(the paper's rate: {100 * PAPER_TRIGGERS['greedy'] / 2400:.1f}); {g['orbits_with_contact']} of "
            f"{g['orbits']} orbits touch the surface, the physical flight lasting {_ms(g['physical_h'], '.0f')} h; "
            f"over the whole 2400 h, through the body: {_ms(g['triggers'])} impulses | "
            "\"The paired study\", \"Why more triggers than the paper\" |",
            f"| maneuver: {PAPER_TRIGGERS['maneuver']} triggers, 19.5 % fewer than greedy | "
            f"before contact: **{plain_change(gm['physical']['triggers'], 'impulses')}** than greedy "
            f"({gm['physical']['n']} pairs, up to the earlier contact, mean "
            f"{gm['physical']['horizon_h']['mean']:.0f} h); {m['tau_impulses']} \"tau\" impulses (min Xi_tau "
            f"{m['min_xi_tau']:.3f} > 0) | \"The paired study\" |",
            f"| - (no baseline) | greedy against periodic every 0.25 h, before contact: "
            f"**{plain_change(gp['physical']['triggers'], 'impulses')}**, "
            f"dv {plain_change(gp['physical']['total_dv'])} | \"The paired study\" |"]
    if shoot:
        c = _cmp(shoot, "maneuver/shooting", "greedy/shooting")
        k = _cmp(shoot, "greedy/shooting", "greedy/kepler")
        per = f"periodic {SHOOTING_PERIOD_H:g}h/shooting"
        pp = ""
        if any(r["config"] == per for r in shoot["runs"]):
            gp = _cmp(shoot, "greedy/shooting", per)
            pp = f"; greedy/shooting {plain_change(gp['physical']['triggers'], 'impulses')} than {per}"
        lines += [f"| - | shooting controller, 240 h, before contact: maneuver "
                  f"**{plain_change(c['physical']['triggers'], 'impulses')}** than greedy; greedy/shooting "
                  f"{plain_change(k['physical']['triggers'], 'impulses')} than greedy/Kepler{pp} | "
                  "\"The shooting controller\" |"]
    s24 = studies.get("shooting2400", {}).get("shooting 2400 h")
    if s24:
        g = _summary(s24, "greedy/shooting")
        c = _cmp(s24, "maneuver/shooting", "greedy/shooting")
        lines.append(f"| greedy 267, maneuver 215 (19.5 % fewer) | shooting controller, 2400 h, "
                     f"{g['orbits']} starts at "
                     f"45 deg: greedy {_ms(g['physical_per_100h'], '.1f')} impulses per 100 h before contact, "
                     f"{_ms(g['triggers'])} over the whole 2400 h; maneuver before contact "
                     f"**{plain_change(c['physical']['triggers'], 'impulses')}** than greedy | "
                     "\"The shooting controller\" |")
    return "\n".join(lines)


def table_study(doc: Mapping[str, Any]) -> str:
    lines = ["| configuration | orbits flown to the end | impulses before contact, per 100 h | physical flight [h] | "
             "orbits with contact | whole run: impulses | whole run: dv [m/s] | tau impulses | min Xi_tau | "
             "band exits |", "|---|---|---|---|---|---|---|---|---|---|"]
    for c in doc["configs"]:
        s = c["summary"]
        xt = "-" if s["min_xi_tau"] is None else f"{s['min_xi_tau']:.3f}"
        lines.append(f"| {c['label']} | {s['completed']}/{s['orbits']} | {_ms(s['physical_per_100h'], '.2f')} | "
                     f"{_ms(s['physical_h'], '.0f')} | {s['orbits_with_contact']} | {_ms(s['triggers'])} | "
                     f"{_ms(s['total_dv'], '.3f')} | {s['tau_impulses']} | {xt} | {s['orbits_with_band_exit']} |")
    lines += ["", "| a against b (paired by start) | physical: pairs, mean horizon | impulses, physical | "
                  "dv, physical | whole run: pairs | impulses, whole run | dv, whole run |",
              "|---|---|---|---|---|---|---|"]
    for c in doc["comparisons"]:
        ph = c["physical"]
        lines.append(f"| {c['a']} against {c['b']} | {ph['n']}, {_f0(ph['horizon_h']['mean'])} h | "
                     f"{plain_change(ph['triggers'])} | {plain_change(ph['total_dv'])} | {c['n']} | "
                     f"{plain_change(c['triggers'])} | {plain_change(c['total_dv'])} |")
    return "\n".join(lines) + _partial_note(doc)


def _f0(v: float | None) -> str:
    return "-" if v is None else f"{v:.0f}"


def table_sensitivity(studies: Mapping[str, Any], shoot: Mapping[str, Any] | None) -> str:
    lines = ["| setting (240 h greedy, 51 starts; one change from the default) | impulses per 100 h, before "
             "contact | impulses per 100 h, whole run | physical flight [h] (to the first contact, else the "
             "whole run) | orbits with contact |",
             "|---|---|---|---|---|"]
    rows = [(d.get("label") or k.removeprefix("sensitivity "), d, "greedy/kepler") for k, d in studies.items()]
    if shoot:
        rows.append(("shooting controller", shoot, "greedy/shooting"))
    for name, doc, label in rows:
        s = _summary(doc, label)
        hours = doc["settings"]["hours"]
        whole = s["triggers"]
        per = None if whole["mean"] is None else {"mean": 100 * whole["mean"] / hours,
                                                   "sd": 100 * whole["sd"] / hours}
        lines.append(f"| {name} | {_ms(s['physical_per_100h'], '.2f')} | {_ms(per, '.2f')} | "
                     f"{_ms(s['physical_h'], '.0f')} | {s['orbits_with_contact']} of {s['orbits']}{_partial(doc)} |")
    lines.append(f"| the paper (one orbit, 2400 h) | {100 * PAPER_TRIGGERS['greedy'] / 2400:.2f} | "
                 f"{100 * PAPER_TRIGGERS['greedy'] / 2400:.2f} | - | - |")
    return "\n".join(lines)


def table_check(doc: Mapping[str, Any]) -> str:
    lines = ["| configuration | seed, inclination | impulses (kinds) | total dv [m/s] | min h [m^2] |",
             "|---|---|---|---|---|"]
    for r in doc["runs"]:
        kinds = ", ".join(f"{k} {v}" for k, v in sorted(r["kinds"].items()))
        lines.append(f"| {r['config']} | {r['seed']}, {r['inclination_deg']:g} | {r['triggers']} ({kinds}) | "
                     f"{r['total_dv']:.6g} | {r['min_h']:.6g} |")
    return "\n".join(lines)


def table_field(doc: Mapping[str, Any]) -> str:
    lines = ["| region of the band (distance to the surface) | random points: median / max | largest found by "
             "the search | where: r / R, distance |", "|---|---|---|---|"]
    for r in doc["regions"]:
        lines.append(f"| {r['region']} | {100 * r['random_median']:.3g} / {100 * r['random_max']:.3g} % | "
                     f"**{100 * r['searched_max']:.3g} %** | {r['at_r_over_R']:.3f} R, {r['at_distance_m']:.1f} m |")
    lines += ["", f"Largest error found: **{100 * doc['max']:.2g} %** of the non-Kepler pull ({doc['candidates']} "
              f"random points per region, the {doc['starts']} worst refined by Nelder-Mead; "
              f"{doc['evaluations']} exact evaluations; seed {doc['seed']})."]
    return "\n".join(lines)


def _tau_fit(coef: list[float], s: float) -> float:
    return sum(c * s**k for k, c in enumerate(coef)) / 3600.0


def table_tau() -> str:
    lines = []
    for ctrl, path in TAU.items():
        d = json.loads(Path(path).read_text())
        r, med, x = d["radii_over_R"], d["median_h"], d["h_over_h_max"]
        coef = d["fit"]["coef_s"]
        lines += [f"**{ctrl} controller** ({d['samples']} states per radius, censored at {d['max_hours']:g} h: "
                  f"{sum(d['censored'])} samples; fit tau_p = " + " + ".join(
                      f"{c:.0f} s" + ("" if k == 0 else " * s" if k == 1 else f" * s^{k}") for k, c in enumerate(coef))
                  + ", s = h / h_max)", "",
                  "| r/R | " + " | ".join(f"{v:.2f}" for v in r) + " |", "|---" * (len(r) + 1) + "|",
                  "| median [h] | " + " | ".join(f"{v:.2f}" for v in med) + " |",
                  "| fit [h] | " + " | ".join(f"{_tau_fit(coef, v):.2f}" for v in x) + " |", ""]
    return "\n".join(lines).rstrip()


def table_figures() -> str:
    d = json.loads((FIGURES / "satellite_figures.json").read_text())
    st = d["settings"]
    lines = [f"Seed {st['seed']}, inclination {st['inclination_deg']:g} deg, {st['hours']:g} h, "
             f"{st['controller']} controller, field `{st['gravity']}`:", "",
             "| trigger | impulses (kinds) | shortest / mean inter-event [h] | min h [m^2] | surface contacts |",
             "|---|---|---|---|---|"]
    for k in ("greedy", "maneuver"):
        g = d[k]
        kinds = ", ".join(f"{a} {b}" for a, b in sorted(g["kinds"].items()))
        lines.append(f"| {k} | {g['triggers']} ({kinds}) | {g['min_inter_event_h']:.3f} / "
                     f"{g['mean_inter_event_h']:.2f} | {g['min_h']:.0f} | {g['surface_contacts']} |")
    return "\n".join(lines)


def render() -> None:
    """Rewrite every generated block of REPRODUCTION.md from the committed part files."""
    studies = {name: _load(name) or {} for name in parts() if name not in OTHER_PARTS}
    blocks: dict[str, Callable[[], str]] = {"paper": lambda: table_paper(studies)}
    if studies["headline"]:
        blocks["headline"] = lambda: table_study(studies["headline"]["headline"])
    if studies["shooting"]:
        blocks["shooting"] = lambda: table_study(studies["shooting"]["shooting"])
    if studies["shooting2400"]:
        blocks["shooting2400"] = lambda: table_study(studies["shooting2400"]["shooting 2400 h"])
    if studies["sensitivity"]:
        blocks["sensitivity"] = lambda: table_sensitivity(studies["sensitivity"],
                                                          studies["shooting"].get("shooting"))
    if studies["check"]:
        blocks["check"] = lambda: table_check(studies["check"]["check"])
    if part_file("field").exists():
        blocks["field"] = lambda: table_field(json.loads(part_file("field").read_text()))
    blocks["tau"] = table_tau
    blocks["figures"] = table_figures
    text = DOC.read_text(encoding="utf-8")
    for name, make in blocks.items():
        start, end = f"<!-- repro:{name}:start -->", f"<!-- repro:{name}:end -->"
        if start not in text or end not in text:
            raise SystemExit(f"REPRODUCTION.md has no {start} ... {end} block")
        head, rest = text.split(start, 1)
        text = head + start + "\n" + make() + "\n" + end + rest.split(end, 1)[1]
    write_text_atomic(DOC, text)


# -- check -----------------------------------------------------------------------------------
def compare(got: Mapping[str, Any], want: Mapping[str, Any], rtol: float = CHECK_RTOL) -> list[str]:
    """Differences between two check documents: counts and kinds exactly, floats to ``rtol``."""
    key = lambda r: (r["config"], r["seed"], r["inclination_deg"])  # noqa: E731
    a, b = {key(r): r for r in got["runs"]}, {key(r): r for r in want["runs"]}
    out = [f"{k}: missing" for k in b if k not in a] + [f"{k}: not in the committed file" for k in a if k not in b]
    for k in sorted(set(a) & set(b)):
        for f in ("triggers", "kinds", "triggers_physical", "surface_contacts", "band_exits"):
            if a[k].get(f) != b[k].get(f):
                out.append(f"{k} {f}: {a[k].get(f)} != committed {b[k].get(f)}")
        for f in ("total_dv", "min_h", "physical_h", "total_dv_physical"):
            x, y = a[k].get(f), b[k].get(f)
            if (x is None) != (y is None) or (x is not None and not math.isclose(x, y, rel_tol=rtol, abs_tol=1e-9)):
                out.append(f"{k} {f}: {x} != committed {y} (rtol {rtol:g})")
    return out


def check() -> int:
    want = _load("check")
    if not want:
        raise SystemExit(f"no committed check results: {part_file('check')}")
    st = parts()["check"].studies[0]
    got = _slim(run_study(list(st.configs), list(st.starts), st.settings, jobs=1))
    diffs = compare(got, want["check"])
    for d in diffs:
        print(d)
    print(f"check: {len(got['runs'])} runs, {len(diffs)} difference(s) (counts exact, floats rtol {CHECK_RTOL:g})")
    return 1 if diffs else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    order = ["tau", "headline", "shooting", "shooting2400", "sensitivity", "check", "field", "figures"]
    ap.add_argument("--parts", nargs="+", choices=order, default=order, metavar="PART",
                    help=f"parts to run, in this order, of {', '.join(order)} (default all)")
    ap.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--resume", action="store_true", help="keep the finished orbits of the parts' files")
    ap.add_argument("--render", action="store_true", help="only rewrite REPRODUCTION.md's tables")
    ap.add_argument("--check", action="store_true", help="rerun the check subset and compare with the committed one")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    if a.workers < 1:
        raise SystemExit("--workers must be >= 1")
    if a.check:
        return check()
    if not a.render:
        for name in sorted(set(a.parts), key=order.index):
            if name in OTHER_PARTS:
                run_other(name, a.workers)
            else:
                run_part(parts()[name], a.workers, a.resume, a.quiet)
    render()
    return 0


if __name__ == "__main__":
    sys.exit(main())
