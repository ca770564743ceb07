"""isf-robot sweep: points, the Pareto front, equal numbers in one process and in workers, bad input."""

from __future__ import annotations

import json

import pytest

from isf_robot.arm.compare import SceneSpec
from isf_robot.arm.sweep import PARAMETERS, SweepPoint, grid_points, pareto_front, random_points, run_sweep
from isf_robot.cli import main
from isf_robot.cli.sweep import _FLAGS
from isf_robot.core import ConfigError
from isf_robot.core.spec import NAMES
from isf_robot.paths import models_dir


def test_grid_gives_each_strategy_only_the_parameters_it_uses():
    pts = grid_points(["nominal", "cbf", "isf"], {"alpha": [2.0, 5.0], "c": [0.05, 0.2], "blend": [0.0, 0.02]})
    by = {s: [p for p in pts if p.strategy == s] for s in ("nominal", "cbf", "isf")}
    assert len(by["nominal"]) == 1 and by["nominal"][0].values == {}
    assert [p.values for p in by["cbf"]] == [{"alpha": 2.0}, {"alpha": 5.0}]
    assert len(by["isf"]) == 8 and len({p.label for p in by["isf"]}) == 8
    assert by["isf"][0].label == "isf alpha=2 c=0.05 blend=0"
    with pytest.raises(ConfigError, match="unknown sweep parameter 'gamma'; valid: alpha"):
        grid_points(["isf"], {"gamma": [1.0]})


def test_random_points_stay_in_their_ranges_and_repeat_with_the_seed():
    ranges = {"c": (0.01, 0.5), "blend": (0.0, 0.05), "predict_every": (1.0, 8.0)}
    a = random_points(["cbf", "isf"], ranges, 20, seed=3)
    assert a == random_points(["cbf", "isf"], ranges, 20, seed=3)
    isf = [p for p in a if p.strategy == "isf"]
    assert len(isf) == 20 and [p for p in a if p.strategy == "cbf"] == [SweepPoint("cbf", {})]
    for p in isf:
        assert 0.01 <= p.values["c"] <= 0.5 and 0.0 <= p.values["blend"] <= 0.05
        assert p.values["predict_every"] == int(p.values["predict_every"])


def test_pareto_front_known_answer():
    rows = [
        dict(duty_cycle=0.5, on_switches=2, min_off_all_s=0.3, intervention=1.0, goals_reached=2, violations=0),
        dict(duty_cycle=0.6, on_switches=3, min_off_all_s=0.2, intervention=1.5, goals_reached=2, violations=0),  # worse
        dict(duty_cycle=0.4, on_switches=9, min_off_all_s=0.3, intervention=1.0, goals_reached=2, violations=0),
        dict(duty_cycle=0.5, on_switches=2, min_off_all_s=None, intervention=1.0, goals_reached=2, violations=0),
    ]
    assert pareto_front(rows) == [False, False, True, True]  # row 3 (never back on) dominates row 0


def test_sweep_numbers_equal_in_one_process_and_in_workers(tmp_path):
    pts = [SweepPoint("cbf", {}), SweepPoint("isf", {"c": 0.1, "blend": 0.01})]
    args = dict(duration=0.6, d_bar=0.05)
    one = run_sweep([SceneSpec(name="planar")], pts, [0, 1], jobs=1, **args)
    files = SceneSpec(model=str(models_dir() / "planar.xml"), config=str(models_dir() / "planar.toml"))
    two = run_sweep([files], pts, [0, 1], jobs=2, **args)  # the same scene as a user's files (--model/--config)

    def strip(sweep):
        for sc in sweep["scenes"]:
            for r in sc["points"]:
                r.pop("wall_s")
                for run in r.pop("runs"):
                    assert run["control_steps"] == 300
    strip(one)
    strip(two)
    assert one == two
    rows = one["scenes"][0]["points"]
    assert [r["episodes"] for r in rows] == [2, 2] and rows[1]["vs_cbf"]["duty_cycle"] is not None
    assert rows[1]["values"] == {"c": 0.1, "blend": 0.01}


def test_sweep_cli_writes_json_and_refuses_bad_input(tmp_path, capsys):
    out = tmp_path / "s.json"
    code = main(["sweep", "--scenes", "planar", "--filters", "isf", "--episodes", "1", "--duration", "0.2",
                 "--d-bar", "0.05", "--c", "0.05,0.1", "--quiet", "--output", str(out)])
    assert code == 0
    doc = json.loads(out.read_text())
    assert doc["schema"] == "isf-robot-sweep/1" and len(doc["scenes"][0]["points"]) == 2
    assert "Pareto" in capsys.readouterr().out
    assert main(["sweep", "--scenes", "planar", "--c", "0.05:0.1"]) == 2
    assert "needs --random" in capsys.readouterr().err
    assert main(["sweep", "--scenes", "planar", "--c", "x"]) == 2
    assert "is not a number" in capsys.readouterr().err
    assert main(["sweep", "--scenes", "planar", "--c", "0.05", "--blend", "-1", "--d-bar", "0.05"]) == 2
    assert "blend" in capsys.readouterr().err


