from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from satellite.cli import SUBCOMMAND_MODULES, build_parser, main
from satellite.gravity.spherical import G_CODATA2018, GravityField


@pytest.fixture
def box_obj(tmp_path, helpers):
    v, f = helpers.box_mesh(0.3, 0.2, 0.1)  # km
    return helpers.write_obj(tmp_path / "box.obj", v, f)


def test_gravity_command_writes_table(box_obj, tmp_path, capsys):
    out = tmp_path / "g.json"
    assert (
        main(
            [
                "gravity",
                "--shape",
                str(box_obj),
                "--degree",
                "4",
                "--mass",
                "1e9",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    data = json.loads(out.read_text())
    assert data["degree"] == 4
    assert data["gm"] == pytest.approx(G_CODATA2018 * 1e9)
    assert data["r_ref_m"] == pytest.approx((3 * 300 * 200 * 100 / (4 * np.pi)) ** (1 / 3))
    assert len(data["C"]) == 5 and len(data["S"][4]) == 5
    assert data["C"][0][0] == 1.0
    assert data["provenance"]["shape_sha256"] and "--degree 4" in data["provenance"]["generator"]
    assert GravityField.from_json(out).degree == 4
    assert "wrote" in capsys.readouterr().out


def test_units_option_scales_the_mesh(box_obj, tmp_path):
    out = tmp_path / "m.json"
    assert (
        main(
            ["gravity", "--shape", str(box_obj), "--degree", "0", "--units", "m", "--out", str(out)]
        )
        == 0
    )
    assert json.loads(out.read_text())["r_ref_m"] == pytest.approx(
        (3 * 0.006 / (4 * np.pi)) ** (1 / 3)
    )


@pytest.mark.parametrize(
    ("extra", "pattern"),
    [
        (["--degree", "-1"], "--degree must be in 0..20"),
        (["--degree", "99"], "--degree must be in 0..20"),
        (["--degree", "2", "--mass", "-5"], "--mass must be a positive"),
        (["--degree", "2", "--mass", "nan"], "--mass must be a positive"),
        (["--table", "--fine-step", "100"], "--fine-step must be 0 (no fine boxes) or in [0.5, 20] m"),
        (["--table", "--refine-step", "0.1"], "--refine-step must be 0 (no second level) or in [0.5, 10] m"),
        (["--table", "--fine-step", "0"], "--refine-step needs a table with fine boxes"),
    ],
)
def test_bad_parameters_exit_2_with_one_line(box_obj, tmp_path, capsys, extra, pattern):
    code = main(["gravity", "--shape", str(box_obj), *extra, "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err
    assert code == 2
    assert pattern in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "x.json").exists()


def test_missing_file_and_open_mesh_exit_2(tmp_path, capsys, helpers):
    code = main(
        [
            "gravity",
            "--shape",
            str(tmp_path / "nope.obj"),
            "--degree",
            "2",
            "--out",
            str(tmp_path / "x.json"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "shape file not found" in err and err.count("\n") == 1
    v, f = helpers.box_mesh()
    opened = helpers.write_obj(tmp_path / "open.obj", v, f[:-2])
    code = main(
        ["gravity", "--shape", str(opened), "--degree", "2", "--out", str(tmp_path / "x.json")]
    )
    err = capsys.readouterr().err
    assert code == 2 and "not closed" in err and err.count("\n") == 1


def test_help_lists_gravity_and_parser_is_extensible(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    assert "gravity" in capsys.readouterr().out
    assert SUBCOMMAND_MODULES[0] == "satellite.cli.gravity"
    parser = build_parser()
    args = parser.parse_args(["gravity", "--shape", "a.obj", "--degree", "3", "--out", "b.json"])
    assert args.mass == 3.51e10 and args.units == "km" and callable(args.func)


def test_console_entry_runs_without_traceback(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "satellite.cli", "gravity", "--shape", str(tmp_path / "nope.obj"),
         "--degree", "2", "--out", str(tmp_path / "x.json")],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert proc.returncode == 2
    assert proc.stderr.strip().startswith("isf-satellite gravity: error: shape file not found")


def test_gravity_table_command(tmp_path, helpers, capsys):
    from satellite.gravity.polyhedron import PolyhedronField
    from satellite.gravity.table import GravityTable
    from satellite.shape.cache import read_obj

    v, f = helpers.icosphere(1)
    obj = helpers.write_obj(tmp_path / "ball.obj", v * np.array([1.5, 1.0, 0.8]) * 100.0, f)  # metres
    out = tmp_path / "t.npz"
    argv = ["gravity", "--table", "--shape", str(obj), "--units", "m", "--mass", "1e10", "--n-lat", "8",
            "--n-r", "5", "--out", str(out)]
    assert main(argv) == 0
    assert "5 x 8 x 16 nodes" in capsys.readouterr().out
    table = GravityTable.load(out)
    mesh = read_obj(obj, units="m")
    exact = PolyhedronField.from_mesh(mesh, G_CODATA2018 * 1e10)
    nodes = table.grid.nodes()
    got = table.values[1, 3, 5] - G_CODATA2018 * 1e10 * nodes[1, 3, 5] / np.linalg.norm(nodes[1, 3, 5]) ** 3
    np.testing.assert_allclose(got, exact.acceleration(nodes[1, 3, 5][None])[0], rtol=1e-12)
    assert table.provenance["generator"].startswith("isf-satellite gravity --table")
    assert table.fine is not None and "--fine-step 4 --refine-step 2" in table.provenance["generator"]  # default
    assert set(table.fine.steps) == {4.0, 2.0}  # its tips come within a stencil of the band: two levels
    assert table.r_ref_m == pytest.approx(mesh.volume_equivalent_radius)
    assert main(["gravity", "--shape", str(obj), "--out", str(tmp_path / "x.json")]) == 2
    assert "--degree N is required" in capsys.readouterr().err
