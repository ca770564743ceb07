from __future__ import annotations

import json
import math

import numpy as np
import pytest

from satellite.errors import GravityModelError
from satellite.gravity.spherical import (
    G_CODATA2018,
    ITOKAWA_MASS_KG,
    GravityField,
    load_default_field,
    normalisation,
    polyhedron_harmonics,
    solid_harmonics,
)
from satellite.shape.cache import shipped_mesh
from satellite.shape.mesh import TriangleMesh

RNG_SEED = 20260101


def random_points(radius_min: float, radius_max: float, k: int = 20) -> np.ndarray:
    rng = np.random.default_rng(RNG_SEED)
    p = rng.normal(size=(k, 3))
    r = rng.uniform(radius_min, radius_max, size=k)
    return p / np.linalg.norm(p, axis=1)[:, None] * r[:, None]


# ---------------------------------------------------------------- coefficients


def test_c00_is_one_and_degree_one_vanishes_for_an_offset_body(helpers):
    h = polyhedron_harmonics(helpers.lumpy_body(), 4)
    assert h.C[0, 0] == 1.0
    np.testing.assert_allclose(h.C[1], 0.0, atol=1e-14)
    np.testing.assert_allclose(h.S[1], 0.0, atol=1e-14)
    assert np.abs(h.C[2:]).max() > 1e-2  # the body is not spherical


def test_box_coefficients_match_inertia_closed_forms(helpers):
    a, b, c = 3.0, 2.0, 0.5
    v, f = helpers.box_mesh(a, b, c)
    q = helpers.rotation(0.3, -0.7, 1.1)
    mesh = TriangleMesh.from_arrays(v @ q.T + np.array([4.0, 1.0, -2.0]), f)
    mass = 1.0
    inertia = q @ (mass / 12 * np.diag([b**2 + c**2, a**2 + c**2, a**2 + b**2])) @ q.T
    radius = (3 * a * b * c / (4 * math.pi)) ** (1 / 3)
    mr2 = mass * radius**2
    ixx, iyy, izz = np.diag(inertia)
    ixy, ixz, iyz = inertia[0, 1], inertia[0, 2], inertia[1, 2]  # = -integral of x y dm, ...
    unnormalised = {
        ("C", 2, 0): (ixx + iyy - 2 * izz) / (2 * mr2),
        ("C", 2, 1): -ixz / mr2,
        ("S", 2, 1): -iyz / mr2,
        ("C", 2, 2): (iyy - ixx) / (4 * mr2),
        ("S", 2, 2): -ixy / (2 * mr2),
    }
    h = polyhedron_harmonics(mesh, 3)
    assert h.r_ref_m == pytest.approx(radius, rel=1e-14)
    assert h.volume_m3 == pytest.approx(a * b * c, rel=1e-14)
    for (kind, n, m), value in unnormalised.items():
        table = h.C if kind == "C" else h.S
        assert table[n, m] == pytest.approx(value / normalisation(n, m), rel=1e-12, abs=1e-14)
    assert normalisation(2, 0) == pytest.approx(math.sqrt(5))
    assert normalisation(2, 2) == pytest.approx(math.sqrt(5 / 12))
    # a centrally symmetric body has no odd-degree terms
    np.testing.assert_allclose(h.C[3], 0.0, atol=1e-14)
    np.testing.assert_allclose(h.S[3], 0.0, atol=1e-14)


def test_aligned_box_c20_negative_when_oblate(helpers):
    h = polyhedron_harmonics(TriangleMesh.from_arrays(*helpers.box_mesh(2.0, 2.0, 1.0)), 2)
    assert h.C[2, 0] < 0
    assert h.C[2, 2] == pytest.approx(0.0, abs=1e-15)
    assert h.S[2, 2] == pytest.approx(0.0, abs=1e-15)


