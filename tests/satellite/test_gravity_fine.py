"""Fine correction boxes of the gravity table: accuracy near the surface, C2 hand-over, inside the body, files."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satellite.errors import GravityModelError
from satellite.gravity.fine import FineBoxes, add_fine_level, build_fine_boxes
from satellite.gravity.polyhedron import PolyhedronField
from satellite.gravity.table import GravityTable, TableGrid, build_table
from satellite.shape.closest import ClosestPoints, closest_on_triangles

GM = 2.0
STEP, D_FULL, D_ZERO = 6.0, 12.0, 20.0


@pytest.fixture(scope="module")
def body(helpers):  # type: ignore[no-untyped-def]
    """A prolate body (tips at 200 m) whose ends poke through a shell table over [150, 250] m."""
    v, f = helpers.icosphere(2)
    return PolyhedronField(v * np.array([200.0, 100.0, 80.0]), f, GM)


def inside(body, p):  # type: ignore[no-untyped-def]
    return body.evaluate(p).solid_angle > 2 * np.pi


@pytest.fixture(scope="module")
def tables(body):  # type: ignore[no-untyped-def]
    grid = TableGrid(150.0, 250.0, 9, 12)
    plain = build_table(body, grid, 100.0)
    fine = build_fine_boxes(plain, body.acceleration, body.vertices, body.faces, lambda p: inside(body, p),
                            body.g_rho, step=STEP, d_full=D_FULL, d_zero=D_ZERO)
    assert fine is not None and len(fine) >= 1
    return plain, GravityTable(grid, plain.values, 100.0, GM, body, None, None, fine)


def near_surface_points(body, n: int, seed: int, dmax: float):  # type: ignore[no-untyped-def]
    """Points outside the body within ``dmax`` of the surface near the tips, in the table's radii."""
    rng = np.random.default_rng(seed)
    tips = body.vertices[np.linalg.norm(body.vertices, axis=1) > 165.0]
    cp = ClosestPoints(body.vertices, body.faces)
    p = tips[rng.integers(len(tips), size=8 * n)] + rng.normal(size=(8 * n, 3)) * 0.6 * dmax
    r = np.linalg.norm(p, axis=1)
    p = p[(r > 165.0) & (r < 235.0)]
    d = cp.query(p)[1]
    p = p[(d < dmax) & ~inside(body, p)][:n]
    return p, body.acceleration(p), cp.query(p)[1]


def test_closest_points_match_every_face(body) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(1)
    p = rng.normal(size=(40, 3)) * 150.0
    cp, d = ClosestPoints(body.vertices, body.faces, k=24).query(p)
    tri = body.vertices[body.faces]
    for q, c, dq in zip(p, cp, d):
        all_cp = closest_on_triangles(np.repeat(q[None], len(tri), 0), tri[:, 0], tri[:, 1], tri[:, 2])
        brute = np.linalg.norm(all_cp - q, axis=1)
        assert dq == pytest.approx(brute.min(), rel=1e-12, abs=1e-9)
        assert np.linalg.norm(c - q) == pytest.approx(dq, rel=1e-12)
    # a point above the middle of a face projects onto it
    a, b, c = tri[0]
    n = np.cross(b - a, c - a)
    mid = (a + b + c) / 3 + 5.0 * n / np.linalg.norm(n)
    np.testing.assert_allclose(closest_on_triangles(mid[None], a[None], b[None], c[None])[0], (a + b + c) / 3,
                               atol=1e-9)


def test_near_the_surface_the_boxes_follow_the_exact_field(body, tables) -> None:  # type: ignore[no-untyped-def]
    plain, fine = tables
    p, a, d = near_surface_points(body, 150, 2, D_FULL)
    assert len(p) > 100 and d.min() < 1.0
    nonkep = np.linalg.norm(a + GM * p / (np.linalg.norm(p, axis=1) ** 3)[:, None], axis=1)
    e_plain = np.linalg.norm(plain.acceleration_batch(p) - a, axis=1) / nonkep
    e_fine = np.linalg.norm(fine.acceleration_batch(p) - a, axis=1) / nonkep
    # a coarse body (edges of 30-40 m at large angles): the edges' log terms need the small step
    assert e_fine.max() < 0.02 < e_plain.max()
    assert e_fine.max() < e_plain.max() / 5, (e_fine.max(), e_plain.max())
    one = np.array([fine.acceleration(tuple(q)) for q in p[:20]])  # the scalar path is the batch path
    np.testing.assert_allclose(one, fine.acceleration_batch(p[:20]), rtol=1e-13, atol=1e-22)


