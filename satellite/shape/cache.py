"""The default shape as shipped, and the parsed-mesh cache of a process.

The default shape of every run is the Gaskell Itokawa model (``itokawa_low.obj``, 49,152 faces,
24,578 vertices; provenance in the gravity table's meta, ``GravityTable.load(...).provenance``),
shipped as its checked mesh ``satellite/data/itokawa_low_mesh.npz`` (vertices [m], outward faces,
the OBJ's SHA-256 and unit: exactly the arrays :func:`satellite.shape.mesh.parse_obj` gives). A run reads it
for the contact watch's surface, the exact field behind the gravity table and ``--gravity polyhedron``
(:func:`shipped_mesh`). The exact field at the contact watch's sample points below the table's radii
ships beside it (:data:`SAMPLES_FILE`, read by :func:`satellite.gravity.fields.exact_samples`). The raw OBJ
(in the shared data folder, :func:`satellite.shape.mesh_surface.default_shape_path`) is needed only to
regenerate these files (``python -m satellite.cli.caches``, atomically) and the gravity table
(``isf-satellite gravity --table``).

:func:`read_obj` is :func:`~satellite.shape.mesh.parse_obj` through the cache (:func:`lookup` /
:func:`remember`): a parsed mesh is kept for the process (keyed by the file's path, modification time,
size and unit), and an OBJ with the shipped mesh's SHA-256 and unit is answered by the shipped arrays.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from satellite.errors import MeshError
from satellite.shape.mesh import UNIT_SCALES, TriangleMesh, parse_obj

__all__ = ["DATA", "MESH_FILE", "SAMPLES_FILE", "SHAPE_NAME", "shipped_mesh", "shipped_sha256", "forget_shipped",
           "sha256_of", "read_obj", "lookup", "remember"]

DATA = Path(__file__).resolve().parents[1] / "data"
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


def sha256_of(path: Path) -> str:
    """SHA-256 of a file (kept per path, modification time and size)."""
    key = _stat_key(path)
    if key not in _SHA:
        _SHA[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return _SHA[key]


def _shipped() -> tuple[Any, str, str]:
    """``(mesh, sha256, units)`` of :data:`MESH_FILE`, read once per process."""
    got = _MEMO.get(_SHIPPED)
    if got is None:
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
    """The default shape's checked mesh (:class:`satellite.shape.mesh.TriangleMesh`, metres, the OBJ's own frame).

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
        if shipped_units == units and sha == sha256_of(p):
            mesh = _MEMO[key] = shipped
    return mesh


def remember(path: str | Path, units: str, mesh: Any) -> None:
    """Keep a parsed mesh for later reads of the same file in this process."""
    try:
        _MEMO[(*_stat_key(Path(path)), units)] = mesh
    except OSError:
        pass


def read_obj(path: str | Path, units: str = "km") -> TriangleMesh:
    """:func:`parse_obj`, through this cache (a file read before, the default shape's arrays)."""
    mesh = lookup(path, units) if units in UNIT_SCALES else None
    if mesh is None:
        mesh = parse_obj(path, units)
        remember(path, units, mesh)
    return mesh  # type: ignore[no-any-return]


def forget_shipped() -> None:
    """Drop the shipped mesh read by this process (after its file was rewritten)."""
    _MEMO.pop(_SHIPPED, None)