def test_icosphere_has_no_terms_below_degree_six(helpers):
    # icosahedral symmetry leaves no invariant harmonic of degree 1..5
    v, f = helpers.icosphere(3, radius=50.0)
    mesh = TriangleMesh.from_arrays(v @ helpers.rotation(0.2, 0.4, 0.9).T, f)
    h = polyhedron_harmonics(mesh, 6)
    assert np.abs(h.C[1:6]).max() < 1e-14
    assert np.abs(h.S[1:6]).max() < 1e-14
    assert np.abs(h.C[6]).max() > 1e-6
    # sphere-like: the volume approaches the sphere's from below
    assert 0.97 < h.volume_m3 / (4 / 3 * math.pi * 50.0**3) < 1.0


@pytest.mark.parametrize("degree", [8, 12])
def test_exact_integration_matches_independent_quadrature(degree, helpers):
    mesh = helpers.lumpy_body()
    h = polyhedron_harmonics(mesh, degree)
    c, s, r_ref, vol = helpers.coefficients_by_quadrature(
        np.asarray(mesh.vertices), np.asarray(mesh.faces), degree
    )
    assert h.r_ref_m == pytest.approx(r_ref, rel=1e-14)
    assert h.volume_m3 == pytest.approx(vol, rel=1e-14)
    np.testing.assert_allclose(h.C, c, rtol=0, atol=1e-14)
    np.testing.assert_allclose(h.S, s, rtol=0, atol=1e-14)


def test_solid_harmonics_are_harmonic_polynomials():
    v, w = solid_harmonics(6)
    e = np.arange(7)
    for arr in (v, w):
        for n in range(7):
            for m in range(n + 1):
                p = arr[n, m]
                lap = np.zeros_like(p)
                lap[:-2] += p[2:] * (e[2:] * (e[2:] - 1))[:, None, None]
                lap[:, :-2] += p[:, 2:] * (e[2:] * (e[2:] - 1))[None, :, None]
                lap[:, :, :-2] += p[:, :, 2:] * (e[2:] * (e[2:] - 1))[None, None, :]
                assert np.abs(lap).max() < 1e-9 * max(1.0, np.abs(p).max())


def test_bad_degree_and_mass_are_rejected(helpers):
    mesh = TriangleMesh.from_arrays(*helpers.box_mesh())
    for degree in (-1, 21, 2.5):
        with pytest.raises(GravityModelError, match="degree"):
            polyhedron_harmonics(mesh, degree)  # type: ignore[arg-type]
    with pytest.raises(GravityModelError, match="mass"):
        GravityField.from_mesh(mesh, 2, mass_kg=-1.0)


# ---------------------------------------------------------------- committed table


def test_committed_table_loads_with_provenance():
    g = load_default_field()
    assert g.degree == 8
    assert g.r_ref_m == pytest.approx(161.93, abs=0.01)
    assert g.gm == pytest.approx(G_CODATA2018 * ITOKAWA_MASS_KG, rel=1e-15)
    assert g.C[0, 0] == 1.0
    assert np.abs(g.C[1]).max() < 1e-13 and np.abs(g.S[1]).max() < 1e-13
    assert g.C[2, 0] == pytest.approx(-0.1470, abs=1e-4)
    assert g.C[2, 2] == pytest.approx(0.2213, abs=1e-4)
    from importlib import resources

    data = json.loads(
        resources.files("satellite").joinpath("data", "itokawa_degree8.json").read_text()
    )
    prov = data["provenance"]
    assert "HAY-A-AMICA-5-ITOKAWASHAPE-V1.0" in prov["citation"]
    assert (
        prov["shape_sha256"] == "1879abcde28ca60f8616da212d6f7ae51dbc0cfc47ef271228d1bd2719b2a26b"
    )
    assert prov["mass_kg"] == 3.51e10 and prov["G"] == 6.67430e-11
    assert "isf-satellite gravity" in prov["generator"] and prov["date"]


