"""The shipped default shape and start-up caches (satellite/shape/cache.py, the samples in satellite/gravity/fields.py): the same numbers as without them.

Only the first test reads the raw shape file (it checks the shipped mesh against it) and skips without it;
the others run on the shipped files alone.
"""

from __future__ import annotations

import numpy as np
import pytest

from satellite.control.contact import contact_samples, make_contact
from satellite.gravity import fields as fields_mod
from satellite.gravity.fields import ExactField, _LazyExact, exact_itokawa, load_field
from satellite.orbit.model import OrbitModel
from satellite.shape import cache as shape_cache
from satellite.shape.cache import read_obj
from satellite.shape.mesh import parse_obj
from satellite.shape.mesh_surface import load_surface


def test_cached_mesh_is_the_parsed_mesh(itokawa_obj, tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    path = itokawa_obj
    monkeypatch.setattr(shape_cache, "_MEMO", {})
    got = read_obj(path)  # from the committed arrays
    want = parse_obj(path)
    assert np.array_equal(got.vertices, want.vertices) and np.array_equal(got.faces, want.faces)
    assert got.faces.dtype == want.faces.dtype and not got.vertices.flags.writeable
    assert got is shape_cache.shipped_mesh() and shape_cache.shipped_sha256() == shape_cache.sha256_of(path)
    assert read_obj(path) is got  # read once per process
    # another file (here the same shape with one vertex moved) is parsed, never answered from the cache
    text = path.read_text().splitlines()
    first = next(i for i, line in enumerate(text) if line.startswith("v "))
    x, y, z = (float(v) for v in text[first].split()[1:4])
    text[first] = f"v {x * 1.001} {y} {z}"
    other = tmp_path / "moved.obj"
    other.write_text("\n".join(text) + "\n")
    moved = read_obj(other)
    assert not np.array_equal(moved.vertices, want.vertices)
    assert np.array_equal(moved.vertices, parse_obj(other).vertices)


def test_cached_exact_samples_are_the_exact_field() -> None:
    model = OrbitModel(load_field("table"))
    _, slow = contact_samples(model, load_surface())
    assert len(slow) > 0
    with np.load(shape_cache.SAMPLES_FILE) as data:
        assert np.array_equal(data["points"], slow)  # the committed file holds this run's points
        stored = np.array(data["acc"])
    np.testing.assert_array_equal(fields_mod.exact_samples(model.field, slow), stored)
    fresh = fields_mod.exact_samples(model.field, slow[:3].copy() * 1.0)  # a subset: evaluated, not looked up
    np.testing.assert_allclose(fresh, stored[:3], rtol=1e-12)


def test_contact_bound_does_not_depend_on_the_cache(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    model = OrbitModel(load_field("table"))
    shape = load_surface()
    cached = make_contact(model, shape).accel_bound  # the default samples: the committed file answers
    monkeypatch.setattr(fields_mod, "SAMPLES_FILE", shape_cache.DATA / "absent.npz")
    # the exact field evaluated (~1 s). Equal to the bit on the machine that wrote the file; on another
    # the field's sums over 49,152 faces (BLAS products, whose kernels and summation order OpenBLAS picks
    # per CPU, and numpy's arctan2/log loops) round differently in the last bits (AMD file vs Intel:
    # 1.6060173367940555e-4 vs ...568, 8e-16 relative), hence rtol 1e-12, the bound of the check above
    assert make_contact(model, shape).accel_bound == pytest.approx(cached, rel=1e-12, abs=0.0)


def test_runs_need_no_raw_shape_file(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Without the shared data folder every default-shape consumer answers from the shipped mesh."""
    monkeypatch.setenv("ISF_ROBOT_DATA", "/nonexistent")
    mesh = shape_cache.shipped_mesh()
    assert mesh.faces.shape == (49152, 3) and mesh.vertices.shape == (24578, 3)
    exact = exact_itokawa()
    assert isinstance(exact, ExactField) and np.array_equal(exact.field.faces, mesh.faces)
    poly = load_field("polyhedron")
    p = np.array([[300.0, 20.0, -10.0]])
    np.testing.assert_array_equal(poly.acceleration_batch(p), exact.acceleration_batch(p))
    table = load_field("table")
    assert isinstance(table.exact, _LazyExact)
    q = np.array([[0.0, 0.0, 200.0], [150.0, 150.0, 0.0]])  # below the table's radii
    np.testing.assert_array_equal(fields_mod.exact_samples(table, q), exact.acceleration_batch(q))


def test_samples_file_is_checked_against_the_shipped_mesh(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    model = OrbitModel(load_field("table"))
    _, slow = contact_samples(model, load_surface())
    with np.load(shape_cache.SAMPLES_FILE) as data:
        stored = np.array(data["acc"])
    np.testing.assert_array_equal(fields_mod.exact_samples(model.field, slow), stored)
    calls = []
    real = _LazyExact.acceleration

    def counted(self, pts):  # type: ignore[no-untyped-def]
        calls.append(len(pts))
        return real(self, pts)

    monkeypatch.setattr(_LazyExact, "acceleration", counted)
    np.testing.assert_array_equal(fields_mod.exact_samples(model.field, slow), stored)
    assert calls == []  # answered by the file
    monkeypatch.setattr(fields_mod, "shipped_sha256", lambda: "0" * 64)  # another shape: evaluated
    fresh = fields_mod.exact_samples(model.field, slow[:4])
    assert calls == [4]
    np.testing.assert_allclose(fresh, stored[:4], rtol=1e-12)


def test_missing_shape_file_is_one_clear_line(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from satellite.errors import GravityModelError

    missing = tmp_path / "nope.obj"
    with pytest.raises(FileNotFoundError, match=r"shape file not found: .*nope\.obj \(an OBJ triangle mesh"):
        load_surface(missing)
    with pytest.raises(GravityModelError, match=r"shape file not found: .*nope\.obj"):
        load_field("polyhedron", shape=missing)
