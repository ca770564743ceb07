"""The satellite recorder draws the body the run sends in its start info (it reads no shape file)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from isf_robot.record import SatelliteRecorder, open_stream
from isf_robot.record.errors import RecordError

# a tetrahedron about its centroid, outward faces
TET_V = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]]) * 100.0
TET_F = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])


def _static(path: Path, entity: str) -> dict[str, list]:  # type: ignore[type-arg]
    out: dict[str, list] = {}  # type: ignore[type-arg]
    for chunk in RrdReader(path).stream():
        if chunk.is_static and chunk.entity_path == entity:
            batch = chunk.to_record_batch()
            for field in batch.schema:
                if (field.metadata or {}).get(b"rerun:kind") == b"data":
                    out.setdefault(field.name, []).extend(batch.column(field.name).to_pylist())
    return out


def _record(path: Path, info: dict) -> SatelliteRecorder:  # type: ignore[type-arg]
    rec = SatelliteRecorder(open_stream("isf_robot_satellite", rrd_path=path), radius_m=162.0)
    rec.on_start(info)
    rec.on_finish({})
    return rec


def test_body_mesh_from_start_info_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "tet.rrd"
    rec = _record(path, {"R_m": 162.0, "body_mesh": {"vertices": TET_V, "faces": TET_F, "name": "tet"}})
    assert rec.body_shape == "mesh:tet"
    cols = _static(path, "/world/body/shape")
    np.testing.assert_allclose(np.asarray(cols["Mesh3D:vertex_positions"][0]), TET_V, rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(cols["Mesh3D:triangle_indices"][0]), TET_F)
    assert "mesh:tet" in str(_static(path, "/run/body_shape"))
    info = json.loads(np.ravel(_static(path, "/run/info")["info_json"])[-1])
    assert info["R_m"] == 162.0 and "body_mesh" not in info  # the triangles are drawn, not copied


def test_no_body_mesh_draws_the_ellipsoid(tmp_path: Path) -> None:
    path = tmp_path / "e.rrd"
    rec = _record(path, {"R_m": 162.0})
    assert rec.body_shape == "ellipsoid"
    cols = _static(path, "/world/body/shape")
    np.testing.assert_allclose(np.asarray(cols["Ellipsoids3D:half_sizes"][0]), [[267.5, 147.0, 104.5]])


@pytest.mark.parametrize("mesh", [
    {"vertices": TET_V},                                  # no faces
    {"vertices": TET_V[:, :2], "faces": TET_F},           # 2-D vertices
    {"vertices": TET_V, "faces": TET_F + 1},              # index out of range
    {"vertices": TET_V, "faces": TET_F.astype(float)},    # float indices
    "tet.obj",                                            # a path is not a mesh
])
def test_bad_body_mesh_is_a_record_error(tmp_path: Path, mesh: object) -> None:
    with pytest.raises(RecordError, match="body_mesh"):
        _record(tmp_path / "bad.rrd", {"R_m": 162.0, "body_mesh": mesh})


def test_simulated_run_sends_the_shape_model(sat_run) -> None:  # type: ignore[no-untyped-def]
    from satellite.shape.mesh_surface import body_mesh_info

    mesh = body_mesh_info()
    if mesh is None:
        assert sat_run.recorder.body_shape == "ellipsoid"
        return
    assert sat_run.recorder.body_shape == f"mesh:{mesh['name']}"
    cols = _static(sat_run.path, "/world/body/shape")
    np.testing.assert_allclose(np.asarray(cols["Mesh3D:vertex_positions"][0]), mesh["vertices"], rtol=1e-6,
                               atol=1e-3)
    np.testing.assert_array_equal(np.asarray(cols["Mesh3D:triangle_indices"][0]), mesh["faces"])