def test_regeneration_equals_committed_table():
    mesh = shipped_mesh()  # the checked mesh of itokawa_low.obj (test_shape_cache: the same arrays as the file's)
    fresh = GravityField.from_mesh(mesh, 8)
    committed = load_default_field()
    assert fresh.r_ref_m == pytest.approx(committed.r_ref_m, rel=1e-13)
    assert fresh.gm == committed.gm
    np.testing.assert_allclose(fresh.C, committed.C, rtol=1e-11, atol=1e-14)
    np.testing.assert_allclose(fresh.S, committed.S, rtol=1e-11, atol=1e-14)
    # C20 and C22 against the inertia-tensor closed forms of the same mesh
    inertia = mesh.inertia_tensor(ITOKAWA_MASS_KG)
    mr2 = ITOKAWA_MASS_KG * fresh.r_ref_m**2
    c20 = (inertia[0, 0] + inertia[1, 1] - 2 * inertia[2, 2]) / (2 * mr2)
    c22 = (inertia[1, 1] - inertia[0, 0]) / (4 * mr2)
    assert fresh.C[2, 0] * normalisation(2, 0) == pytest.approx(c20, rel=1e-12)
    assert fresh.C[2, 2] * normalisation(2, 2) == pytest.approx(c22, rel=1e-12)


# ---------------------------------------------------------------- field evaluation


def random_field(degree: int, seed: int = 3) -> GravityField:
    rng = np.random.default_rng(seed)
    c = np.tril(rng.normal(scale=0.1, size=(degree + 1, degree + 1)))
    s = np.tril(rng.normal(scale=0.1, size=(degree + 1, degree + 1)))
    s[:, 0] = 0.0
    c[0, 0] = 1.0
    return GravityField(c, s, r_ref_m=150.0, gm=2.5)


def test_degree_zero_is_exactly_kepler():
    g = GravityField(np.ones((1, 1)), np.zeros((1, 1)), r_ref_m=161.9, gm=2.3426793)
    for p in random_points(100.0, 1e5):
        r = np.linalg.norm(p)
        np.testing.assert_allclose(g.acceleration(p), -g.gm * p / r**3, rtol=1e-15, atol=0)
        assert g.potential(p) == pytest.approx(g.gm / r, rel=1e-15)
    # the truncation of a full table to degree 0 is the same
    full = load_default_field()
    g0 = GravityField(full.C[:1, :1], full.S[:1, :1], full.r_ref_m, full.gm)
    p = np.array([400.0, -20.0, 35.0])
    np.testing.assert_allclose(
        g0.acceleration(p), -full.gm * p / np.linalg.norm(p) ** 3, rtol=1e-15
    )


def test_potential_matches_textbook_legendre_sum(helpers):
    g = random_field(8)
    pts = random_points(200.0, 600.0)
    ref = helpers.potential_reference(g.C, g.S, g.r_ref_m, g.gm, pts)
    np.testing.assert_allclose(g.potential(pts), ref, rtol=1e-13)
    assert g.potential(pts[0]) == pytest.approx(ref[0], rel=1e-13)


@pytest.mark.parametrize("field_name", ["itokawa", "random"])
def test_acceleration_is_gradient_of_potential(field_name):
    g = load_default_field() if field_name == "itokawa" else random_field(8)
    for p in random_points(1.6 * g.r_ref_m, 5 * g.r_ref_m, k=10):
        r = np.linalg.norm(p)
        h = 1e-4 * r
        fd = np.array(
            [(g.potential(p + h * e) - g.potential(p - h * e)) / (2 * h) for e in np.eye(3)]
        )
        a = g.acceleration(p)
        np.testing.assert_allclose(a, fd, rtol=0, atol=1e-7 * g.gm / r**2)


def test_laplacian_vanishes_outside_the_body():
    g = load_default_field()
    for p in random_points(1.6 * g.r_ref_m, 4 * g.r_ref_m, k=8):
        r = np.linalg.norm(p)
        h = 1e-2 * r
        u0 = g.potential(p)
        second = []
        for e in np.eye(3):  # fourth-order second differences
            u = [g.potential(p + k * h * e) for k in (-2, -1, 1, 2)]
            second.append((-u[0] + 16 * u[1] - 30 * u0 + 16 * u[2] - u[3]) / (12 * h**2))
        scale = g.gm / r**3
        assert max(abs(d) for d in second) > 0.3 * scale  # each term is large ...
        assert abs(sum(second)) < 1e-6 * scale  # ... and they cancel