def test_far_from_the_surface_the_boxes_change_nothing(body, tables) -> None:  # type: ignore[no-untyped-def]
    plain, fine = tables
    rng = np.random.default_rng(3)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    p = u * rng.uniform(165.0, 235.0, len(u))[:, None]
    d = ClosestPoints(body.vertices, body.faces).query(p)[1]
    far = d > D_ZERO + 2 * math.sqrt(3) * STEP + 2 * STEP
    assert far.sum() > 100
    diff = fine.acceleration_batch(p[far]) - plain.acceleration_batch(p[far])
    assert np.abs(diff).max() < 1e-5 * np.abs(fine.fine.values[0]).max()  # only the spline's ringing


def test_the_field_is_c2_across_cell_and_box_faces(body, tables) -> None:  # type: ignore[no-untyped-def]
    """One-sided second differences agree at a lattice plane (they would differ by the jump of a'' there)."""
    _, fine = tables
    boxes = fine.fine
    x0, y0, z0 = (float(c) * boxes.step for c in boxes.origins[0])
    nx, ny, nz = boxes.values[0].shape[:3]
    big = np.abs(boxes.values[0]).max(axis=3)
    ix, iy, iz = np.unravel_index(np.argmax(big), big.shape)  # the largest correction: the most curvature
    eps = 0.02 * STEP
    for plane in (ix, 1):  # a cell face inside the box, and the box's first usable plane
        xp = x0 + plane * STEP
        base = np.array([xp, y0 + (iy + 0.37) * STEP, z0 + (iz + 0.61) * STEP])

        def f(t: float) -> np.ndarray:
            return fine.fine.at_batch((base + [t, 0.0, 0.0])[None])[0]

        left = (f(0.0) - 2 * f(-eps) + f(-2 * eps)) / eps**2
        right = (f(2 * eps) - 2 * f(eps) + f(0.0)) / eps**2
        scale = np.abs(boxes.values[0]).max() / STEP**2
        assert np.abs(left - right).max() < 0.05 * scale
    # the interpolant passes through the node values (interpolating B-spline)
    node = np.array([x0 + ix * STEP, y0 + iy * STEP, z0 + iz * STEP])
    np.testing.assert_allclose(boxes.at(*node.tolist()), boxes.values[0][ix, iy, iz], rtol=1e-9,
                               atol=1e-12 * big.max())


def test_inside_the_body_the_field_is_finite_and_smooth(body, tables) -> None:  # type: ignore[no-untyped-def]
    _, fine = tables
    t = np.linspace(165.0, 205.0, 400)
    p = np.stack([t, 0.3 * (t - 150.0), 0.1 * (t - 150.0)], axis=1)  # from deep inside out through a tip
    assert inside(body, p[:10]).all() and not inside(body, p[-10:]).any()
    a = fine.acceleration_batch(p)
    assert np.isfinite(a).all()
    jump = np.abs(np.diff(a, axis=0)).max()
    assert jump < 5 * np.abs(np.diff(a, 2, axis=0)).max() * 400 / 40 + 1e-3 * np.abs(a).max() / 40


