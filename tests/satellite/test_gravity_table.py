"""The tabulated polyhedron field: accuracy against the exact field, continuity, files, the continuation outside."""

from __future__ import annotations

import numpy as np
import pytest

from satellite.errors import GravityModelError
from satellite.gravity.polyhedron import PolyhedronField
from satellite.gravity.splines import bspline3, dbspline3
from satellite.gravity.table import GravityTable, TableGrid, build_table, shell_continued, shell_spline

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


def _shell(tab: GravityTable, p: np.ndarray) -> np.ndarray:
    g = tab.grid
    return np.array(shell_continued(*p.tolist(), tab._ext, g.r_lo, g.r_hi, tab._inv_dr, tab._inv_dang, g.n_r))


def test_dbspline_weights_are_the_derivatives() -> None:
    t = np.linspace(0.0, 1.0, 11)
    e = 1e-6
    num = (np.array(bspline3(t + e)) - np.array(bspline3(t - e))) / (2 * e)
    np.testing.assert_allclose(np.array(dbspline3(t)), num, atol=1e-9)
    np.testing.assert_allclose(np.array(dbspline3(t)).sum(axis=0), 0.0, atol=1e-15)


def test_continuation_meets_the_table_at_its_ends(body, tables) -> None:  # type: ignore[no-untyped-def]
    """Continuous at the radii (the same spline on both sides) and at the end nodes; C1 at the end nodes."""
    _, rb = body
    tab = tables[24]
    g = tab.grid
    rng = np.random.default_rng(5)
    u = rng.normal(size=(40, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    r_in, r_out = tab.fast_radii
    for q in u:
        for r0 in (r_in, r_out):  # the table's own path inside, the continuation's just outside
            out = r0 * (1 + 1e-12) if r0 == r_out else r0 * (1 - 1e-12)
            a_in, a_out = tab.acceleration(q * r0), tab.acceleration(q * out)
            assert np.abs(a_out - a_in).max() <= 1e-9 * np.abs(a_in).max()
        for r0, sgn in ((g.r_lo, -1.0), (g.r_hi, 1.0)):  # the spline meets the radial continuation
            e = 1e-4 * g.dr
            f0 = _shell(tab, q * r0)
            fi1, fi2 = _shell(tab, q * (r0 - sgn * e)), _shell(tab, q * (r0 - 2 * sgn * e))
            fo1, fo2 = _shell(tab, q * (r0 + sgn * e)), _shell(tab, q * (r0 + 2 * sgn * e))
            scale = np.abs(f0).max()
            assert np.abs(_shell(tab, q * r0 * (1 + sgn * 1e-12)) - f0).max() <= 1e-9 * scale  # value
            slope_in = sgn * (3 * f0 - 4 * fi1 + fi2) / (2 * e)  # one-sided, second order
            slope_out = sgn * (-3 * f0 + 4 * fo1 - fo2) / (2 * e)
            assert np.abs(slope_in - slope_out).max() <= 1e-6 * scale / r0  # slope (measured <= 2e-8)
            assert np.abs(slope_in).max() > 1e-2 * scale / r0  # a slope worth matching


def test_continuation_is_used_only_outside_the_radii(body, tables) -> None:  # type: ignore[no-untyped-def]
    field, rb = body
    tab = tables[12]
    r_in, r_out = tab.fast_radii
    rng = np.random.default_rng(8)
    u = rng.normal(size=(60, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    inside = u * np.concatenate([[r_in, r_out], rng.uniform(r_in, r_out, 58)])[:, None]
    outside = u[:6] * np.array([0.9 * r_in, np.nextafter(r_in, 0.0), 0.5 * (tab.grid.r_lo + r_in),
                                np.nextafter(r_out, np.inf), tab.grid.r_hi, 1.5 * r_out])[:, None]
    g = tab.grid

    def expected(p, continued):  # type: ignore[no-untyped-def]
        x, y, z = p.tolist()
        if continued:
            s = shell_continued(x, y, z, tab._ext, g.r_lo, g.r_hi, 1.0 / g.dr, 1.0 / g.dang, g.n_r)
        else:
            s = shell_spline(x, y, z, float(np.linalg.norm(p)), tab._ext, g.r_lo, 1.0 / g.dr, 1.0 / g.dang, g.n_r)
        return np.array(s) - tab.gm * p / np.linalg.norm(p) ** 3

    for pts, continued in ((inside, False), (outside, True)):
        want = np.array([expected(p, continued) for p in pts])
        np.testing.assert_allclose(np.array([tab.acceleration(p) for p in pts]), want, rtol=1e-12, atol=0.0)
        np.testing.assert_allclose(tab.acceleration_batch(pts), want, rtol=1e-12, atol=0.0)
    got = tab.acceleration_batch(outside)
    # the radial continuation against the exact field (the lumpy body's table: 9 radii over 0.8 rb; measured <= 1 %)
    near = u * rng.choice([0.97 * tab.grid.r_lo, 1.05 * tab.grid.r_hi], len(u))[:, None]  # beyond the end nodes
    exact = field.acceleration(near)
    nonkep = np.linalg.norm(exact + GM * near / (np.linalg.norm(near, axis=1) ** 3)[:, None], axis=1)
    assert (np.linalg.norm(tab.acceleration_batch(near) - exact, axis=1) / nonkep).max() < 0.02
    bare = GravityTable(tab.grid, tab.values, tab.r_ref_m, tab.gm)  # no exact field: the table still answers
    np.testing.assert_array_equal(bare.acceleration_batch(outside), got)


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


def test_committed_table_is_a_potential_field_outside_the_body() -> None:
    """Outside the body the field is a gradient (symmetric Jacobian) and harmonic (zero trace): central differences.

    The shell spline, the fine boxes and Kepler each interpolate their own components, so both hold to the
    interpolation error (measured <= 4e-3 of the Jacobian's size at band points); a wrong weight, index or
    component in :func:`satellite.gravity.table.table_acceleration` breaks them at order one.
    """
    from satellite.gravity.fields import load_field
    from satellite.shape.mesh_surface import load_surface

    tab = load_field("table")
    rng = np.random.default_rng(0)
    u = rng.normal(size=(40, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    pts = u * rng.uniform(1.6, 2.4, size=40)[:, None] * tab.r_ref_m
    pts = np.vstack([pts, [[s * x, 0.0, 0.0] for s in (-1, 1) for x in (300.0, 320.0)]])  # the long axis' tips
    pts = pts[~load_surface().inside(pts)]
    assert len(pts) > 30 and any(tab.fine.at(*p.tolist()) is not None for p in pts)  # the boxes are exercised

    def nonkep(p):  # type: ignore[no-untyped-def]
        return tab.acceleration(p) + tab.gm * p / np.linalg.norm(p) ** 3

    step = 0.05
    for p in pts:
        jac = np.array([(nonkep(p + step * e) - nonkep(p - step * e)) / (2 * step) for e in np.eye(3)]).T
        size = np.linalg.norm(jac)
        assert np.linalg.norm(jac - jac.T) < 2e-2 * size, p
        assert abs(np.trace(jac)) < 2e-2 * size, p