def test_field_approaches_kepler_far_away():
    g = load_default_field()
    p = np.array([3.0, -2.0, 1.0]) * 1e5
    r = np.linalg.norm(p)
    np.testing.assert_allclose(g.acceleration(p), -g.gm * p / r**3, rtol=1e-6)


def test_batch_and_single_point_agree():
    g = load_default_field()
    pts = random_points(250.0, 800.0, k=50)
    single = np.array([g.acceleration(p) for p in pts])
    np.testing.assert_allclose(g.acceleration_batch(pts), single, rtol=1e-13, atol=1e-22)
    np.testing.assert_allclose(g.acceleration(pts), single, rtol=1e-13, atol=1e-22)
    pots = np.array([g.potential(p) for p in pts])
    np.testing.assert_allclose(g.potential(pts), pots, rtol=1e-14)
    xyz = np.array([g.acceleration_xyz(*p) for p in pts.tolist()])
    np.testing.assert_array_equal(xyz, single)
    assert g.acceleration(pts[0]).shape == (3,)
    assert isinstance(g.potential(pts[0]), float)


# ---------------------------------------------------------------- JSON and validation


def test_json_round_trip_is_exact(tmp_path):
    g = random_field(5)
    path = tmp_path / "field.json"
    g.to_json(path, provenance={"note": "test"})
    data = json.loads(path.read_text())
    assert set(data) >= {"provenance", "degree", "r_ref_m", "gm", "C", "S"}
    assert [len(row) for row in data["C"]] == [1, 2, 3, 4, 5, 6]
    back = GravityField.from_json(path)
    assert back.degree == 5 and back.r_ref_m == g.r_ref_m and back.gm == g.gm
    np.testing.assert_array_equal(back.C, g.C)
    np.testing.assert_array_equal(back.S, g.S)
    square = GravityField.from_dict(
        {"degree": 5, "r_ref_m": 150.0, "gm": 2.5, "C": g.C.tolist(), "S": g.S.tolist()}
    )
    np.testing.assert_array_equal(square.C, g.C)


def test_invalid_tables_are_rejected(tmp_path):
    good = random_field(2).to_dict()
    with pytest.raises(GravityModelError, match="lacks key"):
        GravityField.from_dict({k: v for k, v in good.items() if k != "gm"})
    with pytest.raises(GravityModelError, match="rows"):
        GravityField.from_dict({**good, "C": good["C"][:2]})
    with pytest.raises(GravityModelError, match="gm"):
        GravityField.from_dict({**good, "gm": -1.0})
    with pytest.raises(GravityModelError, match="r_ref_m"):
        GravityField(np.ones((1, 1)), np.zeros((1, 1)), r_ref_m=0.0, gm=1.0)
    with pytest.raises(GravityModelError, match="S\\[n\\]\\[0\\]"):
        GravityField(np.ones((2, 2)) * np.tri(2), np.tri(2), r_ref_m=1.0, gm=1.0)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(GravityModelError, match="not valid JSON"):
        GravityField.from_json(bad)
    with pytest.raises(GravityModelError, match="shape"):
        random_field(2).acceleration(np.zeros((2, 2)))
    for bad_point in (np.zeros(3), np.array([np.nan, 1.0, 0.0])):
        with pytest.raises(GravityModelError, match="non-zero"):
            random_field(2).acceleration(bad_point)
        with pytest.raises(GravityModelError, match="non-zero"):
            random_field(2).potential(bad_point)
        with pytest.raises(GravityModelError, match="non-zero"):
            random_field(2).acceleration_batch(bad_point[None, :])


def test_coefficient_arrays_are_read_only():
    g = random_field(2)
    with pytest.raises(ValueError):
        g.C[2, 0] = 1.0
