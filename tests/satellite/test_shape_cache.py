"""Start-up caches of the default shape (satellite/shape_cache.py): the same numbers as without them."""

from __future__ import annotations

import numpy as np
import pytest

from satellite import shape_cache
from satellite.contact import contact_samples, make_contact
from satellite.fields import load_field
from satellite.mesh import parse_obj, read_obj
from satellite.mesh_surface import default_shape_path, load_surface
from satellite.model import OrbitModel

pytestmark = pytest.mark.skipif(not default_shape_path().is_file(), reason="the shape file is not available")


def test_cached_mesh_is_the_parsed_mesh(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    path = default_shape_path()
    monkeypatch.setattr(shape_cache, "_MEMO", {})
    got = read_obj(path)  # from the committed arrays
    want = parse_obj(path)
    assert np.array_equal(got.vertices, want.vertices) and np.array_equal(got.faces, want.faces)
    assert got.faces.dtype == want.faces.dtype and not got.vertices.flags.writeable
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
    np.testing.assert_array_equal(shape_cache.exact_samples(model.field, slow), stored)
    fresh = shape_cache.exact_samples(model.field, slow[:3].copy() * 1.0)  # a subset: evaluated, not looked up
    np.testing.assert_allclose(fresh, stored[:3], rtol=1e-12)


def test_contact_bound_does_not_depend_on_the_cache(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    model = OrbitModel(load_field("table"))
    shape = load_surface()
    cached = make_contact(model, shape).accel_bound  # the default samples: the committed file answers
    monkeypatch.setattr(shape_cache, "SAMPLES_FILE", shape_cache.DATA / "absent.npz")
    # the exact field evaluated (~1 s). Equal to the bit on the machine that wrote the file; on another
    # the field's sums over 49,152 faces (BLAS products, whose kernels and summation order OpenBLAS picks
    # per CPU, and numpy's arctan2/log loops) round differently in the last bits (AMD file vs Intel:
    # 1.6060173367940555e-4 vs ...568, 8e-16 relative), hence rtol 1e-12, the bound of the check above
    assert make_contact(model, shape).accel_bound == pytest.approx(cached, rel=1e-12, abs=0.0)
