"""The gravity table on disk: JSON with ``degree``, ``r_ref_m``, ``gm``, ``C`` and ``S`` rows.

Format (written by :func:`write_table`, read by :func:`read_table` and :func:`table_arrays`)::

    {
     "provenance": {...},             # optional: how the table was made (isf-satellite gravity)
     "degree": N,
     "r_ref_m": R,                    # reference radius [m]
     "gm": GM,                        # [m^3/s^2]
     "normalisation": "full (4-pi geodesy), no Condon-Shortley phase",
     "C": [[C00], [C10, C11], ...],   # row n has n + 1 (or N + 1) entries
     "S": [[S00], [S10, S11], ...]
    }

Floats are written with ``json.dumps`` (shortest round-trip repr), so a table read back gives
the same coefficients to the bit. The field these numbers define is :class:`satellite.gravity.spherical.GravityField`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from isf_robot.support.files import write_text_atomic
from satellite.errors import GravityModelError
from satellite.gravity.harmonics import check_degree

__all__ = [
    "DEFAULT_TABLE",
    "NORMALISATION_NOTE",
    "table_arrays",
    "table_dict",
    "read_table",
    "read_default_table",
    "write_table",
]

DEFAULT_TABLE = "itokawa_degree8.json"
"""File name of the committed Itokawa table in ``satellite/data/``."""

NORMALISATION_NOTE = "full (4-pi geodesy), no Condon-Shortley phase"
"""Value of the table's ``normalisation`` key (see :mod:`satellite.gravity.harmonics`)."""


def _square(rows: Any, degree: int, name: str) -> NDArray[np.float64]:
    """Turn triangular or square row lists into a (N+1, N+1) array."""
    out = np.zeros((degree + 1, degree + 1))
    try:
        if len(rows) != degree + 1:
            raise GravityModelError(
                f"{name} has {len(rows)} rows, expected degree + 1 = {degree + 1}"
            )
        for n, row in enumerate(rows):
            vals = np.asarray(row, dtype=np.float64).reshape(-1)
            if vals.size < n + 1 or vals.size > degree + 1:
                raise GravityModelError(
                    f"{name}[{n}] has {vals.size} entries, expected {n + 1}..{degree + 1}"
                )
            out[n, : vals.size] = vals
    except (TypeError, ValueError) as exc:
        if isinstance(exc, GravityModelError):
            raise
        raise GravityModelError(f"{name} must be a list of numeric rows: {exc}") from None
    return out


def table_arrays(data: Mapping[str, Any]) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
    """Check a table mapping and return its ``(C, S, r_ref_m, gm)``.

    Args:
        data: Mapping with ``degree``, ``r_ref_m`` [m], ``gm`` [m^3/s^2], ``C`` and ``S``
            (``C[n][m]``); rows may be triangular (``n + 1`` entries) or full (``degree + 1``).

    Returns:
        ``C`` and ``S``, each shape (N+1, N+1) with zeros above the diagonal, ``R`` [m] and ``GM``
        [m^3/s^2] (their values are checked by :class:`satellite.gravity.spherical.GravityField`).

    Raises:
        GravityModelError: Missing keys, a bad degree, non-numeric values, or badly sized rows.

    """
    missing = [k for k in ("degree", "r_ref_m", "gm", "C", "S") if k not in data]
    if missing:
        raise GravityModelError(
            f"gravity table lacks key(s) {missing}; needs degree, r_ref_m, gm, C, S"
        )
    degree = check_degree(data["degree"])
    try:
        r_ref, gm = float(data["r_ref_m"]), float(data["gm"])
    except (TypeError, ValueError):
        raise GravityModelError("r_ref_m and gm must be numbers") from None
    return _square(data["C"], degree, "C"), _square(data["S"], degree, "S"), r_ref, gm


def table_dict(
    C: NDArray[np.float64],  # noqa: N803
    S: NDArray[np.float64],  # noqa: N803
    r_ref_m: float,
    gm: float,
    provenance: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The JSON-ready table of a field.

    Args:
        C: ``Cbar_nm``, shape (N+1, N+1).
        S: ``Sbar_nm``, shape (N+1, N+1).
        r_ref_m: Reference radius [m].
        gm: ``GM`` [m^3/s^2].
        provenance: Optional description of how the table was made (stored first).

    Returns:
        ``provenance`` (if given), ``degree``, ``r_ref_m``, ``gm``, ``normalisation``, and the
        triangular rows of ``C`` and ``S``.

    """
    degree = C.shape[0] - 1
    out: dict[str, Any] = {}
    if provenance is not None:
        out["provenance"] = dict(provenance)
    out["degree"] = degree
    out["r_ref_m"] = float(r_ref_m)
    out["gm"] = float(gm)
    out["normalisation"] = NORMALISATION_NOTE
    out["C"] = [C[n, : n + 1].tolist() for n in range(degree + 1)]
    out["S"] = [S[n, : n + 1].tolist() for n in range(degree + 1)]
    return out


def read_table(path: str | Path) -> dict[str, Any]:
    """Read a table file as a mapping (checked by :func:`table_arrays` when it is used).

    Raises:
        GravityModelError: Not valid JSON, or not a JSON object.
        OSError: The file cannot be read.

    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise GravityModelError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise GravityModelError(f"{path}: expected a JSON object")
    return data


def read_default_table() -> dict[str, Any]:
    """The committed Itokawa table, ``satellite/data/itokawa_degree8.json``, as a mapping."""
    resource = resources.files("satellite") / "data" / DEFAULT_TABLE
    with resources.as_file(resource) as path:
        return read_table(path)


def write_table(path: str | Path, data: Mapping[str, Any]) -> None:
    """Write a table mapping (from :func:`table_dict`) as JSON, one coefficient row per line (atomically)."""
    parts = []
    for key, value in data.items():
        if key in ("C", "S"):
            rows = ",\n".join("  " + json.dumps(row) for row in value)
            text = "[\n" + rows + "\n ]"
        else:
            text = json.dumps(value, indent=1).replace("\n", "\n ")
        parts.append(f" {json.dumps(key)}: {text}")
    write_text_atomic(path, "{\n" + ",\n".join(parts) + "\n}\n")
