"""The arm subcommands of ``isf-robot``: scenes, run, compare, demo, and their errors."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from isf_robot.cli import main
from isf_robot.paths import models_dir

RUN_KEYS = {"scene", "filter", "seed", "duration_s", "control_steps", "duty_cycle",
            "on_switches", "mean_off_s", "min_off_s", "min_barrier", "collisions",
            "goals_reached", "intervention", "qp_solves", "d_bar", "wall_s"}
SCENES = ("planar", "planar_moving", "panda_pole", "panda_shelf", "panda_moving")


def _run(capsys, *argv: str) -> tuple[int, str, str]:  # type: ignore[no-untyped-def]
    rc = main(list(argv))
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_scenes_lists_one_line_each(capsys) -> None:  # type: ignore[no-untyped-def]
    rc, out, _ = _run(capsys, "scenes")
    assert rc == 0
    lines = out.strip().splitlines()
    names = [ln.split()[0] for ln in lines]
    for s in SCENES:
        assert s in names
    assert all(len(ln.split(None, 1)) == 2 for ln in lines)  # name and description


def test_run_json_keys(capsys) -> None:  # type: ignore[no-untyped-def]
    rc, out, _ = _run(capsys, "run", "--scene", "planar", "--filter", "isf", "--duration", "1",
                      "--seed", "3", "--json")
    assert rc == 0
    d = json.loads(out)  # stdout is exactly one JSON object
    assert RUN_KEYS <= set(d)
    assert d["scene"] == "planar" and d["filter"] == "isf" and d["seed"] == 3
    assert d["duration_s"] == pytest.approx(1.0) and d["control_steps"] == 500
    assert d["min_barrier"] >= -1e-3


def test_run_text_output(capsys) -> None:  # type: ignore[no-untyped-def]
    rc, out, _ = _run(capsys, "run", "--scene", "planar", "--filter", "cbf", "--duration", "0.5")
    assert rc == 0 and "duty cycle" in out and "min barrier" in out


def test_run_from_model_and_config_files(capsys) -> None:  # type: ignore[no-untyped-def]
    m = models_dir()
    rc, out, _ = _run(capsys, "run", "--model", str(m / "planar.xml"), "--config",
                      str(m / "planar.toml"), "--filter", "nominal", "--duration", "0.5", "--json")
    assert rc == 0 and json.loads(out)["filter"] == "nominal"


@pytest.mark.parametrize("scene", SCENES)
def test_compare_json_every_scene(capsys, scene: str) -> None:  # type: ignore[no-untyped-def]
    rc, out, err = _run(capsys, "compare", "--scene", scene, "--episodes", "1", "--duration",
                        "0.3", "--json")
    assert rc == 0
    d = json.loads(out)
    assert d["scene"] == scene and d["episodes"] == 1
    assert set(d["results"]) == {"nominal", "cbf", "isf"}
    for strategy, res in d["results"].items():
        assert len(res["episodes"]) == 1
        assert res["episodes"][0]["filter"] == strategy
        assert RUN_KEYS <= set(res["episodes"][0])
        assert res["duty_cycle"] == pytest.approx(res["episodes"][0]["duty_cycle"])
    assert "[3/3]" in err  # progress on stderr


def test_compare_parallel_matches_serial(capsys) -> None:  # type: ignore[no-untyped-def]
    args = ("compare", "--scene", "planar", "--episodes", "2", "--duration", "0.5", "--filters",
            "cbf", "isf", "--json", "--quiet")
    rc, out1, err = _run(capsys, *args, "--jobs", "2")
    assert rc == 0 and err == ""
    rc, out2, _ = _run(capsys, *args)
    d1, d2 = json.loads(out1), json.loads(out2)
    d_bars = {e["d_bar"] for r in d1["results"].values() for e in r["episodes"]}
    assert len(d_bars) == 1  # every worker calibrates to the same bound
    for s in ("cbf", "isf"):
        e1 = [(e["seed"], e["qp_solves"], e["min_barrier"]) for e in d1["results"][s]["episodes"]]
        e2 = [(e["seed"], e["qp_solves"], e["min_barrier"]) for e in d2["results"][s]["episodes"]]
        assert e1 == e2


def test_compare_table(capsys) -> None:  # type: ignore[no-untyped-def]
    rc, out, _ = _run(capsys, "compare", "--scene", "planar", "--episodes", "2", "--duration",
                      "0.4", "--quiet")
    assert rc == 0
    lines = out.splitlines()
    header = next(ln for ln in lines if ln.startswith("strategy"))
    assert "duty cycle" in header and "QP solves" in header and "wall [s]" in header
    rows = [ln for ln in lines if ln.split() and ln.split()[0] in ("nominal", "cbf", "isf")]
    assert len(rows) == 3 and all("±" in r for r in rows)
    assert len({len(r) for r in rows + [header]}) == 1  # aligned columns


# ----------------------------------------------------------------------------- errors


def _error(capsys, *argv: str) -> str:  # type: ignore[no-untyped-def]
    rc, out, err = _run(capsys, *argv)
    assert rc == 2
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    return err


def test_unknown_scene_lists_valid(capsys) -> None:  # type: ignore[no-untyped-def]
    err = _error(capsys, "run", "--scene", "nope")
    assert "unknown scene 'nope'" in err and "panda_pole" in err and "planar" in err
    err = _error(capsys, "compare", "--scene", "nope", "--episodes", "1")
    assert "panda_pole" in err


def test_malformed_mjcf(capsys, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    xml = tmp_path / "bad.xml"
    xml.write_text("<mujoco><worldbody><geom type='nonsense'/></worldbody>")
    err = _error(capsys, "run", "--model", str(xml), "--config", str(models_dir() / "planar.toml"))
    assert "bad.xml" in err


def _copy_planar(tmp_path: Path) -> Path:
    for f in ("planar.xml", "planar_arm.xml", "planar.toml"):
        shutil.copy(models_dir() / f, tmp_path / f)
    return tmp_path


def test_config_with_missing_geom_or_joint(capsys, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    d = _copy_planar(tmp_path)
    toml = (d / "planar.toml").read_text()
    (d / "geom.toml").write_text(toml.replace('"pole_b"', '"pole_z"'))
    err = _error(capsys, "run", "--model", str(d / "planar.xml"), "--config", str(d / "geom.toml"))
    assert "pole_z" in err and "pole_a" in err  # names the valid geoms
    (d / "joint.toml").write_text(toml.replace('"j3"', '"j9"'))
    err = _error(capsys, "run", "--model", str(d / "planar.xml"), "--config",
                 str(d / "joint.toml"))
    assert "j9" in err and "j1" in err


def test_control_period_not_a_multiple(capsys) -> None:  # type: ignore[no-untyped-def]
    err = _error(capsys, "run", "--scene", "planar", "--control-period", "0.0015")
    assert "multiple" in err
    err = _error(capsys, "compare", "--scene", "planar", "--episodes", "1", "--control-period",
                 "0.0025")
    assert "multiple" in err


def test_negative_duration(capsys) -> None:  # type: ignore[no-untyped-def]
    err = _error(capsys, "run", "--scene", "planar", "--duration", "-1")
    assert "duration" in err
    err = _error(capsys, "compare", "--scene", "planar", "--episodes", "1", "--duration", "-2")
    assert "duration" in err


def test_scene_and_files_are_exclusive(capsys) -> None:  # type: ignore[no-untyped-def]
    err = _error(capsys, "run", "--scene", "planar", "--model", "x.xml", "--config", "y.toml")
    assert "not both" in err
    _error(capsys, "run")
    _error(capsys, "compare", "--scene", "planar", "--episodes", "0")


# ----------------------------------------------------------------------------- demo


def test_demo_entry_point_prints_table() -> None:
    exe = shutil.which("isf-robot", path=str(Path(sys.executable).parent))
    cmd = [exe] if exe else [sys.executable, "-m", "isf_robot.cli"]
    p = subprocess.run(cmd + ["demo", "--episodes", "1", "--duration", "1", "--jobs", "1"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "panda_pole" in p.stdout and "isf" in p.stdout and "duty cycle" in p.stdout


@pytest.mark.parametrize("argv", [
    ["run", "--scene", "planar", "--duration", "0.1", "--seed", "-3"],
    ["compare", "--scene", "planar", "--episodes", "1", "--duration", "0.1", "--seed", "-1"],
])
def test_negative_seed_cli_exit_2_one_line(argv: list[str], capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "seed" in err and "non-negative" in err and "\n" not in err and "Traceback" not in err
