"""MuJoCo geometry drawn in Rerun: every geom type, static and moving bodies (tiny inline MJCF)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from rerun.chunk import RrdReader

from isf_robot.record import close_stream, open_stream
from isf_robot.record.mjgeometry import MujocoDrawing

MJCF = """
<mujoco>
  <asset>
    <mesh name="tet" vertex="0 0 0  0.1 0 0  0 0.1 0  0 0 0.1"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <geom name="post" type="cylinder" size="0.05 0.2" pos="0.5 0 0.2"/>
    <body name="arm" pos="0 0 0.3">
      <joint name="hinge" type="hinge" axis="0 0 1"/>
      <geom name="link" type="capsule" size="0.03 0.15" pos="0.15 0 0" euler="0 90 0"/>
      <geom name="tip" type="sphere" size="0.04" pos="0.3 0 0"/>
      <geom name="egg" type="ellipsoid" size="0.02 0.03 0.04" pos="0.1 0.1 0"/>
      <geom name="tet" type="mesh" mesh="tet" pos="0 0.2 0"/>
    </body>
    <body name="crate" mocap="true" pos="0.6 0.4 0.1">
      <geom name="crate" type="box" size="0.1 0.05 0.05" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>
"""


def _static_components(path) -> dict[str, set[str]]:  # type: ignore[no-untyped-def]
    out: dict[str, set[str]] = {}
    for chunk in RrdReader(path).stream():
        if chunk.is_static:
            names = {f.name.split(":")[0] for f in chunk.to_record_batch().schema if ":" in f.name}
            out.setdefault(chunk.entity_path, set()).update(names)
    return out


def test_every_geom_type_is_drawn(tmp_path) -> None:  # type: ignore[no-untyped-def]
    model = mujoco.MjModel.from_xml_string(MJCF)
    draw = MujocoDrawing(model)
    path = tmp_path / "geoms.rrd"
    rec = open_stream("isf_robot", rrd_path=path)
    draw.log_static(rec)
    assert draw.geoms_drawn == model.ngeom and not draw.geoms_skipped
    # moving bodies: the hinged arm and the mocap crate; the world is static
    assert sorted(draw.body_paths[b].rsplit("/", 1)[1] for b in draw.moving) == ["arm", "crate"]
    t = np.array([0.0, 0.1])
    data = mujoco.MjData(model)
    pos, quat = np.zeros((2, model.nbody, 3)), np.zeros((2, model.nbody, 4))
    for i, (q, crate) in enumerate([(0.0, [0.6, 0.4, 0.1]), (np.pi / 2, [0.7, 0.4, 0.1])]):
        data.qpos[0], data.mocap_pos[0] = q, crate
        mujoco.mj_kinematics(model, data)
        pos[i], quat[i] = data.xpos, data.xquat
    with pytest.raises(ValueError, match="every body"):
        draw.send_poses(rec, t, pos[:, :1], quat)
    draw.send_poses(rec, t, pos, quat)
    close_stream(rec)
    comps = _static_components(path)
    want = {
        "/world/bodies/world/floor": "Boxes3D", "/world/bodies/world/post": "Cylinders3D",
        "/world/bodies/arm/link": "Capsules3D", "/world/bodies/arm/tip": "Ellipsoids3D",
        "/world/bodies/arm/egg": "Ellipsoids3D", "/world/bodies/arm/tet": "Mesh3D",
        "/world/bodies/crate/crate": "Boxes3D",
    }
    for entity, archetype in want.items():
        assert archetype in comps.get(entity, set()), (entity, comps.get(entity))
        assert "Transform3D" in comps[entity]
    assert "Transform3D" in comps["/world/bodies/world"]
    from isf_robot.record import read_columns

    arm = read_columns(path, "/world/bodies/arm")
    quat = arm["Transform3D:quaternion"]  # x, y, z, w
    np.testing.assert_allclose(quat[1], [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)], atol=1e-6)
    crate = read_columns(path, "/world/bodies/crate")
    np.testing.assert_allclose(crate["Transform3D:translation"][1], [0.7, 0.4, 0.1], atol=1e-6)


def test_transform_columns_are_rerun_own() -> None:
    """The Arrow-built pose columns equal ``rr.Transform3D.columns`` of the same poses, value for value."""
    import rerun as rr

    from isf_robot.record.mjgeometry import transform_columns

    rng = np.random.default_rng(3)
    pos, quat = rng.normal(size=(7, 3)), rng.normal(size=(7, 4))  # (w, x, y, z), not normalised: kept as given
    mine = list(transform_columns(pos, quat))
    ref = list(rr.Transform3D.columns(translation=pos, quaternion=quat[:, [1, 2, 3, 0]]))
    assert [c.component_descriptor() for c in mine] == [c.component_descriptor() for c in ref]
    for a, b in zip(mine, ref):
        assert a.as_arrow_array().equals(b.as_arrow_array())


def test_poses_of_moving_bodies_apart(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Moving bodies that are not consecutive (a static body between them): each gets its own poses back."""
    from isf_robot.record import read_columns

    xml = MJCF.replace('<body name="crate"', '<body name="shelf" pos="0 -0.5 0"><geom type="box" size="0.1 0.1 0.1"/>'
                       '</body>\n    <body name="crate"')
    model = mujoco.MjModel.from_xml_string(xml)
    draw = MujocoDrawing(model)
    assert [draw.body_paths[b].rsplit("/", 1)[1] for b in draw.moving] == ["arm", "crate"]
    assert draw.moving.tolist() == [1, 3]
    path = tmp_path / "apart.rrd"
    rec = open_stream("isf_robot", rrd_path=path)
    draw.log_static(rec)
    t = np.array([0.0, 0.1, 0.2])
    rng = np.random.default_rng(5)
    pos, quat = rng.normal(size=(3, model.nbody, 3)), rng.normal(size=(3, model.nbody, 4))
    draw.send_poses(rec, t, pos, quat)
    close_stream(rec)
    for b in draw.moving.tolist():
        got = read_columns(path, draw.body_paths[b])
        np.testing.assert_array_equal(got["Transform3D:translation"], pos[:, b].astype(np.float32))
        np.testing.assert_array_equal(got["Transform3D:quaternion"], quat[:, b][:, [1, 2, 3, 0]].astype(np.float32))
