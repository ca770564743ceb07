"""The default shape as shipped, and start-up caches: its checked mesh, the exact field at the contact samples.

The default shape of every run is the Gaskell Itokawa model (``itokawa_low.obj``, 49,152 faces,
24,578 vertices; provenance in the gravity table's meta, ``GravityTable.load(...).provenance``),
shipped as its checked mesh ``satellite/data/itokawa_low_mesh.npz`` (vertices [m], outward faces,
the OBJ's SHA-256 and unit: exactly the arrays :func:`satellite.mesh.parse_obj` gives). A run reads it
for the contact watch's surface, the exact field behind the gravity table and ``--gravity polyhedron``
(:func:`shipped_mesh`), and takes the exact polyhedron field at the contact watch's up to 100 sample
points below the table's radii (:func:`satellite.contact.make_contact`, ~1.2 s of field sums) from
``satellite/data/itokawa_contact_samples.npz`` (:func:`exact_samples`). The raw OBJ (in the shared data
folder, :func:`satellite.mesh_surface.default_shape_path`) is needed only to regenerate these files
(``python -m satellite.shape_cache``, atomically) and the gravity table (``isf-satellite gravity --table``).

* :func:`lookup` / :func:`remember` (used by :func:`satellite.mesh.read_obj`): a parsed mesh is kept
  for the process (keyed by the file's path, modification time, size and unit), and an OBJ with the
  shipped mesh's SHA-256 and unit is answered by the shipped arrays.
* :func:`exact_samples`: the exact field at points, taken from the samples file when it holds exactly
  these points for the shipped shape (its SHA-256) and ``GM``; otherwise evaluated.

A stale samples file only costs the time it saves, never changes a number on the machine that wrote it
(on another CPU the evaluated exact field can differ from the file in the last bits, ~1e-15 relative: its
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

__all__ = ["MESH_FILE", "SAMPLES_FILE", "SHAPE_NAME", "shipped_mesh", "shipped_sha256", "lookup", "remember",
           "exact_samples", "write_caches"]

DATA = Path(__file__).resolve().parent / "data"
MESH_FILE = DATA / "itokawa_low_mesh.npz"
"""The default shape's checked mesh (vertices [m], outward faces) and the SHA-256 of its OBJ."""

SHAPE_NAME = "itokawa_low.obj"
"""The file name of the default shape (Gaskell's model) the shipped mesh was checked from."""

SAMPLES_FILE = DATA / "itokawa_contact_samples.npz"
"""The exact field at the contact watch's samples below the table's radii, for the default shape."""

_MEMO: dict[Any, Any] = {}
_SHIPPED = ("shipped",)
_SHA: dict[tuple[str, int, int], str] = {}


def _stat_key(path: Path) -> tuple[str, int, int]:
    st = path.stat()
    return str(path.resolve()), st.st_mtime_ns, st.st_size