def test_sweep_tunes_a_users_arm_and_writes_its_filter_table(tmp_path, capsys):
    import tomllib

    xml, toml = str(models_dir() / "planar.xml"), str(models_dir() / "planar.toml")
    out = tmp_path / "tuned.toml"
    base = ["sweep", "--model", xml, "--config", toml, "--episodes", "1", "--duration", "0.4", "--d-bar", "0.05",
            "--quiet"]
    # refused before anything runs, nothing written: two scenes, no intermittent strategy, not .toml
    assert main(base + ["--scenes", "planar", "--write-config", str(out)]) == 2
    assert "give one scene, got 2" in capsys.readouterr().err
    assert main(base + ["--filters", "cbf", "--write-config", str(out)]) == 2
    assert "add an intermittent strategy" in capsys.readouterr().err
    assert main(base + ["--write-config", str(tmp_path / "tuned.txt")]) == 2
    assert "give a .toml path" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
    assert main(base + ["--filters", "cbf", "isf", "--c", "0.05,0.1", "--write-config", str(out)]) == 0
    table = tomllib.loads(out.read_text())["filter"]
    assert table["c"] in (0.05, 0.1) and table["d_bar"] == 0.05
    evidence = json.loads(out.with_suffix(".json").read_text())
    assert evidence["schema"] == "isf-robot-sweep/1" and evidence["scenes"][0]["scene"] == "planar"
    chosen = [r for r in evidence["scenes"][0]["points"] if r["strategy"] == "isf" and r["values"]["c"] == table["c"]]
    assert len(chosen) == 1 and f"point {chosen[0]['label']}" in out.read_text()
    assert "Pareto" in out.with_suffix(".txt").read_text()
    assert "wrote" in capsys.readouterr().err


def test_every_sweep_parameter_has_its_flag_and_is_a_filter_field() -> None:
    assert tuple(_FLAGS) == PARAMETERS
    assert set(PARAMETERS) <= set(NAMES)
    assert all(flag == "--" + name.replace("_", "-") for name, flag in _FLAGS.items())
    # every design option the run and compare commands take is one a sweep can vary (off_hold was missing once);
    # d_bar is given once for all points, and the fall-rate memory has no flag anywhere
    run_flags = {a.dest for a in _parser("run")._actions if a.option_strings}
    design = {n for n in NAMES if n in run_flags} - {"d_bar"}
    assert design == set(PARAMETERS) and "off_hold" in PARAMETERS
    assert not {"fall_rate_prior", "fall_rate_forget"} & run_flags


def _parser(command: str):  # type: ignore[no-untyped-def]
    import argparse

    from isf_robot.cli import build_parser

    root = build_parser()
    sub = next(a for a in root._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[command]


def test_a_sweep_over_off_hold_runs_each_value(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["sweep", "--scenes", "planar", "--filters", "isf", "--episodes", "1", "--duration", "0.3",
                 "--d-bar", "0.05", "--off-hold", "0,0.2", "--json", "--quiet"]) == 0
    points = json.loads(capsys.readouterr().out)["scenes"][0]["points"]
    assert [p["values"] for p in points] == [{"off_hold": 0.0}, {"off_hold": 0.2}]
    assert [p["runs"][0]["off_hold"] for p in points] == [0.0, 0.2]  # (what each run's filter was given)


def test_sweep_at_the_torque_level_runs_that_level_and_says_so(capsys, tmp_path) -> None:  # type: ignore[no-untyped-def]
    pts = [SweepPoint("cbf"), SweepPoint("isf", {"c": 0.5})]
    sweep = run_sweep([SceneSpec(name="ur5e_pole")], pts, [0], duration=0.4, d_bar=0.3, level="torque")
    assert sweep["level"] == "torque"
    runs = [r for p in sweep["scenes"][0]["points"] for r in p["runs"]]
    assert len(runs) == 2 and all(r["level"] == "torque" for r in runs)
    assert all(r["d_bar"] == 0.3 for r in runs)
    with pytest.raises(ConfigError, match="unknown level"):
        run_sweep([SceneSpec(name="ur5e_pole")], pts, [0], duration=0.4, d_bar=0.3, level="force")
    assert main(["sweep", "--scenes", "ur5e_pole", "--level", "torque", "--episodes", "1",
                 "--write-config", str(tmp_path / "x.toml")]) == 2
    assert "velocity level" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())  # nothing written


@pytest.mark.parametrize("bad", [2.9, 0.5, 0.0, float("nan")])
def test_a_grid_refuses_a_predict_every_that_is_not_a_whole_number_of_steps(bad: float) -> None:
    """(It was truncated: a point labelled predict_every=2.9 ran with 2.)"""
    with pytest.raises(ConfigError, match="--predict-every takes whole numbers"):
        grid_points(["isf"], {"predict_every": [2.0, bad]})
    assert [p.values["predict_every"] for p in grid_points(["isf"], {"predict_every": [2.0, 3.0]})] == [2.0, 3.0]
