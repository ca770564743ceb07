from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core.exceptions import ConfigError
from satellite.errors import MeshError
from satellite.shape.cache import read_obj, shipped_mesh
from satellite.shape.mesh import TriangleMesh, check_closed_oriented


def test_unit_cube_volume_is_one(helpers):
    mesh = TriangleMesh.from_arrays(*helpers.box_mesh())
    assert mesh.volume == pytest.approx(1.0, rel=1e-15)
    assert mesh.volume_equivalent_radius == pytest.approx((3 / (4 * np.pi)) ** (1 / 3))


def test_box_volume_centre_and_inertia_closed_forms(helpers):
    a, b, c, mass = 3.0, 2.0, 0.5, 7.0
    v, f = helpers.box_mesh(a, b, c)
    offset = np.array([5.0, -3.0, 2.0])
    mesh = TriangleMesh.from_arrays(v + offset, f)
    assert mesh.volume == pytest.approx(a * b * c, rel=1e-14)
    np.testing.assert_allclose(mesh.centre_of_mass, offset, rtol=0, atol=1e-13)
    expected = mass / 12 * np.diag([b**2 + c**2, a**2 + c**2, a**2 + b**2])
    np.testing.assert_allclose(mesh.inertia_tensor(mass), expected, rtol=0, atol=1e-13)


def test_rotated_box_inertia_is_rotated_tensor(helpers):
    a, b, c, mass = 3.0, 2.0, 0.5, 7.0
    v, f = helpers.box_mesh(a, b, c)
    q = helpers.rotation(0.3, -0.7, 1.1)
    mesh = TriangleMesh.from_arrays(v @ q.T, f)
    body = mass / 12 * np.diag([b**2 + c**2, a**2 + c**2, a**2 + b**2])
    np.testing.assert_allclose(mesh.inertia_tensor(mass), q @ body @ q.T, rtol=0, atol=1e-13)


def test_monomial_moments_match_quadrature_on_a_tetrahedron(helpers):
    v = np.array([[0.3, -0.2, 0.1], [1.4, 0.1, -0.3], [0.2, 1.1, 0.4], [0.5, 0.3, 1.3]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    mesh = TriangleMesh.from_arrays(v, f)
    origin = np.array([0.1, 0.2, -0.3])
    moments = mesh.monomial_moments(6, origin=origin, scale=0.7)
    u, w = helpers.simplex_quadrature(6)
    e = v[1:] - v[0]
    vol6 = abs(np.linalg.det(e))
    x = (v[0] + u @ e - origin) / 0.7
    for i in range(7):
        for j in range(7 - i):
            for k in range(7 - i - j):
                ref = vol6 * np.sum(w * x[:, 0] ** i * x[:, 1] ** j * x[:, 2] ** k)
                assert moments[i, j, k] == pytest.approx(ref, rel=1e-12, abs=1e-14)
    assert moments[6, 1, 0] == 0.0  # beyond max_degree


def test_unreferenced_vertices_are_dropped(helpers):
    v, f = helpers.box_mesh(2, 2, 2)
    extra = np.vstack([[[9.0, 9.0, 9.0]], v, [[-9.0, 0.0, 1.0]]])
    mesh = TriangleMesh.from_arrays(extra, f + 1)
    assert mesh.vertices.shape == (8, 3)
    assert mesh.faces.max() == 7
    assert mesh.volume == pytest.approx(8.0)


def test_inward_oriented_mesh_is_flipped(helpers):
    v, f = helpers.box_mesh(1, 2, 3)
    mesh = TriangleMesh.from_arrays(v, f[:, ::-1])
    assert mesh.volume == pytest.approx(6.0)


def test_open_mesh_is_rejected_with_clear_error(helpers):
    v, f = helpers.box_mesh()
    with pytest.raises(MeshError, match="not closed: 3 boundary edge"):
        TriangleMesh.from_arrays(v, f[:-1])
    with pytest.raises(MeshError, match="not closed"):
        TriangleMesh.from_arrays(v, f[:-2])  # a whole square face removed


def test_flipped_face_is_rejected(helpers):
    v, f = helpers.icosphere(1)
    f = f.copy()
    f[5] = f[5, ::-1]
    with pytest.raises(MeshError, match="inconsistently oriented"):
        TriangleMesh.from_arrays(v, f)


def test_non_manifold_and_degenerate_faces_are_rejected(helpers):
    v, f = helpers.box_mesh()
    with pytest.raises(MeshError, match="not 2-manifold"):
        TriangleMesh.from_arrays(v, np.vstack([f, f[:1]]))
    bad = f.copy()
    bad[0] = [0, 0, 1]
    with pytest.raises(MeshError, match="degenerate"):
        TriangleMesh.from_arrays(v, bad)
    with pytest.raises(MeshError, match="out of range"):
        check_closed_oriented(f + 1, 8)


def test_mesh_errors_are_config_errors_and_value_errors(helpers):
    v, f = helpers.box_mesh()
    with pytest.raises(ConfigError):
        TriangleMesh.from_arrays(v, f[:-1])
    with pytest.raises(ValueError):
        TriangleMesh.from_arrays(v[:, :2], f)


def test_flat_mesh_without_volume_is_rejected(helpers):
    v, f = helpers.box_mesh(1.0, 1.0, 1.0)
    v = v.copy()
    v[:, 2] = 0.0
    with pytest.raises(MeshError, match="no volume"):
        TriangleMesh.from_arrays(v, f)


def test_read_obj_formats_units_and_relative_indices(tmp_path):
    text = """# a unit cube with quads, normals, texture indices and negative indices
v 0 0 0
v 0 0 1
v 0 1 0
v 0 1 1
v 1 0 0
v 1 0 1
v 1 1 0
v 1 1 1
vn 0 0 1
vt 0 0
f 1/1/1 2/1/1 4/1/1 3/1/1
f 5 7 8 6
f 1//1 5//1 6//1 2//1
f 3 4 8 7
f 1 3 7 5
f -7 -3 -1 -5
"""
    path = tmp_path / "cube.obj"
    path.write_text(text)
    km = read_obj(path)
    assert km.faces.shape == (12, 3)
    assert km.volume == pytest.approx(1e9)
    assert read_obj(path, units="m").volume == pytest.approx(1.0)


def test_read_obj_errors(tmp_path, helpers):
    with pytest.raises(FileNotFoundError):
        read_obj(tmp_path / "missing.obj")
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 x\n")
    with pytest.raises(MeshError, match="bad.obj:2: malformed 'v'"):
        read_obj(path)
    v, f = helpers.box_mesh()
    good = helpers.write_obj(tmp_path / "box.obj", v, f)
    with pytest.raises(MeshError, match="unknown length unit 'mm'"):
        read_obj(good, units="mm")
    opened = helpers.write_obj(tmp_path / "open.obj", v, f[:-1])
    with pytest.raises(MeshError, match="not closed"):
        read_obj(opened)


def test_itokawa_mesh_facts():
    mesh = shipped_mesh()
    assert mesh.vertices.shape == (24578, 3)
    assert mesh.faces.shape == (49152, 3)
    assert mesh.volume == pytest.approx(1.77856e7, rel=1e-5)
    assert mesh.volume_equivalent_radius == pytest.approx(161.93, abs=0.01)
    radii = np.linalg.norm(mesh.vertices - mesh.centre_of_mass, axis=1)
    assert radii.max() == pytest.approx(311.7, abs=0.1)
