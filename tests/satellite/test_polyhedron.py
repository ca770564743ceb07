"""Exact constant-density polyhedron gravity (Werner and Scheeres 1997): known answers and invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest

from satellite.errors import GravityModelError, MeshError
from satellite.gravity.polyhedron import PolyhedronField
from satellite.gravity.spherical import GravityField

GM = 2.0


def directions(n: int, seed: int) -> np.ndarray:
    u = np.random.default_rng(seed).normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1)[:, None]


@pytest.fixture(scope="module")
def body(helpers):  # type: ignore[no-untyped-def]
    mesh = helpers.lumpy_body()  # asymmetric, ~100 m, 320 faces
    return mesh, PolyhedronField.from_mesh(mesh, GM)


def test_far_field_of_a_cube_is_the_point_mass(helpers) -> None:  # type: ignore[no-untyped-def]
    v, f = helpers.box_mesh(100.0, 100.0, 100.0)  # no degree-2 or -3 terms: (50 m / r)^4 corrections
    field = PolyhedronField(v, f, GM)
    p = directions(20, 0) * 5000.0
    vals = field.evaluate(p)
    r = np.linalg.norm(p, axis=1)
    np.testing.assert_allclose(vals.potential, GM / r, rtol=1e-6)
    np.testing.assert_allclose(vals.acceleration, -GM * p / r[:, None] ** 3, rtol=1e-5, atol=1e-5 * GM / 5000.0**2)


def test_gauss_law_solid_angles_and_laplacian(body) -> None:  # type: ignore[no-untyped-def]
    mesh, field = body
    inside = directions(10, 1) * 20.0  # well inside the ~60-160 m body
    outside = directions(10, 2) * 400.0
    v_in, v_out = field.evaluate(inside), field.evaluate(outside)
    np.testing.assert_allclose(v_in.solid_angle, 4 * math.pi, atol=1e-9)
    np.testing.assert_allclose(v_out.solid_angle, 0.0, atol=1e-9)
    np.testing.assert_allclose(v_in.laplacian, -4 * math.pi * GM / mesh.volume, rtol=1e-9)
    # div a from central differences of the acceleration: -4 pi G rho inside, 0 outside
    h = 1e-2
    for pts, want in ((inside[:3], -4 * math.pi * GM / mesh.volume), (outside[:3], 0.0)):
        div = sum((field.acceleration(pts + h * e) - field.acceleration(pts - h * e))[:, k] / (2 * h)
                  for k, e in enumerate(np.eye(3)))
        np.testing.assert_allclose(div, want, atol=1e-6 * GM / mesh.volume * 4 * math.pi + 1e-12)


def test_acceleration_is_the_gradient_of_the_potential(body) -> None:  # type: ignore[no-untyped-def]
    _, field = body
    pts = np.concatenate([directions(6, 3) * 30.0, directions(6, 4) * 250.0])
    a = field.acceleration(pts)
    h = 1e-3
    fd = np.stack([(field.evaluate(pts + h * e).potential - field.evaluate(pts - h * e).potential) / (2 * h)
                   for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(a, fd, rtol=1e-6, atol=1e-8 * float(np.abs(a).max()))


def test_equals_the_harmonic_series_of_the_same_body_outside_its_sphere(body) -> None:  # type: ignore[no-untyped-def]
    mesh, field = body
    sh = GravityField.from_mesh(mesh, mass_kg=GM / 6.6743e-11, degree=16)
    r_b = float(np.linalg.norm(mesh.vertices - mesh.centre_of_mass, axis=1).max())
    p = directions(20, 5) * 3.0 * r_b
    kep = -sh.gm * p / (np.linalg.norm(p, axis=1) ** 3)[:, None]
    exact = field.acceleration(p)
    series = sh.acceleration_batch(p)
    rel = np.linalg.norm(exact - series, axis=1) / np.linalg.norm(exact - kep, axis=1)
    assert rel.max() < 1e-6  # truncation (1/3)^17 ~ 1e-8 times the coefficients' growth


def test_itokawa_equals_degree_8_far_out() -> None:
    from satellite.gravity.spherical import load_default_field
    from satellite.shape.cache import shipped_mesh

    sh = load_default_field()
    field = PolyhedronField.from_mesh(shipped_mesh(), sh.gm)
    for k, tol in ((3.0, 5e-3), (6.0, 5e-5)):  # degree-8 truncation shrinks like (311.7 m / r)^9
        p = directions(6, 6) * k * sh.r_ref_m
        kep = -sh.gm * p / (np.linalg.norm(p, axis=1) ** 3)[:, None]
        rel = np.linalg.norm(field.acceleration(p) - sh.acceleration_batch(p), axis=1) / np.linalg.norm(
            sh.acceleration_batch(p) - kep, axis=1)
        assert rel.max() < tol, (k, rel.max())


def test_bad_input(helpers) -> None:  # type: ignore[no-untyped-def]
    v, f = helpers.box_mesh(1.0, 2.0, 3.0)
    with pytest.raises(GravityModelError, match="gm must be"):
        PolyhedronField(v, f, -1.0)
    with pytest.raises(MeshError):
        PolyhedronField(v, f[:-1], 1.0)  # open
