"""Bad command lines through both command lines: exit status 2, one line on stderr, no traceback,
and an output file that existed before is byte-identical afterwards (nothing is lost).

Every case fails before any simulation starts (validation comes first), so the table runs in
seconds. ``OUT`` in a command stands for a file that holds a previous good result.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from isf_robot.cli import main as robot_main
from satellite.cli import main as satellite_main

PREVIOUS = b"previous good result\n"

ROBOT = [
    # scene selection and files
    ["run", "--scene", "no_such_scene"],
    ["run"],
    ["run", "--scene", "planar", "--model", "x.xml", "--config", "x.toml"],
    ["run", "--model", "MISSING.xml", "--config", "MISSING.toml"],
    ["run", "--model", "DIR", "--config", "DIR"],
    ["run", "--scene", "planar", "--filter", "nonsense"],
    # numbers
    ["run", "--scene", "planar", "--alpha", "-1", "--rrd", "OUT"],
    ["run", "--scene", "planar", "--alpha", "0", "--d-bar", "0.1"],
    ["run", "--scene", "planar", "--alpha", "nan", "--d-bar", "0.1"],
    ["run", "--scene", "planar", "--c", "0", "--d-bar", "0.1", "--rrd", "OUT"],
    ["run", "--scene", "planar", "--b", "-0.1", "--d-bar", "0.1"],
    ["run", "--scene", "planar", "--d-bar", "-1"],
    ["run", "--scene", "planar", "--d-bar", "inf"],
    ["run", "--scene", "planar", "--duration", "-1", "--d-bar", "0.1", "--rrd", "OUT"],
    ["run", "--scene", "planar", "--duration", "0", "--d-bar", "0.1"],
    ["run", "--scene", "planar", "--duration", "nan", "--d-bar", "0.1"],
    ["run", "--scene", "planar", "--duration", "1e300", "--d-bar", "0.1", "--rrd", "OUT"],
    ["run", "--scene", "planar", "--duration", "1e9", "--d-bar", "0.1"],
    ["run", "--scene", "planar", "--control-period", "0.0015", "--d-bar", "0.1"],
    ["run", "--scene", "planar", "--control-period", "-0.002", "--d-bar", "0.1"],
    ["run", "--scene", "planar", "--seed", "-3", "--rrd", "OUT"],
    ["run", "--scene", "planar", "--seed", "1.5"],
    ["run", "--scene", "planar", "--duration", "abc"],
    ["run", "--scene", "planar", "--unknown-flag"],
    # outputs
    ["run", "--scene", "planar", "--d-bar", "0.1", "--duration", "0.01", "--rrd", "DIR"],
    ["run", "--scene", "planar", "--d-bar", "0.1", "--duration", "0.01", "--rrd", "/dev/null"],
    ["compare", "--scene", "planar", "--d-bar", "0.1", "--rrd", "OUT"],
    # compare
    ["compare", "--scene", "planar", "--episodes", "0"],
    ["compare", "--scene", "planar", "--episodes", "-2"],
    ["compare", "--scene", "planar", "--episodes", "1e9"],
    ["compare", "--scene", "planar", "--episodes", "1000000000", "--d-bar", "0.1"],
    ["compare", "--scene", "planar", "--jobs", "0"],
    ["compare", "--scene", "planar", "--jobs", "1000000000000000000"],
    ["compare", "--scene", "planar", "--filters", "cbf", "cbf", "--d-bar", "0.1"],
    ["compare", "--scene", "planar", "--filters", "bogus"],
    ["compare", "--scene", "planar", "--seed", "-1"],
    ["compare", "--scene", "planar", "--duration", "-5", "--d-bar", "0.1"],
    # replay
    ["replay", "MISSING.rrd"],
    ["replay", "OUT"],
    ["replay", "EMPTYDIR"],
    # core demo
    ["core-demo", "--episodes", "0"],
    ["core-demo", "--duration", "1e12"],
    ["core-demo", "--duration", "-1"],
    ["core-demo", "--seed", "-1"],
    # no command
    ["no-such-command"],
]

SATELLITE = [
    ["run", "--hours", "0"],
    ["run", "--hours", "-5"],
    ["run", "--hours", "nan"],
    ["run", "--trigger", "bogus"],
    ["run", "--radius", "5", "--hours", "1"],
    ["run", "--c", "1e9", "--hours", "1", "--rrd", "OUT"],
    ["run", "--alpha-gain", "-1", "--hours", "1", "--rrd", "OUT"],
    ["run", "--d-bar", "-1", "--hours", "1"],
    ["run", "--trigger", "maneuver", "--tau", "MISSING.json", "--hours", "1"],
    ["run", "--trigger", "maneuver", "--tau", "OUT", "--hours", "1"],
    ["run", "--gravity", "MISSING.json", "--hours", "1"],
    ["run", "--gravity", "DIR", "--hours", "1"],
    ["run", "--gravity", "sh9", "--hours", "1"],
    ["run", "--trigger", "periodic", "--hours", "1"],
    ["run", "--trigger", "greedy", "--period-h", "1", "--hours", "1"],
    ["run", "--trigger", "periodic", "--period-h", "-1", "--hours", "1"],
    ["run", "--controller", "bogus", "--hours", "1"],
    ["run", "--period-at-start", "--hours", "1"],
    ["run", "--shoot-horizon-h", "2", "--hours", "1"],
    ["run", "--controller", "shooting", "--shoot-grid", "4", "--hours", "1"],
    ["run", "--controller", "shooting", "--shoot-dv-max", "-1", "--hours", "1"],
    ["tau", "--controller", "bogus", "--samples", "1", "--out", "OUT"],
    ["tau", "--gravity", "exact", "--samples", "1", "--out", "OUT"],
    ["gravity", "--shape", "MISSING.obj", "--out", "OUT"],
    ["gravity", "--shape", "DIR", "--out", "OUT"],
    ["gravity", "--degree", "99", "--out", "OUT"],
    ["tau", "--samples", "0", "--out", "OUT"],
    ["tau", "--degree", "-1", "--out", "OUT"],
    ["tau", "--degree", "50", "--samples", "2", "--out", "OUT"],
    ["tau", "--samples", "2", "--out", "DIR"],
]


def _argv(argv: list[str], tmp_path: Path) -> tuple[list[str], Path]:
    out = tmp_path / "previous.json"
    out.write_bytes(PREVIOUS)
    (tmp_path / "dir").mkdir()
    (tmp_path / "emptydir").mkdir()
    subst = {"OUT": str(out), "DIR": str(tmp_path / "dir"), "EMPTYDIR": str(tmp_path / "emptydir"),
             "MISSING.xml": str(tmp_path / "missing.xml"), "MISSING.toml": str(tmp_path / "missing.toml"),
             "MISSING.rrd": str(tmp_path / "missing.rrd"), "MISSING.json": str(tmp_path / "missing.json"),
             "MISSING.obj": str(tmp_path / "missing.obj")}
    return [subst.get(a, a) for a in argv], out


def _check(main, argv: list[str], tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    args, out = _argv(argv, tmp_path)
    try:
        code = main(args)
    except SystemExit as exc:  # argparse's own usage errors
        code = exc.code
    cap = capsys.readouterr()
    err = cap.err.strip()
    assert code == 2, (args, code, err)
    assert err and "\n" not in err, (args, err)
    assert "Traceback" not in err and "error" in err, (args, err)
    assert out.read_bytes() == PREVIOUS, f"{args} changed a previous output file"
    assert not any(p.name.endswith(".partial") for p in tmp_path.iterdir()), list(tmp_path.iterdir())


@pytest.mark.parametrize("argv", ROBOT, ids=lambda a: " ".join(a))
def test_isf_robot_bad_input(argv: list[str], tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    _check(robot_main, argv, tmp_path, capsys)


@pytest.mark.parametrize("argv", SATELLITE, ids=lambda a: " ".join(a))
def test_isf_satellite_bad_input(argv: list[str], tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    _check(satellite_main, argv, tmp_path, capsys)


def test_the_table_is_large_enough() -> None:
    assert len(ROBOT) + len(SATELLITE) >= 40
