"""``isf-satellite run`` and ``isf-satellite tau``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from satellite.cli import main
from satellite.control.tau import TauFit, load_tau

KEYS = {
    "trigger", "hours", "triggers", "min_h", "r_min_over_R", "r_max_over_R", "total_dv",
    "min_inter_event_h", "mean_inter_event_h", "miet_bound_h", "wall_s",
}


@pytest.fixture(scope="module")
def tau_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tau") / "tau.json"
    assert main(["tau", "--samples", "2", "--workers", "2", "--max-hours", "20", "--out", str(out), "--quiet"]) == 0
    return out


def test_run_json_is_pure(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--trigger", "greedy", "--hours", "24", "--seed", "1", "--json"]) == 0
    out, err = capsys.readouterr()
    doc = json.loads(out)
    assert KEYS <= set(doc)
    assert doc["trigger"] == "greedy" and doc["hours"] == 24.0
    assert doc["min_xi_tau"] is None  # evaluated by the maneuver trigger only
    assert "%" in err  # progress goes to stderr


def test_run_none_reports_band_exit(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--trigger", "none", "--hours", "48", "--json", "--quiet"]) == 0
    out, err = capsys.readouterr()
    doc = json.loads(out)
    assert doc["left_band_h"] is not None and doc["left_band_h"] < 48
    assert err == ""


def test_tau_file_and_maneuver_run(tau_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = json.loads(tau_file.read_text())
    assert len(doc["median_h"]) == len(doc["radii_over_R"]) == 17
    assert isinstance(load_tau(tau_file), TauFit)
    assert main(["run", "--trigger", "maneuver", "--tau", str(tau_file), "--hours", "48", "--json", "--quiet"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["trigger"] == "maneuver" and out["min_h"] >= -1e-6
    low = out["min_xi_tau"]  # a tau impulse needs Xi_tau <= 0
    assert isinstance(low, float) and (low <= 1e-6 if out["kinds"].get("tau", 0) else low > 0.0)


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["run", "--trigger", "sometimes"], "unknown trigger 'sometimes'"),
        (["run", "--hours", "-5"], "--hours"),
        (["run", "--trigger", "maneuver"], "--tau"),
        (["run", "--trigger", "maneuver", "--tau", "/nonexistent/tau.json"], "not found"),
        (["run", "--radius", "3.0"], "band"),
        (["tau", "--samples", "0", "--out", "/tmp/x.json"], "--samples"),
    ],
)
def test_bad_input_one_line_exit_2(argv: list[str], needle: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err and "Traceback" not in err


def test_tau_file_that_is_not_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for text in ("not json", json.dumps({"format": "something-else"}), json.dumps([1, 2])):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        assert main(["run", "--trigger", "maneuver", "--tau", str(bad), "--hours", "1"]) == 2
        err = capsys.readouterr().err.strip()
        assert "not a tau file" in err and "\n" not in err
