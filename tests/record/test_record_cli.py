"""The CLI: replay --json reproduces run --json; compare writes one recording per run; --spawn fails cleanly."""

from __future__ import annotations

import json
import math
import pickle
import subprocess
import sys

import pytest

from isf_robot.cli import main

KEYS_EXACT = ("duty_cycle", "on_switches", "off_switches", "control_steps", "qp_solves")
KEYS_FLOAT = ("mean_off_s", "min_off_s", "max_off_s", "mean_on_s", "min_on_s", "min_barrier", "intervention",
              "duration_s")


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict:  # type: ignore[type-arg]
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def _close(a: float | None, b: float | None) -> bool:
    if a is None or b is None:
        return a is b
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-300)


def test_replay_json_reproduces_run_json(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    rrd = tmp_path / "run.rrd"
    run = _json(capsys, ["run", "--scene", "planar_moving", "--filter", "isf", "--duration", "6", "--json",
                         "--rrd", str(rrd)])
    assert run["on_switches"] > 0 and run["schema"] == "isf-robot-run/1"
    doc = _json(capsys, ["replay", str(rrd), "--json"])
    assert doc["schema"] == "isf-robot-replay/1" and len(doc["recordings"]) == 1  # one shape for any number
    (item,) = doc["recordings"]
    rep = item["metrics"]
    # the recording says what made it: versions, scene, strategy and every parameter of the run
    import mujoco

    import isf_robot

    assert item["versions"] == {"isf_robot": isf_robot.__version__, "rerun": item["versions"]["rerun"],
                                "mujoco": mujoco.__version__}
    for k in ("scene", "strategy", "seed", "alpha", "c", "b", "d_bar", "d_bar_source", "control_period", "dt"):
        assert item["info"][k] == run.get(k, item["info"][k]), k
    assert item["info"]["strategy"] == run["filter"] and item["info"]["d_bar"] == run["d_bar"]
    assert main(["replay", str(rrd)]) == 0
    text = capsys.readouterr().out
    assert f"isf_robot {isf_robot.__version__}" in text and f"mujoco {mujoco.__version__}" in text
    assert "scene=planar_moving" in text and "strategy=isf" in text and "d_bar=" in text
    for k in KEYS_EXACT:
        assert rep[k] == run[k], k
    for k in KEYS_FLOAT:
        assert _close(rep[k], run[k]), (k, rep[k], run[k])


def test_compare_one_recording_per_strategy_and_seed(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "cmp"
    comp = _json(capsys, ["compare", "--scene", "planar_moving", "--episodes", "2", "--duration", "1.5",
                          "--filters", "cbf", "isf", "--quiet", "--json", "--rrd", str(out)])
    files = sorted(p.name for p in out.glob("*.rrd"))
    assert files == ["planar_moving-cbf-seed0.rrd", "planar_moving-cbf-seed1.rrd", "planar_moving-isf-seed0.rrd",
                     "planar_moving-isf-seed1.rrd"]
    rep = _json(capsys, ["replay", str(out), "--json"])
    recs = rep["recordings"]
    assert len(recs) == 4 and len({r["recording_id"] for r in recs}) == 4
    for r in recs:
        strat, seed = r["info"]["strategy"], r["info"]["seed"]
        (run,) = [e for e in comp["results"][strat]["episodes"] if e["seed"] == seed]
        for k in KEYS_EXACT:
            assert r["metrics"][k] == run[k], (strat, seed, k)
        for k in KEYS_FLOAT:
            assert _close(r["metrics"][k], run[k]), (strat, seed, k)
    assert main(["replay", str(out / "planar_moving-cbf-seed0.rrd"), str(out / "planar_moving-isf-seed0.rrd")]) == 0
    table = capsys.readouterr().out
    assert "duty_cycle" in table and "planar_moving/cbf/seed0" in table and "planar_moving/isf/seed0" in table


def test_compare_rrd_must_be_a_directory(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["compare", "--scene", "planar_moving", "--episodes", "1", "--duration", "0.2",
                 "--rrd", str(tmp_path / "x.rrd")]) == 2
    assert "pass a directory" in capsys.readouterr().err


def test_per_run_recorder_pickles(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.record import PerRunRecorder

    obs = PerRunRecorder(tmp_path, "arm")
    clone = pickle.loads(pickle.dumps(obs))
    assert clone.directory == tmp_path and clone.kind == "arm"


def test_spawn_without_display_fails_clearly(monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if sys.platform.startswith("linux"):
        assert main(["run", "--scene", "planar_moving", "--duration", "0.2", "--spawn"]) == 2
        err = capsys.readouterr().err
        assert "viewer" in err and ("display" in err or "executable" in err)


def test_cli_help_does_not_import_rerun() -> None:
    code = ("import sys; from isf_robot.cli import build_parser; build_parser(); "
            "print('rerun' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_record_package_is_the_only_rerun_importer() -> None:
    code = ("import sys, isf_robot.core, isf_robot.arm, satellite.orbit.simulate; "
            "print('rerun' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_satellite_cli_rrd_replays(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    from satellite.cli import main as sat_main

    rrd = tmp_path / "sat.rrd"
    assert sat_main(["run", "--hours", "40", "--json", "--quiet", "--rrd", str(rrd)]) == 0
    run = json.loads(capsys.readouterr().out)
    assert run["schema"] == "isf-satellite-run/1"
    rep = _json(capsys, ["replay", str(rrd), "--json"])["recordings"][0]["metrics"]
    assert rep["triggers"] == run["triggers"] and rep["kinds"] == run["kinds"]
    assert rep["min_barrier"] == run["min_h"]  # exact, from the run
    assert rep["total_dv"] == run["total_dv"]
    for k in ("min_inter_event_h", "mean_inter_event_h"):
        assert _close(rep[k], run[k]), k
