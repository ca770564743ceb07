"""The paired study: identical starts for every configuration, CIs against known answers, the same
numbers on 1 and 2 workers, resumed runs kept, Ctrl-C keeping finished orbits, one-line errors."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from satellite.cli import main as satellite_main
from satellite.orbit.model import OrbitModel
from satellite.study.paired import StudySettings, plan, run_study
from satellite.study.stats import (
    bootstrap_ci,
    paired_comparison,
    paired_physical,
    paired_t_ci,
    plain_change,
    summarize_config,
)

SATELLITE = [sys.executable, "-c", "import sys; from satellite.cli import main; sys.exit(main())"]


def _tau(tmp_path: Path) -> str:
    tau = tmp_path / "tau.json"
    tau.write_text(json.dumps({"format": "isf-satellite-tau/1",
                               "fit": {"coef_s": [6000.0, 300.0], "h_max": OrbitModel().h_max}}))
    return str(tau)


def _strip(runs: list[dict]) -> list[dict]:
    return sorted(({k: v for k, v in r.items() if k != "wall_s"} for r in runs),
                  key=lambda r: (r["config"], r["seed"], r["inclination_deg"]))


def test_paired_t_ci_known_answer() -> None:
    # mean 3, sd sqrt(2.5), t_{0.975,4} = 2.776445: half width 2.776445 * 1.581139 / sqrt(5) = 1.963243
    mean, lo, hi = paired_t_ci([1.0, 2.0, 3.0, 4.0, 5.0])
    assert mean == pytest.approx(3.0)
    assert (lo, hi) == (pytest.approx(3.0 - 1.963243, abs=1e-6), pytest.approx(3.0 + 1.963243, abs=1e-6))
    assert paired_t_ci([0.2]) == (0.2, 0.2, 0.2)
    # the bootstrap of a large normal sample agrees with the t interval; of constant data it is that constant
    x = np.random.default_rng(1).normal(0.1, 0.05, 400)
    _, tlo, thi = paired_t_ci(x)
    blo, bhi = bootstrap_ci(x)
    assert blo == pytest.approx(tlo, abs=1.5e-3) and bhi == pytest.approx(thi, abs=1.5e-3)
    assert bootstrap_ci([0.3, 0.3, 0.3]) == (pytest.approx(0.3), pytest.approx(0.3))


def test_paired_comparison_matches_orbits_and_skips_unfinished_ones() -> None:
    def run(seed: int, n: int, dv: float, completed: bool = True) -> dict:
        return {"seed": seed, "inclination_deg": 45.0, "triggers": n, "total_dv": dv, "completed": completed}

    ref = [run(0, 100, 2.0), run(1, 200, 4.0), run(2, 50, 1.0), run(3, 80, 1.0, completed=False)]
    new = [run(2, 25, 1.0), run(0, 90, 1.0), run(1, 220, 4.0), run(3, 10, 1.0)]  # another order
    c = paired_comparison(new, ref)
    assert c["n"] == 3  # seed 3: the reference left the band
    assert c["triggers"]["mean"] == pytest.approx((0.1 - 0.1 + 0.5) / 3)
    assert c["triggers"]["fewer"] == 2
    assert c["total_dv"]["mean"] == pytest.approx(0.5 / 3)
    lo, hi = c["triggers"]["ci_t"]
    assert lo < c["triggers"]["mean"] < hi
    # a run stopped at its first band exit (periodic) counts as an orbit with an exit
    for r in ref:
        r.update(band_exits=0, left_band_h=None if r["completed"] else 3.5, min_h=10.0, kinds={}, wall_s=1.0,
                 min_inter_event_h=None)
    s = summarize_config(ref)
    assert (s["orbits"], s["completed"], s["orbits_with_band_exit"], s["band_exits"]) == (4, 3, 1, 1)
    assert s["triggers"]["mean"] == pytest.approx(350 / 3)


def test_configurations_fly_the_same_starts_and_workers_do_not_change_numbers(tmp_path: Path) -> None:
    configs = plan(["greedy", "maneuver", "periodic"], ["kepler"], [0.5])
    settings = StudySettings(hours=1.5, gravity="sh8", tau={"kepler": _tau(tmp_path)})
    starts = [(0, 45.0), (1, 45.0), (0, 80.0)]
    one = run_study(configs, starts, settings, jobs=1)
    two = run_study(configs, starts, settings, jobs=2)
    assert _strip(one["runs"]) == _strip(two["runs"])
    assert not one["partial"] and one["orbits_done"] == 9
    x0 = {}
    for r in one["runs"]:  # every configuration starts each (seed, inclination) from the same state
        x0.setdefault((r["seed"], r["inclination_deg"]), set()).add((tuple(r["x0"]), r["body_phase_rad"]))
        assert r["min_h"] > 0 and r["completed"]
        assert r["config"] == "maneuver/kepler" or r["min_xi_tau"] is None  # the maneuver trigger's only
    assert all(len(v) == 1 for v in x0.values()) and len({next(iter(v)) for v in x0.values()}) == 3
    labels = [c["label"] for c in one["configs"]]
    assert labels == ["greedy/kepler", "maneuver/kepler", "periodic 0.5h/kepler"]
    assert [(c["a"], c["b"]) for c in one["comparisons"]][0] == ("maneuver/kepler", "greedy/kepler")
    assert all(c["n"] == 3 for c in one["comparisons"])
    periodic = one["configs"][2]["summary"]
    assert periodic["triggers"]["mean"] == 2.0  # at 0.5 h and 1 h of 1.5 h
    gated = [r["min_xi_tau"] for r in one["runs"] if r["config"] == "maneuver/kepler" and r["min_xi_tau"] is not None]
    assert one["configs"][1]["summary"]["min_xi_tau"] == min(gated, default=None) and periodic["min_xi_tau"] is None


def test_the_surface_barrier_option_reaches_the_runs_and_keeps_its_barrier_nonnegative(tmp_path: Path) -> None:
    configs = plan(["greedy"], ["kepler"], [])
    starts = [(0, 45.0), (3, 15.0)]
    plain = run_study(configs, starts, StudySettings(hours=6.0, gravity="sh8"))
    guarded = run_study(configs, starts, StudySettings(hours=6.0, gravity="sh8", surface_barrier=True))
    assert guarded["settings"]["surface_barrier"] is True and plain["settings"]["surface_barrier"] is False
    for r in plain["runs"]:  # contact is counted in every study run; the barrier is off by default
        assert r["surface_contacts"] is not None and r["surface_min_h_m"] is None
    for r in guarded["runs"]:
        assert r["completed"] and r["min_h"] > 0
        assert r["surface_min_h_m"] is not None and r["surface_min_h_m"] >= 0.0
        assert r["surface_contacts"] == 0
    assert guarded["configs"][0]["summary"]["surface_min_h_m"] == min(r["surface_min_h_m"] for r in guarded["runs"])


def _run(seed: int, physical_h: float, times: list[float]) -> dict:
    return {"seed": seed, "inclination_deg": 45.0, "physical_h": physical_h,
            "impulses_physical": [[t, 0.5] for t in times if t < physical_h]}


def test_physical_counts_stop_at_the_pairs_earlier_contact() -> None:
    """Known answer: each pair is counted up to the earlier of its two ends; nothing after a contact enters."""
    a0, b0 = _run(0, 5.0, [1, 2, 3, 10]), _run(0, 8.0, [1, 4, 6, 7])  # horizon 5 h: a 3, b 2 impulses
    a1, b1 = _run(1, 20.0, [2, 4, 6, 8]), _run(1, 9.0, [1, 3, 5, 7, 11])  # horizon 9 h: a 4, b 4
    a2, b2 = _run(2, 0.0, []), _run(2, 9.0, [1])  # a touched at once: no physical flight, left out
    out = paired_physical([(a0, b0), (a1, b1), (a2, b2)])
    assert out["n"] == 2 and out["horizon_h"]["mean"] == pytest.approx(7.0)
    assert out["triggers"]["mean"] == pytest.approx(((1 - 3 / 2) + 0.0) / 2)  # -25 %: a fired more
    assert out["total_dv"]["mean"] == pytest.approx(out["triggers"]["mean"])  # every impulse 0.5 m/s
    assert out["triggers"]["fewer"] == 0


@pytest.mark.parametrize("mean, ci, want", [
    (-0.074, [-0.122, -0.025], "7.4 % more impulses (95 % CI 2.5 % to 12.2 % more)"),
    (0.669, [0.630, 0.708], "66.9 % fewer impulses (95 % CI 63.0 % to 70.8 % fewer)"),
    (-0.006, [-0.022, 0.009], "0.6 % more impulses (95 % CI 2.2 % more to 0.9 % fewer)"),
    (0.0, [0.0, 0.0], "0.0 % impulses"),
])
def test_changes_read_as_fewer_or_more(mean: float, ci: list[float], want: str) -> None:
    assert plain_change({"mean": mean, "ci_t": ci}, "impulses") == want


def test_finished_runs_of_an_earlier_study_are_kept(tmp_path: Path) -> None:
    configs = plan(["greedy"], ["kepler"], [])
    settings = StudySettings(hours=1.0, gravity="sh8")
    marker = {"config": "greedy/kepler", "seed": 0, "inclination_deg": 45.0, "triggers": 999, "kinds": {},
              "min_h": 1.0, "total_dv": 1.0, "band_exits": 0, "left_band_h": None, "completed": True,
              "surface_contacts": 0, "min_pass_clearance_m": None, "min_inter_event_h": None, "wall_s": 0.0}
    doc = run_study(configs, [(0, 45.0), (1, 45.0)], settings, done_runs=[marker])
    runs = {r["seed"]: r for r in doc["runs"]}
    assert runs[0]["triggers"] == 999 and runs[1]["triggers"] < 999  # seed 0 not flown again


def test_ctrl_c_keeps_finished_orbits_and_resume_completes(tmp_path: Path) -> None:
    out = tmp_path / "study.json"
    # 6 orbits of 48 h (~3 s each on the degree-8 field): several seconds of work are left when the
    # first one ends, so the study cannot finish before the signal lands even on a loaded machine
    argv = SATELLITE + ["study", "--gravity", "sh8", "--triggers", "greedy", "--seeds", "6", "--inclinations",
                        "45", "--hours", "48", "--jobs", "2", "--out", str(out), "--json"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    assert proc.stderr is not None
    t0 = time.monotonic()
    while time.monotonic() - t0 < 120:
        line = proc.stderr.readline()
        if not line or line.startswith("[1/6]"):
            break
    proc.send_signal(signal.SIGINT)
    stdout, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err
    printed = json.loads(stdout)
    saved = json.loads(out.read_text())
    assert printed["partial"] is True and saved["partial"] is True
    assert 1 <= len(saved["runs"]) < 6 and saved["runs"] == printed["runs"]
    deadline = time.monotonic() + 10  # multiprocessing's resource tracker exits once the parent is gone
    while True:
        left = subprocess.run(["ps", "-o", "stat=,args=", "-g", str(proc.pid)], capture_output=True,
                              text=True).stdout.splitlines()
        live = [p for p in left if p.strip() and not p.split()[0].startswith("Z")]
        if not live or time.monotonic() > deadline:
            break
        time.sleep(0.2)
    assert live == [], f"workers left behind: {live}"
    finished = {r["seed"]: r for r in saved["runs"]}
    code = satellite_main(["study", "--gravity", "sh8", "--triggers", "greedy", "--seeds", "6", "--inclinations",
                           "45", "--hours", "48", "--out", str(out), "--resume", "--quiet", "--jobs", "2"])
    assert code == 0
    full = json.loads(out.read_text())
    assert full["partial"] is False and len(full["runs"]) == 6
    assert all(r == finished[r["seed"]] for r in full["runs"] if r["seed"] in finished)


@pytest.mark.parametrize("argv", [
    ["study", "--triggers", "greedy", "bogus"],
    ["study", "--controllers", "nonsense", "--triggers", "greedy"],
    ["study", "--triggers", "maneuver"],  # no --tau
    ["study", "--triggers", "greedy", "--tau", "MISSING.json"],
    ["study", "--triggers", "maneuver", "--tau", "MISSING.json"],
    ["study", "--triggers", "maneuver", "--tau", "nonsense=x.json"],
    ["study", "--seeds", "0"],
    ["study", "--hours", "-1", "--triggers", "greedy"],
    ["study", "--inclinations", "200", "--triggers", "greedy"],
    ["study", "--period-h", "0"],
    ["study", "--jobs", "0", "--triggers", "greedy"],
    ["study", "--backend", "dask", "--triggers", "greedy"],
    ["study", "--address", "auto", "--triggers", "greedy"],
    ["study", "--resume", "--triggers", "greedy"],
    ["study", "--resume", "--out", "OUT", "--triggers", "greedy"],  # not a study file
    ["study", "--out", "DIR", "--triggers", "greedy"],
    ["study", "--gravity", "nope", "--triggers", "greedy"],
    ["study", "--surface-barrier", "--triggers", "greedy", "periodic"],
], ids=lambda a: " ".join(a))
def test_bad_study_input_is_one_line(argv: list[str], tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    prev = tmp_path / "previous.json"
    prev.write_text("previous good result\n")
    (tmp_path / "dir").mkdir()
    subst = {"OUT": str(prev), "DIR": str(tmp_path / "dir"), "MISSING.json": str(tmp_path / "missing.json")}
    code = satellite_main([subst.get(a, a) for a in argv])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert err and "\n" not in err and "Traceback" not in err and "error" in err, err
    assert prev.read_text() == "previous good result\n"
