"""The optional surface check: shapes, the spin transform, and ``isf-satellite run --surface-check``."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import satellite.shape.mesh_surface as mesh_surface_mod
from satellite.cli import main
from satellite.orbit.model import OrbitModel
from satellite.orbit.simulate import simulate
from satellite.shape.mesh import TriangleMesh
from satellite.shape.mesh_surface import MeshSurface, load_surface
from satellite.shape.surface_check import SurfaceCheck, to_body_frame
from satellite.shape.surfaces import EllipsoidSurface, winding_numbers

SURFACE_KEYS = {"surface_model", "surface_hits", "first_surface_hit_h", "min_clearance_m", "surface_passes"}


def random_points(n: int, r_max: float, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    return u * rng.uniform(0.0, r_max, n)[:, None]


def convex_oracle(v: np.ndarray, f: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inside test and radial surface distance of a convex polyhedron containing the origin."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    d = np.einsum("fi,fi->f", n, a)
    inside = (p @ n.T - d <= 0).all(axis=1)
    u = p / np.linalg.norm(p, axis=1)[:, None]
    cosang = u @ n.T
    with np.errstate(divide="ignore"):
        rs = np.where(cosang > 0, d / cosang, np.inf).min(axis=1)
    return inside, rs


def test_cube_inside_outside_and_clearance(helpers: SimpleNamespace) -> None:
    v, f = helpers.box_mesh(2.0, 2.0, 2.0)
    cube = MeshSurface(TriangleMesh.from_arrays(v, f))
    assert cube.origin_inside and cube.max_radius == pytest.approx(math.sqrt(3))
    # Rays along the axes and the diagonals run exactly through shared edges and corners.
    pts = np.array(
        [[0, 0, 0], [0.99, 0, 0], [1.01, 0, 0], [0, -2, 0], [0, 0, 0.5], [0.9, 0.9, 0.9],
         [1.1, 1.1, 1.1], [0.5, -0.5, 0.999], [3.0, 0.2, -0.1], [-0.999, 0.999, 0.0]]
    )  # fmt: skip
    inside, clear = cube.query(pts)
    assert inside.tolist() == [True, True, False, False, True, True, False, True, False, True]
    assert clear[1:4] == pytest.approx([-0.01, 0.01, 1.0])
    assert clear[5] == pytest.approx(-0.1 * math.sqrt(3))
    assert clear[6] == pytest.approx(0.1 * math.sqrt(3))
    p = random_points(3000, 2.0, seed=1)
    inside, clear = cube.query(p)
    assert np.array_equal(inside, (np.abs(p) <= 1.0).all(axis=1))
    _, rs = convex_oracle(cube.vertices, cube.faces, p)
    assert np.allclose(np.abs(clear), np.abs(np.linalg.norm(p, axis=1) - rs), atol=1e-9)
    assert np.allclose(winding_numbers(pts, cube.vertices, cube.faces), [1, 1, 0, 0, 1, 1, 0, 1, 0, 1], atol=1e-9)


def test_icosphere_against_convex_oracle(helpers: SimpleNamespace) -> None:
    v, f = helpers.icosphere(3)
    body = MeshSurface(TriangleMesh.from_arrays(v * 100.0, f))
    p = random_points(5000, 110.0, seed=2)
    inside, clear = body.query(p)
    want, rs = convex_oracle(body.vertices, body.faces, p)
    assert np.array_equal(inside, want)
    assert np.allclose(clear, np.linalg.norm(p, axis=1) - rs, atol=1e-8)
    assert np.array_equal(body.inside(p[:200]), winding_numbers(p[:200], body.vertices, body.faces) > 0.5)


def u_prism() -> tuple[np.ndarray, np.ndarray]:
    """A U-shaped prism (non-convex; its centroid lies in the gap between the arms)."""
    poly = [(0, 0), (3, 0), (3, 3), (2, 3), (2, 1), (1, 1), (1, 3), (0, 3)]
    caps = [(0, 1, 4), (0, 4, 5), (1, 2, 3), (1, 3, 4), (5, 6, 7), (5, 7, 0)]
    v = np.array([(x, y, 0.0) for x, y in poly] + [(x, y, 1.0) for x, y in poly])
    f = [(a + 8, b + 8, c + 8) for a, b, c in caps] + [(a, c, b) for a, b, c in caps]
    for i in range(8):
        j = (i + 1) % 8
        f += [(i, j, j + 8), (i, j + 8, i + 8)]
    return v, np.array(f)


def in_u(p: np.ndarray) -> np.ndarray:
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    box = (x >= 0) & (x <= 3) & (y >= 0) & (y <= 3) & (z >= 0) & (z <= 1)
    gap = (x > 1) & (x < 2) & (y > 1)
    return box & ~gap


@pytest.mark.parametrize("origin", [None, (0.5, 0.5, 0.5)])
def test_nonconvex_body_with_several_crossings(origin: tuple[float, ...] | None) -> None:
    v, f = u_prism()
    mesh = TriangleMesh.from_arrays(v, f)
    body = MeshSurface(mesh, origin=origin, grid=8)
    o = body.origin_in_mesh
    assert body.origin_inside == (origin is not None)  # the centroid sits in the gap
    rng = np.random.default_rng(3)
    p = rng.uniform([-0.5, -0.5, -0.5], [3.5, 3.5, 1.5], size=(800, 3))
    assert np.array_equal(body.inside(p - o), in_u(p))
    # A point in the gap beyond the right arm seen from (0.5, 0.5, 0.5): the ray crosses the body
    # several times, and the clearance is to the nearest crossing.
    if origin is not None:
        q = np.array([[1.5, 2.5, 0.5]]) - o
        inside, clear = body.query(q)
        assert not inside[0] and 0 < clear[0] < np.linalg.norm(q)


def test_default_shape_is_the_shipped_mesh_without_the_raw_file(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(mesh_surface_mod, "default_shape_path", lambda: Path("/nonexistent/itokawa.obj"))
    monkeypatch.setenv("ISF_ROBOT_DATA", "/nonexistent")
    body = load_surface(None)
    assert isinstance(body, MeshSurface) and body.faces.shape == (49152, 3) and "itokawa_low.obj" in body.name
    info = mesh_surface_mod.body_mesh_info(None)
    assert info is not None and np.array_equal(info["faces"], body.faces) and info["name"] == "itokawa_low.obj"
    np.testing.assert_array_equal(info["vertices"], body.vertices)


def test_ellipsoid_matches_analytic() -> None:
    ell = EllipsoidSurface.itokawa()
    assert "ellipsoid 535 x 294 x 209 m" in ell.name
    a = np.array([267.5, 147.0, 104.5])
    assert ell.max_radius == 267.5
    p = random_points(4000, 300.0, seed=4)
    inside, clear = ell.query(p)
    assert np.array_equal(inside, ((p / a) ** 2).sum(axis=1) <= 1)
    surf = p / np.linalg.norm(p, axis=1)[:, None] * (np.linalg.norm(p, axis=1) - clear)[:, None]
    assert np.allclose(((surf / a) ** 2).sum(axis=1), 1.0)
    axes = np.array([[300.0, 0, 0], [0, -100.0, 0], [0, 0, 110.0]])
    assert ell.clearance(axes) == pytest.approx([32.5, -47.0, 5.5])


def test_spin_transform_keeps_body_fixed_points(helpers: SimpleNamespace) -> None:
    model = OrbitModel(body_phase=0.7)
    p_body = np.array([[200.0, -30.0, 40.0], [290.0, 10.0, 0.0], [100.0, 100.0, 100.0]])
    times = np.array([0.0, 1234.5, 20000.0, 43677.0])
    theta = model.body_phase + model.omega * times
    c, s = np.cos(theta), np.sin(theta)
    for k in range(len(times)):
        rz = np.array([[c[k], -s[k], 0], [s[k], c[k], 0], [0, 0, 1]])
        inertial = p_body @ rz.T
        back = to_body_frame(np.full(3, times[k]), inertial, model.body_phase, model.omega)
        assert np.allclose(back, p_body)
        # Same convention as the truth flow: a = Rz(theta) a_SH(r_body).
        a = model.truth_acceleration(times[k], inertial[0])
        assert np.allclose(a, rz @ model.field.acceleration(p_body[0]))
    # A body-fixed point is flagged the same at every time (inside the ellipsoid, or not).
    ell = EllipsoidSurface.itokawa()
    for point, expect in ((p_body[0], True), (p_body[1], False)):
        check = SurfaceCheck(ell, model.body_phase, model.omega, step_s=10.0)
        inertial = np.stack([np.array([[c[k], -s[k], 0], [s[k], c[k], 0], [0, 0, 1]]) @ point for k in range(4)])
        check.add(times, inertial)
        rep = check.report()
        assert rep["surface_hits"] == (4 if expect else 0)
        assert rep["surface_passes"] == (1 if expect else 0)
        assert rep["min_clearance_m"] == pytest.approx(float(ell.clearance(point[None])[0]))


def test_run_with_check_keeps_trajectory_and_reports(helpers: SimpleNamespace) -> None:
    plain = simulate("greedy", 12.0, miet_samples=200)
    assert plain.surface is None and not (SURFACE_KEYS & set(plain.summary()))
    big = MeshSurface(TriangleMesh.from_arrays(*helpers.icosphere(2)), name="big")
    big = MeshSurface(TriangleMesh.from_arrays(big.vertices * 500.0, big.faces), name="sphere 500 m")
    checked = simulate("greedy", 12.0, miet_samples=200, surface=big, surface_step_s=60.0)
    assert checked.triggers == plain.triggers and checked.r_min_over_R == plain.r_min_over_R
    s = checked.summary()
    assert SURFACE_KEYS <= set(s) and s["surface_model"] == "sphere 500 m"
    assert s["surface_hits"] == s["surface_samples"] >= 12 * 60 and s["surface_passes"] == 1
    assert s["first_surface_hit_h"] == 0.0 and s["min_clearance_m"] < -100.0


def test_cli_surface_check_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--hours", "24", "--seed", "1", "--json", "--quiet", "--surface-check"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert SURFACE_KEYS <= set(doc)
    assert doc["surface_model"].startswith(("mesh", "ellipsoid"))
    assert doc["surface_hits"] >= 0 and doc["min_clearance_m"] is not None
    assert (doc["first_surface_hit_h"] is None) == (doc["surface_hits"] == 0)


def test_cli_surface_check_with_shape_file(
    helpers: SimpleNamespace, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    v, f = helpers.icosphere(1)
    obj = helpers.write_obj(tmp_path / "small.obj", v * 0.05, f)  # 50 m sphere, in km
    assert main(["run", "--hours", "6", "--quiet", "--surface-check", "--shape", str(obj)]) == 0
    out = capsys.readouterr().out
    assert "surface model      mesh" in out and "surface hits       0 samples" in out
    assert main(["run", "--hours", "6", "--json", "--quiet", "--surface-check", "--shape", str(obj)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["surface_hits"] == 0 and doc["first_surface_hit_h"] is None
    assert doc["min_clearance_m"] > 200.0  # r >= 1.6 R = 259 m against a 50 m sphere


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["run", "--contact", "off", "--shape", "x.obj"], "--shape needs --surface-check, --contact count|stop"),
        (["run", "--surface-check", "--shape", "/nonexistent/shape.obj"], "not found"),
        (["run", "--surface-check", "--surface-step", "0"], "--surface-step"),
        (["run", "--surface-step", "0"], "--surface-step goes with --surface-check"),  # (was accepted, unused)
        (["run", "--surface-step", "60"], "--surface-step goes with --surface-check"),
        (["run", "--gravity", "nope.json"], "gravity file not found: nope.json (give table, sh8"),
    ],
)
def test_cli_surface_errors(argv: list[str], needle: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*argv, "--hours", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1


def test_itokawa_mesh() -> None:
    body = load_surface(None)  # the shipped mesh
    assert isinstance(body, MeshSurface) and body.origin_inside
    assert body.max_radius == pytest.approx(311.7, abs=0.05)
    assert np.allclose(body.origin_in_mesh, [0.358, 0.035, -0.107], atol=1e-3)
    # Points near the surface, where the ray shortcut and the winding number must agree.
    p = random_points(150, 320.0, seed=5)
    _, clear = body.query(p)
    near = p[np.abs(clear) < 30.0][:60]
    assert near.shape[0] > 20
    assert np.array_equal(body.inside(near), winding_numbers(near, body.vertices, body.faces) > 0.5)
    # The long-axis tip: just outside beyond 311.7 m, inside well below it.
    tip = body.vertices[np.argmax(np.linalg.norm(body.vertices, axis=1))]
    assert not body.inside(tip[None] * 1.01)[0] and body.inside(tip[None] * 0.9)[0]
