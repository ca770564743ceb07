"""The tabulated polyhedron field: accuracy against the exact field, continuity, files, fallback."""

from __future__ import annotations

import numpy as np
import pytest

from satellite.errors import GravityModelError
from satellite.gravity_table import GravityTable, TableGrid, bspline3, build_table
from satellite.polyhedron import PolyhedronField

GM = 2.0


@pytest.fixture(scope="module")
def body(helpers):  # type: ignore[no-untyped-def]
    mesh = helpers.lumpy_body()
    field = PolyhedronField.from_mesh(mesh, GM)
    rb = float(np.linalg.norm(mesh.vertices - mesh.centre_of_mass, axis=1).max())
    return field, rb


@pytest.fixture(scope="module")
def tables(body):  # type: ignore[no-untyped-def]
    field, rb = body
    return {n: build_table(field, TableGrid(1.2 * rb, 2.0 * rb, 9, n), rb) for n in (12, 24)}


def shell_points(rb: float, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    return u * rng.uniform(1.35 * rb, 1.85 * rb, n)[:, None]


def test_bspline_weights_reproduce_lines_and_join_c2() -> None:
    t = np.linspace(0, 1, 7)
    w = np.stack(bspline3(t))
    np.testing.assert_allclose(w.sum(axis=0), 1.0, atol=1e-15)
    nodes = np.array([-1.0, 0.0, 1.0, 2.0])
    np.testing.assert_allclose(nodes @ w, t, atol=1e-15)  # linear functions exactly
    # C2 across a cell face: value, slope and curvature of cell i at t=1 equal cell i+1's at t=0
    c = np.random.default_rng(0).normal(size=5)
    eps = 1e-4

    def f(cell: int, x: float) -> float:
        return float(np.dot(c[cell: cell + 4], bspline3(x)))

    for d in (lambda g, x: g(x), lambda g, x: (g(x + eps) - g(x - eps)) / (2 * eps),
              lambda g, x: (g(x + eps) - 2 * g(x) + g(x - eps)) / eps**2):
        assert d(lambda x: f(0, x), 1.0) == pytest.approx(d(lambda x: f(1, x), 0.0), rel=1e-5, abs=1e-6)


def test_table_converges_to_the_exact_field(body, tables) -> None:  # type: ignore[no-untyped-def]
    field, rb = body
    p = shell_points(rb, 300, 0)
    exact = field.acceleration(p)
    nonkep = np.linalg.norm(exact + GM * p / (np.linalg.norm(p, axis=1) ** 3)[:, None], axis=1)
    err = {n: np.linalg.norm(t.acceleration_batch(p) - exact, axis=1) / nonkep for n, t in tables.items()}
    assert err[24].max() < 0.01
    assert err[24].max() < err[12].max() / 4  # fourth order: halving the cells cuts the error ~16x


def test_scalar_and_batch_paths_agree_and_poles_and_seam_are_continuous(body, tables) -> None:  # type: ignore[no-untyped-def]
    _, rb = body
    tab = tables[24]
    p = shell_points(rb, 50, 1)
    one = np.array([tab.acceleration(q) for q in p])
    np.testing.assert_allclose(one, tab.acceleration_batch(p), rtol=1e-12, atol=1e-20)
    e = 1e-9 * rb
    seam = [tab.acceleration(np.array(q)) for q in ([-1.5 * rb, e, 0.1 * rb], [-1.5 * rb, -e, 0.1 * rb])]
    np.testing.assert_allclose(seam[0], seam[1], rtol=1e-6)  # longitude +-180 deg: continuous
    # at a pole the value depends on the longitude of approach, by less than the table's error
    field = body[0]
    for z in (1.5 * rb, -1.5 * rb):
        pts = np.array([[e, 0, z], [-e, e, z], [0, -e, z]])
        exact = field.acceleration(pts)[0]
        nonkep = np.linalg.norm(exact + GM * pts[0] / np.linalg.norm(pts[0]) ** 3)
        got = tab.acceleration_batch(pts)
        assert np.linalg.norm(got - exact, axis=1).max() < 0.01 * nonkep


def test_outside_the_radii_the_exact_field_answers(body, tables) -> None:  # type: ignore[no-untyped-def]
    field, rb = body
    tab = tables[12]
    far = np.array([[3.0 * rb, 0.0, 0.0], [0.0, 0.0, 0.5 * rb]])
    np.testing.assert_array_equal(tab.acceleration_batch(far), field.acceleration(far))
    bare = GravityTable(tab.grid, tab.values, tab.r_ref_m, tab.gm)
    with pytest.raises(GravityModelError, match="outside the table"):
        bare.acceleration(far[0])


def test_file_round_trip_and_bad_files(tables, tmp_path) -> None:  # type: ignore[no-untyped-def]
    tab = tables[12]
    path = tmp_path / "t.npz"
    tab.save(path)
    back = GravityTable.load(path)
    np.testing.assert_array_equal(back.values, tab.values)
    assert back.grid.describe() == tab.grid.describe() and back.gm == tab.gm
    assert sorted(x.name for x in tmp_path.iterdir()) == ["t.npz"]  # no temporary file left
    (tmp_path / "bad.npz").write_bytes(b"not a table")
    with pytest.raises(GravityModelError, match="not a gravity table"):
        GravityTable.load(tmp_path / "bad.npz")
    with pytest.raises(GravityModelError, match="bad table grid"):
        TableGrid(2.0, 1.0, 9, 12)