def test_boxes_survive_a_round_trip_and_bad_input_is_refused(body, tables, tmp_path) -> None:  # type: ignore[no-untyped-def]
    _, fine = tables
    fine.save(tmp_path / "t.npz")
    back = GravityTable.load(tmp_path / "t.npz", exact=body)
    assert back.fine is not None and len(back.fine) == len(fine.fine)
    p, _, _ = near_surface_points(body, 30, 5, D_ZERO)
    np.testing.assert_array_equal(back.acceleration_batch(p), fine.acceleration_batch(p))
    with pytest.raises(GravityModelError, match="positive number of metres"):
        FineBoxes(0.0, [])
    with pytest.raises(GravityModelError, match="shape"):
        FineBoxes(4.0, [((0, 0, 0), np.zeros((3, 5, 5, 3)))])
    with pytest.raises(GravityModelError, match="d_full < d_zero"):
        build_fine_boxes(fine, body.acceleration, body.vertices, body.faces, lambda q: inside(body, q),
                         body.g_rho, d_full=30.0, d_zero=20.0)


@pytest.fixture(scope="module")
def two_levels(body, tables):  # type: ignore[no-untyped-def]
    """The boxed table with a second level (half the step) within 6 m of the surface above r = 170 m."""
    _, fine = tables
    surface = type("Surface", (), {"vertices": body.vertices, "faces": body.faces,
                                   "query": staticmethod(lambda p: (inside(body, p),))})
    two = GravityTable(fine.grid, fine.values, 100.0, GM, body, None, None, fine.fine)
    add_fine_level(two, body, surface, step=STEP / 2, d_full=3.0, d_zero=6.0, r_band=170.0)
    assert len(two.fine) > len(fine.fine) and set(two.fine.steps) == {STEP, STEP / 2}
    return two


def test_a_second_level_follows_the_exact_field_closer_to_the_surface(body, tables, two_levels) -> None:  # type: ignore[no-untyped-def]
    _, fine = tables
    p, a, d = near_surface_points(body, 400, 7, 3.0)
    keep = np.linalg.norm(p, axis=1) >= 170.0
    p, a, d = p[keep], a[keep], d[keep]
    assert len(p) > 100 and d.min() < 0.5
    nonkep = np.linalg.norm(a + GM * p / (np.linalg.norm(p, axis=1) ** 3)[:, None], axis=1)
    e_one = np.linalg.norm(fine.acceleration_batch(p) - a, axis=1) / nonkep
    e_two = np.linalg.norm(two_levels.acceleration_batch(p) - a, axis=1) / nonkep
    assert e_two.max() < 0.6 * e_one.max(), (e_two.max(), e_one.max())
    assert np.median(e_two) < 0.6 * np.median(e_one), (np.median(e_two), np.median(e_one))
    one = np.array([two_levels.acceleration(tuple(q)) for q in p[:20]])  # the scalar path sums both levels too
    np.testing.assert_allclose(one, two_levels.acceleration_batch(p[:20]), rtol=1e-13, atol=1e-22)
    # beyond the second level's reach (6 m + its stencil) nothing changes but the spline's ringing
    q, _, dq = near_surface_points(body, 300, 8, 40.0)
    far = dq > 6.0 + (2 * math.sqrt(3) + 1) * STEP / 2
    assert far.sum() > 30
    diff = two_levels.acceleration_batch(q[far]) - fine.acceleration_batch(q[far])
    assert np.abs(diff).max() < 1e-5 * np.abs(two_levels.fine.values[-1]).max()


def test_two_levels_survive_a_round_trip(body, two_levels, tmp_path) -> None:  # type: ignore[no-untyped-def]
    two_levels.save(tmp_path / "t2.npz")
    back = GravityTable.load(tmp_path / "t2.npz", exact=body)
    assert back.fine is not None and back.fine.steps == two_levels.fine.steps
    p, _, _ = near_surface_points(body, 40, 9, 6.0)
    np.testing.assert_array_equal(back.acceleration_batch(p), two_levels.acceleration_batch(p))
    # a file of one level (no per-box steps, as written before the second level) still loads
    arrays = two_levels.fine.to_arrays()
    del arrays["fine_box_step"]
    assert FineBoxes.from_arrays(arrays).steps == [STEP] * len(two_levels.fine)
    with pytest.raises(GravityModelError, match="first level"):
        add_fine_level(GravityTable(two_levels.grid, two_levels.values, 100.0, GM, body), body, None, r_band=170.0)
