"""``python -m satellite.cli.caches``: regenerate the shipped shape files from the raw Gaskell OBJ.

Writes :data:`satellite.shape.cache.MESH_FILE` (the checked mesh and its OBJ's SHA-256) and
:data:`satellite.shape.cache.SAMPLES_FILE` (the exact field at the contact watch's samples below the
gravity table's radii), atomically. Runs never need the raw OBJ; only this and ``isf-satellite gravity
--table`` read it (:func:`satellite.shape.mesh_surface.default_shape_path`).
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from isf_robot.support.files import write_bytes_atomic
from satellite.control.contact import contact_samples
from satellite.gravity.fields import load_field
from satellite.orbit.model import OrbitModel
from satellite.shape.cache import MESH_FILE, SAMPLES_FILE, SHAPE_NAME, forget_shipped, sha256_of
from satellite.shape.mesh import parse_obj
from satellite.shape.mesh_surface import default_shape_path, load_surface

__all__ = ["write_caches"]


def _write(path: Path, **arrays: Any) -> None:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_bytes_atomic(path, buf.getvalue())


def write_caches() -> list[Path]:
    """Write the shipped mesh and contact-sample files from the raw shape file; returns the paths written.

    Raises:
        FileNotFoundError: The raw shape file (:func:`satellite.shape.mesh_surface.default_shape_path`) is absent.

    """
    shape = default_shape_path()
    if not shape.is_file():
        raise FileNotFoundError(f"shape file not found: {shape} (the raw Gaskell {SHAPE_NAME}; set ISF_ROBOT_DATA "
                                f"to the folder holding itokawa/{SHAPE_NAME})")
    mesh = parse_obj(shape, units="km")
    _write(MESH_FILE, sha256=np.array(sha256_of(shape)), units=np.array("km"), vertices=mesh.vertices,
           faces=mesh.faces.astype(np.int32))
    forget_shipped()
    model = OrbitModel(load_field("table"))
    _, slow = contact_samples(model, load_surface())
    acc = model.field.exact.acceleration(slow)
    _write(SAMPLES_FILE, sha256=np.array(sha256_of(shape)), gm=np.array(float(model.field.gm)), points=slow, acc=acc)
    return [MESH_FILE, SAMPLES_FILE]


if __name__ == "__main__":  # pragma: no cover (a maintenance command)
    for written in write_caches():
        print(f"{written} written")
