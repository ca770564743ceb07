"""Gravity models by name: the committed table against the exact field, names, errors."""

from __future__ import annotations

import numpy as np
import pytest

from satellite.errors import GravityModelError
from satellite.gravity.fields import DEFAULT_GRAVITY, exact_itokawa, load_field, model_name
from satellite.gravity.spherical import GravityField
from satellite.gravity.table import GravityTable, TableGrid


def test_names_and_errors() -> None:
    assert DEFAULT_GRAVITY == "table"
    sh8 = load_field("sh8")
    assert isinstance(sh8, GravityField) and model_name(sh8) == "sh8"
    table = load_field("table")
    assert model_name(table) == "polyhedron-table" and table.fine is not None and len(table.fine) >= 2
    assert load_field("table") is table  # read once per process
    assert table.r_ref_m == pytest.approx(sh8.r_ref_m) and table.gm == pytest.approx(sh8.gm)
    assert "shape_sha256" in table.provenance and "Gaskell" in table.provenance["citation"]
    with pytest.raises(GravityModelError, match="valid: table, sh8, polyhedron, FILE.json or FILE.npz"):
        load_field("sh9")


def test_a_table_file_of_another_body_loads_without_an_exact_field(tmp_path) -> None:  # type: ignore[no-untyped-def]
    grid = TableGrid(10.0, 20.0, 5, 4)
    GravityTable(grid, np.zeros((5, 4, 8, 3)), 7.0, 1.5).save(tmp_path / "t.npz")
    table = load_field(str(tmp_path / "t.npz"))
    p = np.array([12.0, 3.0, 4.0])
    np.testing.assert_allclose(table.acceleration(p), -1.5 * p / np.linalg.norm(p) ** 3, rtol=1e-12)  # Kepler + 0
    assert table.exact is None
    far = np.array([30.0, 0.0, 0.0])  # outside its radii: its continuation (of a zero table: Kepler alone)
    np.testing.assert_allclose(table.acceleration(far), -1.5 * far / np.linalg.norm(far) ** 3, rtol=1e-12)
    with pytest.raises(GravityModelError, match="not found"):
        load_field(str(tmp_path / "missing.npz"))


def test_committed_table_is_within_one_percent_of_the_exact_field() -> None:
    """Random band points outside the body, half of them near the long axis where the surface reaches in."""
    exact = exact_itokawa()  # the shipped shape
    table = load_field("table")
    rng = np.random.default_rng(7)
    u = rng.normal(size=(60, 3))
    u[:30, 1:] *= 0.2
    u /= np.linalg.norm(u, axis=1)[:, None]
    p = u * rng.uniform(1.6, 2.4, len(u))[:, None] * table.r_ref_m
    v = exact.field.evaluate(p)
    out = v.solid_angle < 2 * np.pi
    p, a = p[out], v.acceleration[out]
    assert len(p) > 40
    nonkep = np.linalg.norm(a + table.gm * p / (np.linalg.norm(p, axis=1) ** 3)[:, None], axis=1)
    err = np.linalg.norm(table.acceleration_batch(p) - a, axis=1) / nonkep
    assert err.max() < 0.01
    one = np.array([table.acceleration(q) for q in p[:10]])
    np.testing.assert_allclose(one, table.acceleration_batch(p[:10]), rtol=1e-12, atol=1e-20)
    sh8 = load_field("sh8")  # the paper's series is the model that fails here (inside 1.925 R)
    err8 = np.linalg.norm(sh8.acceleration_batch(p) - a, axis=1) / nonkep
    assert err8.max() > 0.05


def test_committed_table_is_within_one_percent_of_the_exact_field_near_the_surface() -> None:
    """Points outside the body within 10 m of the long-axis tips (where the fine boxes answer), some within 1 m."""
    from satellite.shape.closest import ClosestPoints

    exact = exact_itokawa()  # the shipped shape
    table = load_field("table")
    v = exact.field.vertices
    tips = v[np.linalg.norm(v, axis=1) > 1.7 * table.r_ref_m]
    rng = np.random.default_rng(11)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    p = tips[rng.integers(len(tips), size=400)] + u * rng.uniform(0.0, 10.0, 400)[:, None]
    d = ClosestPoints(v, exact.field.faces).query(p)[1]
    p, d = p[d < 10.0][:80], d[d < 10.0][:80]
    val = exact.field.evaluate(p)
    out = val.solid_angle < 2 * np.pi
    p, a, d = p[out], val.acceleration[out], d[out]
    assert len(p) > 25 and (d < 1.0).sum() >= 3
    nonkep = np.linalg.norm(a + table.gm * p / (np.linalg.norm(p, axis=1) ** 3)[:, None], axis=1)
    err = np.linalg.norm(np.array([table.acceleration(tuple(q)) for q in p.tolist()]) - a, axis=1) / nonkep
    assert err.max() < 0.01
    shell = GravityTable(table.grid, table.values, table.r_ref_m, table.gm)  # the shell spline alone fails here
    err_shell = np.linalg.norm(shell.acceleration_batch(p) - a, axis=1) / nonkep
    assert err_shell.max() > 0.03


def test_polyhedron_with_a_users_shape(helpers, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """``--gravity polyhedron --shape FILE``: the exact field of that file (GM and R of the Itokawa series)."""
    import json

    from satellite.cli import main

    v, f = helpers.box_mesh(200.0, 150.0, 120.0)
    path = helpers.write_obj(tmp_path / "box.obj", v, f)
    field = load_field("polyhedron", shape=path, units="m")
    assert field.field.faces.shape == (12, 3) and field.gm == load_field("sh8").gm
    assert load_field("polyhedron").field.faces.shape == (49152, 3)  # without --shape: the shipped shape
    p = np.array([[400.0, 0.0, 0.0]])
    assert not np.allclose(field.acceleration_batch(p), load_field("polyhedron").acceleration_batch(p), rtol=1e-3)
    code = main(["run", "--gravity", "polyhedron", "--shape", str(path), "--shape-units", "m", "--hours", "0.05",
                 "--contact", "off", "--json", "--quiet"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["simulated_h"] == pytest.approx(0.05) and out["settings"]["gravity_model"] == "polyhedron"
