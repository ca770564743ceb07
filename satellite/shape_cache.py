"""Start-up caches for the default shape: the parsed mesh and the exact field at the contact watch's samples.

A run reads the Gaskell shape (``../shared/data/itokawa/itokawa_low.obj``, 49,152 faces) twice (the
contact watch's surface and the exact field behind the gravity table) and evaluates the exact
polyhedron field at up to 100 sample points below the table's radii for the contact watch's
acceleration bound (:func:`satellite.contact.make_contact`): ~0.5 s per parse and ~1.2 s of field sums
at every start. Here:

* :func:`lookup` / :func:`remember` (used by :func:`satellite.mesh.read_obj`): a parsed mesh is kept
  for the process (keyed by the file's path, modification time, size and unit), and the default
  shape comes from ``satellite/data/itokawa_low_mesh.npz`` (the checked mesh's arrays) when that file
  was written from a shape file with the same SHA-256 and unit; otherwise the OBJ is parsed.
* :func:`exact_samples`: the exact field at points, taken from
  ``satellite/data/itokawa_contact_samples.npz`` when it holds exactly these points for this shape
  (SHA-256) and ``GM``; otherwise evaluated.

Both files are written by ``python -m satellite.shape_cache`` (atomically) from the shape file; a stale
or missing file only costs the time it saves, never changes a number on the machine that wrote it (on
another CPU the evaluated exact field can differ from the file in the last bits, ~1e-15 relative: its
BLAS sums and numpy's arctan2/log loops round per CPU). The sample points themselves are the same on
every machine (:func:`satellite.contact.contact_samples` takes latitude/longitude from libm).
"""

from __future__ import annotations

import hashlib
import io
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["MESH_FILE", "SAMPLES_FILE", "lookup", "remember", "exact_samples", "write_caches"]

DATA = Path(__file__).resolve().parent / "data"
MESH_FILE = DATA / "itokawa_low_mesh.npz"
"""The default shape's checked mesh (vertices [m], outward faces) and the SHA-256 of its OBJ."""

SAMPLES_FILE = DATA / "itokawa_contact_samples.npz"
"""The exact field at the contact watch's samples below the table's radii, for the default shape."""

_MEMO: dict[tuple[str, int, int, str], Any] = {}
_SHA: dict[tuple[str, int, int], str] = {}


def _stat_key(path: Path) -> tuple[str, int, int]:
    st = path.stat()
    return str(path.resolve()), st.st_mtime_ns, st.st_size


def _sha256(path: Path) -> str:
    key = _stat_key(path)
    if key not in _SHA:
        _SHA[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return _SHA[key]


def lookup(path: str | Path, units: str) -> Any:
    """The mesh of an OBJ file read before in this process, or from :data:`MESH_FILE`; ``None`` otherwise."""
    p = Path(path)
    try:
        key = (*_stat_key(p), units)
    except OSError:
        return None
    mesh = _MEMO.get(key)
    if mesh is None and MESH_FILE.is_file():
        try:
            with np.load(MESH_FILE) as data:
                if str(data["units"]) == units and str(data["sha256"]) == _sha256(p):
                    from satellite.mesh import TriangleMesh

                    v = np.array(data["vertices"], dtype=np.float64)
                    f = np.array(data["faces"], dtype=np.intp)
                    v.setflags(write=False)
                    f.setflags(write=False)
                    mesh = _MEMO[key] = TriangleMesh(v, f)
        except (OSError, KeyError, ValueError):
            return None
    return mesh


def remember(path: str | Path, units: str, mesh: Any) -> None:
    """Keep a parsed mesh for later reads of the same file in this process."""
    try:
        _MEMO[(*_stat_key(Path(path)), units)] = mesh
    except OSError:
        pass


def exact_samples(field: Any, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """``field.acceleration_batch(points)`` (outside the table's radii), from :data:`SAMPLES_FILE` if it holds them.

    The file answers only for the committed table's exact field (the default shape's polyhedron) and
    exactly these points; any other field or point set is evaluated.
    """
    from satellite.fields import _LazyExact
    from satellite.mesh_surface import default_shape_path

    shape = default_shape_path()
    if isinstance(getattr(field, "exact", None), _LazyExact) and SAMPLES_FILE.is_file() and shape.is_file():
        try:
            with np.load(SAMPLES_FILE) as data:
                if (str(data["sha256"]) == _sha256(shape) and float(data["gm"]) == float(field.gm)
                        and np.array_equal(data["points"], points)):
                    return np.array(data["acc"], dtype=np.float64)
        except (OSError, KeyError, ValueError):
            pass
    return np.asarray(field.acceleration_batch(points), dtype=np.float64)


def _write(path: Path, **arrays: Any) -> None:
    from isf_robot.core.files import write_bytes_atomic

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_bytes_atomic(path, buf.getvalue())


def write_caches() -> list[Path]:
    """Write :data:`MESH_FILE` and :data:`SAMPLES_FILE` from the default shape file; returns the paths written."""
    from satellite.contact import contact_samples
    from satellite.fields import load_field
    from satellite.mesh import parse_obj
    from satellite.mesh_surface import default_shape_path, load_surface
    from satellite.model import OrbitModel

    shape = default_shape_path()
    if not shape.is_file():
        raise FileNotFoundError(f"shape file not found: {shape}")
    mesh = parse_obj(shape, units="km")
    _write(MESH_FILE, sha256=np.array(_sha256(shape)), units=np.array("km"), vertices=mesh.vertices,
           faces=mesh.faces.astype(np.int32))
    model = OrbitModel(load_field("table"))
    _, slow = contact_samples(model, load_surface())
    acc = model.field.acceleration_batch(slow)
    _write(SAMPLES_FILE, sha256=np.array(_sha256(shape)), gm=np.array(float(model.field.gm)), points=slow, acc=acc)
    return [MESH_FILE, SAMPLES_FILE]


if __name__ == "__main__":  # pragma: no cover (a maintenance command)
    for written in write_caches():
        print(f"{written} written")
