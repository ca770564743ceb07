"""The truth gravity models of a run, by name (``isf-satellite run --gravity``).

* ``table`` (default): the exact constant-density polyhedron field of the Gaskell shape model,
  tabulated once on a body-frame shell grid around the band (:mod:`satellite.gravity.table`),
  corrected within 35 m of the surface by fine Cartesian B-spline boxes (4 m nodes,
  :mod:`satellite.gravity.fine`, built from exact sums of the nearby faces,
  :mod:`satellite.gravity.near`); committed as ``satellite/data/itokawa_polyhedron_table.npz``
  (derived from the shape file, which ships as its checked mesh; provenance inside:
  ``GravityTable.load(...).provenance``).
  Valid everywhere in the band; its measured error is in REPRODUCTION.md. Outside the table's
  radii (1.5625 R .. 2.4375 R: only DOP853's stage and trial points, or a trajectory past a
  reported band exit) its shell part is continued radially
  (:func:`satellite.gravity.table.shell_continued`); the exact field behind it (of the shipped
  shape, :func:`exact_itokawa`) answers the contact watch's samples there.
* ``sh8``: the paper's degree-8 spherical harmonics (``satellite/data/itokawa_degree8.json``);
  the series diverges inside the Brillouin sphere (1.925 R), i.e. in the band's inner part.
* ``polyhedron``: the exact field evaluated at every step (:mod:`satellite.gravity.polyhedron`, of the
  shipped shape or of ``--shape FILE``; some ms per evaluation, for checks, not for long runs).
* a path ending in ``.json``: a spherical-harmonic table written by ``isf-satellite gravity``;
  a path ending in ``.npz``: a table written by ``isf-satellite gravity --table`` (of any body:
  no exact field behind it; outside its radii the continuation answers everything).

All share the interface :class:`satellite.orbit.model.OrbitModel` uses: ``r_ref_m``, ``gm``,
``acceleration(p)`` (one body-frame point) and ``acceleration_batch(P)``, plus ``model_name``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from satellite.errors import GravityModelError
from satellite.gravity.polyhedron import PolyhedronField
from satellite.gravity.spherical import GravityField, load_default_field
from satellite.gravity.table import GravityTable
from satellite.shape.cache import SAMPLES_FILE, read_obj, shipped_mesh, shipped_sha256

__all__ = ["GRAVITY_MODELS", "DEFAULT_GRAVITY", "TABLE_FILE", "ExactField", "load_field", "exact_itokawa",
           "model_name", "exact_samples"]

GRAVITY_MODELS = ("table", "sh8", "polyhedron")
"""Gravity model names accepted by :func:`load_field` (besides ``.json`` paths)."""

DEFAULT_GRAVITY = "table"
"""The default truth model."""

TABLE_FILE = "itokawa_polyhedron_table.npz"
"""The committed table in ``satellite/data/``."""


class ExactField:
    """The exact polyhedron field with the interface of a gravity table (one point or many)."""

    degree = None
    model_name = "polyhedron"

    def __init__(self, field: PolyhedronField, r_ref_m: float) -> None:
        self.field = field
        self.r_ref_m = float(r_ref_m)
        self.gm = field.gm

    def acceleration(self, r_body: ArrayLike) -> NDArray[np.float64]:
        """Acceleration [m/s^2] at one body-frame point [m] (shape (3,)) or many (shape (N, 3))."""
        p = np.asarray(r_body, dtype=np.float64)
        return self.field.acceleration(p) if p.ndim == 2 else self.field.acceleration(p.reshape(1, 3))[0]

    def acceleration_batch(self, r_body: ArrayLike) -> NDArray[np.float64]:
        """Acceleration [m/s^2] at body-frame points [m], shape (N, 3)."""
        return self.field.acceleration(r_body)


def exact_itokawa(shape: str | Path | None = None, units: str = "km") -> ExactField:
    """The exact field of the Itokawa shape (``GM`` and ``R`` of the degree-8 table).

    Args:
        shape: An OBJ file; ``None`` for the shipped shape (:func:`satellite.shape.cache.shipped_mesh`).
        units: Length unit of ``shape``.

    Raises:
        GravityModelError: ``shape`` does not exist.
        MeshError: ``shape`` is not a closed, oriented triangle mesh.

    """
    if shape is None:
        mesh = shipped_mesh()
    else:
        if not Path(shape).is_file():
            raise GravityModelError(f"shape file not found: {shape} (an OBJ triangle mesh; without --shape the "
                                    "shipped Itokawa shape is used)")
        mesh = read_obj(shape, units=units)
    sh = load_default_field()
    return ExactField(PolyhedronField.from_mesh(mesh, sh.gm), sh.r_ref_m)


def model_name(field: Any) -> str:
    """``sh<degree>`` for a spherical-harmonic field, else the field's ``model_name``."""
    if isinstance(field, GravityField):
        return f"sh{field.degree}"
    return str(getattr(field, "model_name", type(field).__name__))


def load_field(name: str = DEFAULT_GRAVITY, shape: str | Path | None = None, units: str = "km") -> Any:
    """The gravity model called ``name`` (see the module docstring).

    Args:
        name: A name of :data:`GRAVITY_MODELS` or a ``.json``/``.npz`` file.
        shape: For ``polyhedron``: an OBJ file instead of the shipped shape (ignored by the others).
        units: Length unit of ``shape``.

    Raises:
        GravityModelError: Unknown name, missing shape file (``polyhedron``), unreadable table.

    """
    if name == "sh8":
        return load_default_field()
    if name == "table":
        return _committed_table()
    if name == "polyhedron":
        return exact_itokawa(shape, units)
    if name.endswith((".json", ".npz")) and not Path(name).is_file():
        raise GravityModelError(f"gravity file not found: {name} (give {', '.join(GRAVITY_MODELS)}, or a .json series "
                                "or .npz table written by `isf-satellite gravity`)")
    if name.endswith(".json"):
        return GravityField.from_json(name)
    if name.endswith(".npz"):
        return GravityTable.load(name)
    raise GravityModelError(f"unknown gravity model {name!r}; valid: {', '.join(GRAVITY_MODELS)}, FILE.json "
                            "or FILE.npz")


class _LazyExact:
    """The exact field of the shipped shape, read on first use (the contact watch's samples below the table's radii)."""

    def __init__(self) -> None:
        self._field: ExactField | None = None

    def acceleration(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        if self._field is None:
            self._field = exact_itokawa()
        return self._field.field.acceleration(p)


_TABLE: GravityTable | None = None


def _committed_table() -> GravityTable:
    """The committed table, read once per process (it is not modified by its users)."""
    global _TABLE
    if _TABLE is None:
        resource = resources.files("satellite") / "data" / TABLE_FILE
        with resources.as_file(resource) as path:
            if not Path(path).is_file():
                raise GravityModelError(f"the committed table {TABLE_FILE} is missing (build it: "
                                        "`isf-satellite gravity --table`)")
            table = GravityTable.load(path)
        table.exact = _LazyExact()
        _TABLE = table
    return _TABLE


def exact_samples(field: Any, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """The exact field at points outside a table's radii, from the shipped samples file if it holds them.

    ``field.exact`` (the exact field behind a gravity table) answers; a field without one answers
    itself (``field.acceleration_batch``). The file answers only for the committed table's exact field
    (the shipped shape's polyhedron, checked by its SHA-256) and exactly these points.
    """
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