def _sha256(path: Path) -> str:
    key = _stat_key(path)
    if key not in _SHA:
        _SHA[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return _SHA[key]


def _shipped() -> tuple[Any, str, str]:
    """``(mesh, sha256, units)`` of :data:`MESH_FILE`, read once per process."""
    got = _MEMO.get(_SHIPPED)
    if got is None:
        from satellite.errors import MeshError
        from satellite.mesh import TriangleMesh

        try:
            with np.load(MESH_FILE) as data:
                v = np.array(data["vertices"], dtype=np.float64)
                f = np.array(data["faces"], dtype=np.intp)
                sha, units = str(data["sha256"]), str(data["units"])
        except (OSError, KeyError, ValueError) as exc:
            raise MeshError(f"the shipped shape {MESH_FILE} is missing or unreadable ({exc}); "
                            "reinstall isf-robot") from None
        v.setflags(write=False)
        f.setflags(write=False)
        got = _MEMO[_SHIPPED] = (TriangleMesh(v, f), sha, units)
    return got  # type: ignore[no-any-return]


def shipped_mesh() -> Any:
    """The default shape's checked mesh (:class:`satellite.mesh.TriangleMesh`, metres, the OBJ's own frame).

    Raises:
        MeshError: The package's mesh file is missing or unreadable (a broken install).

    """
    return _shipped()[0]


def shipped_sha256() -> str:
    """SHA-256 of the OBJ file the shipped mesh was read from."""
    return str(_shipped()[1])


def lookup(path: str | Path, units: str) -> Any:
    """The mesh of an OBJ file read before in this process, or the shipped mesh for the same file, else ``None``."""
    p = Path(path)
    try:
        key = (*_stat_key(p), units)
    except OSError:
        return None
    mesh = _MEMO.get(key)
    if mesh is None and MESH_FILE.is_file():
        try:
            shipped, sha, shipped_units = _shipped()
        except Exception:  # noqa: BLE001 (an unreadable cache only costs the parse)
            return None
        if shipped_units == units and sha == _sha256(p):
            mesh = _MEMO[key] = shipped
    return mesh


def remember(path: str | Path, units: str, mesh: Any) -> None:
    """Keep a parsed mesh for later reads of the same file in this process."""
    try:
        _MEMO[(*_stat_key(Path(path)), units)] = mesh
    except OSError:
        pass


def exact_samples(field: Any, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """The exact field at points outside a table's radii, from :data:`SAMPLES_FILE` if it holds them.

    ``field.exact`` (the exact field behind a gravity table) answers; a field without one answers
    itself (``field.acceleration_batch``). The file answers only for the committed table's exact field
    (the shipped shape's polyhedron, checked by its SHA-256) and exactly these points.
    """
    from satellite.fields import _LazyExact

    exact = getattr(field, "exact", None)
    if isinstance(exact, _LazyExact) and SAMPLES_FILE.is_file():
        try:
            with np.load(SAMPLES_FILE) as data:
                if (str(data["sha256"]) == shipped_sha256() and float(data["gm"]) == float(field.gm)
                        and np.array_equal(data["points"], points)):
                    return np.array(data["acc"], dtype=np.float64)
        except (OSError, KeyError, ValueError):
            pass
    if exact is not None:
        return np.asarray(exact.acceleration(np.asarray(points, dtype=np.float64).reshape(-1, 3)), dtype=np.float64)
    return np.asarray(field.acceleration_batch(points), dtype=np.float64)


def _write(path: Path, **arrays: Any) -> None:
    from isf_robot.support.files import write_bytes_atomic

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_bytes_atomic(path, buf.getvalue())


def write_caches() -> list[Path]:
    """Write :data:`MESH_FILE` and :data:`SAMPLES_FILE` from the raw shape file; returns the paths written.

    Raises:
        FileNotFoundError: The raw shape file (:func:`satellite.mesh_surface.default_shape_path`) is absent.

    """
    from satellite.contact import contact_samples
    from satellite.fields import load_field
    from satellite.mesh import parse_obj
    from satellite.mesh_surface import default_shape_path, load_surface
    from satellite.model import OrbitModel

    shape = default_shape_path()
    if not shape.is_file():
        raise FileNotFoundError(f"shape file not found: {shape} (the raw Gaskell {SHAPE_NAME}; set ISF_ROBOT_DATA "
                                f"to the folder holding itokawa/{SHAPE_NAME})")
    mesh = parse_obj(shape, units="km")
    _write(MESH_FILE, sha256=np.array(_sha256(shape)), units=np.array("km"), vertices=mesh.vertices,
           faces=mesh.faces.astype(np.int32))
    _MEMO.pop(_SHIPPED, None)
    model = OrbitModel(load_field("table"))
    _, slow = contact_samples(model, load_surface())
    acc = model.field.exact.acceleration(slow)
    _write(SAMPLES_FILE, sha256=np.array(_sha256(shape)), gm=np.array(float(model.field.gm)), points=slow, acc=acc)
    return [MESH_FILE, SAMPLES_FILE]


if __name__ == "__main__":  # pragma: no cover (a maintenance command)
    for written in write_caches():
        print(f"{written} written")
