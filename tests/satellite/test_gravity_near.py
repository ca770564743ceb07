"""Near-surface tiles of the gravity table: face-wise sums, exactness near the surface, continuity, files."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from satellite.errors import GravityModelError
from satellite.gravity.near import build_near_tiles, tile_faces
from satellite.gravity.polyhedron import FacePatch, PolyhedronField
from satellite.gravity.table import GravityTable, TableGrid, build_table

GM = 2.0


@pytest.fixture(scope="module")
def body(helpers):  # type: ignore[no-untyped-def]
    """A prolate body (tips at 200 m) whose ends poke through a shell table over [150, 250] m."""
    v, f = helpers.icosphere(2)
    return PolyhedronField(v * np.array([200.0, 100.0, 80.0]), f, GM)


@pytest.fixture(scope="module")
def tables(body):  # type: ignore[no-untyped-def]
    grid = TableGrid(150.0, 250.0, 9, 12)
    plain = build_table(body, grid, 100.0)
    near = build_near_tiles(body, grid, r_cut=140.0, max_faces=40, d_in=15.0, d_out=25.0)
    tiled = GravityTable(grid, plain.values, 100.0, GM, body, None, near)
    return plain, tiled


def outside_points(body, n: int, seed: int):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u[: n // 2, 1:] *= 0.15  # half of them towards the tips
    u /= np.linalg.norm(u, axis=1)[:, None]
    p = u * rng.uniform(165.0, 235.0, n)[:, None]
    v = body.evaluate(p)
    out = v.solid_angle < 2 * np.pi
    return p[out], v.acceleration[out]


def test_face_patches_sum_to_the_whole_field(body) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(0)
    mask = rng.random(len(body.faces)) < 0.3
    p = rng.normal(size=(6, 3)) * 150.0
    whole = body.acceleration(p)
    parts = FacePatch.from_field(body, mask).acceleration(p) + FacePatch.from_field(body, ~mask).acceleration(p)
    np.testing.assert_allclose(parts, whole, rtol=1e-11, atol=1e-12 * np.abs(whole).max())
    patch = FacePatch.from_field(body, mask)  # the one-point path (sums expanded in x) agrees
    one = np.array([patch.point_acceleration(x) for x in p])
    np.testing.assert_allclose(one, patch.acceleration(p), rtol=1e-10, atol=1e-12 * np.abs(whole).max())


def test_tiles_are_compact_and_cover_every_face() -> None:
    c = np.random.default_rng(1).uniform(-1, 1, size=(1000, 3))
    t = tile_faces(c, 100)
    assert sorted(set(t.tolist())) == list(range(t.max() + 1))
    assert np.bincount(t).max() <= 100
    spread = max(np.ptp(c[t == k], axis=0).max() for k in range(t.max() + 1))
    assert spread < 1.5  # halved along the widest axis: no tile spans the cube


def test_near_the_surface_the_tiled_table_is_closer_to_the_exact_field(body, tables) -> None:  # type: ignore[no-untyped-def]
    plain, tiled = tables
    p, exact = outside_points(body, 3000, 2)
    d = cKDTree(body.vertices).query(p)[0]
    nonkep = np.linalg.norm(exact + GM * p / (np.linalg.norm(p, axis=1) ** 3)[:, None], axis=1)
    err = {k: np.linalg.norm(t.acceleration_batch(p) - exact, axis=1) / nonkep
           for k, t in (("plain", plain), ("tiled", tiled))}
    close = d < 10.0
    assert close.sum() > 50
    assert err["tiled"][close].max() < 0.3 * err["plain"][close].max()
    far = ~tiled.near.near(p)  # beyond every tile's reach the table alone answers
    assert far.sum() > 100
    np.testing.assert_allclose(tiled.acceleration_batch(p[far]), plain.acceleration_batch(p[far]), rtol=1e-12,
                               atol=1e-20)  # (numpy's vectorised sums against the one-point formula's)
    one = np.array([tiled.acceleration(q) for q in p[:100]])
    np.testing.assert_allclose(one, tiled.acceleration_batch(p[:100]), rtol=1e-12, atol=1e-20)


def test_the_field_is_continuous_where_a_tile_switches_off(body, tables) -> None:  # type: ignore[no-untyped-def]
    _, tiled = tables
    near = tiled.near
    a, b = np.array([160.0, 0.0, 60.0]), np.array([240.0, 0.0, 60.0])

    def dmin(x: np.ndarray) -> float:
        return min(float(np.linalg.norm(v - x, axis=1).min()) for v in near.vertices)

    assert dmin(a) < near.d_out < dmin(b)
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if dmin(a + mid * (b - a)) < near.d_out else (lo, mid)
    x = a + lo * (b - a)

    def jump(eps: float) -> float:
        return float(np.linalg.norm(tiled.acceleration(x - eps * (b - a)) - tiled.acceleration(x + eps * (b - a))))

    assert jump(1e-9) < 0.01 * jump(1e-6)  # no step where the tile's weight reaches 0


def test_tiles_survive_a_round_trip_and_bad_distances_are_refused(body, tables, tmp_path) -> None:  # type: ignore[no-untyped-def]
    _, tiled = tables
    tiled.save(tmp_path / "t.npz")
    back = GravityTable.load(tmp_path / "t.npz", exact=body)
    p, _ = outside_points(body, 400, 3)
    np.testing.assert_array_equal(back.acceleration_batch(p), tiled.acceleration_batch(p))
    with pytest.raises(GravityModelError, match="d_in < d_out"):
        type(tiled.near)(tiled.near.patch, tiled.near.tile, tiled.near.ext, 30.0, 20.0, 25.0)
