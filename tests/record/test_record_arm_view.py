"""What the viewer shows of an arm run, read back from the .rrd: robot, tint, gaps, thresholds, camera."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import mujoco
import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader
from rerun.components import FillMode

from isf_robot.record import read_columns, read_rrd
from isf_robot.record.arm import ArmRecorder
from isf_robot.record.blueprints import camera_for, xi_range
from isf_robot.record.mjgeometry import TINT, MujocoDrawing

SHAPES = {"Capsules3D", "Ellipsoids3D", "Boxes3D", "Cylinders3D", "Mesh3D"}


def _components(path: Path) -> dict[tuple[str, bool], dict[str, list]]:
    """(entity, static) -> component column -> values (static rows)."""
    out: dict[tuple[str, bool], dict[str, list]] = defaultdict(dict)
    for chunk in RrdReader(path).stream(store=RrdReader(path).recordings()[0]):
        b = chunk.to_record_batch()
        for f in b.schema:
            if (f.metadata or {}).get(b"rerun:kind") == b"data":
                out[(chunk.entity_path, chunk.is_static)][f.name] = b.column(f.name).to_pylist()
    return out


@pytest.fixture(scope="module")
def panda_rrd(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`isf-robot run --scene panda_pole --filter isf --rrd x.rrd` (1 s; switching on and off, so no predictive trigger)."""
    from isf_robot.cli import main

    path = tmp_path_factory.mktemp("panda") / "x.rrd"
    assert main(["run", "--scene", "panda_pole", "--filter", "isf", "--duration", "1", "--horizon", "0",
                 "--rrd", str(path)]) == 0
    return path


def test_every_robot_and_obstacle_collision_geom_is_a_solid_shape(panda_rrd: Path) -> None:
    from isf_robot.arm import load_scene

    scene = load_scene("panda_pole")
    m = scene.model
    comps = _components(panda_rrd)
    ids = [int(g) for g in scene.robot_geom_ids] + [int(g) for g in scene.obstacle_geom_ids]
    assert len(scene.robot_geom_ids) == 14 and all(int(m.geom_group[g]) == 3 for g in scene.robot_geom_ids)
    for g in ids:
        body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
        geom = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g)
        entity = f"/world/bodies/{rr.escape_entity_path_part(body)}/{rr.escape_entity_path_part(geom)}"
        static = comps.get((entity, True), {})
        shapes = {k.split(":")[0] for k in static} & SHAPES
        assert shapes, (entity, sorted(static))
        (shape,) = shapes
        fill = static.get(f"{shape}:fill_mode")
        assert shape == "Mesh3D" or fill == [[int(FillMode.Solid.value)]], (entity, fill)
        assert "Transform3D:translation" in static
    # the base link (group 3, not a robot collision geom) is drawn too: it is on the robot's tree
    assert any(k[0].endswith("/link0_geom") and k[1] for k in comps)
    drawn = comps[("/run/arm", True)]["geom_ids_drawn"]
    assert set(ids) <= {int(v) for v in np.asarray(drawn).reshape(-1)}
    (log,) = read_rrd(panda_rrd)
    assert log.info["scene"] == "panda_pole" and log.info["strategy"] == "isf"


def test_robot_turns_orange_exactly_while_the_filter_is_on(arm_run) -> None:  # type: ignore[no-untyped-def]
    recs = arm_run.collector.steps
    draw = arm_run.recorder.drawing
    robot = draw.tinted
    assert robot
    m = draw.model
    g = robot[0]
    body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
    geom = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g)
    col = read_columns(arm_run.path, f"/world/bodies/{body}/{geom}", ["Capsules3D:colors"])
    on = np.array([r.on for r in recs])
    t = np.array([r.t for r in recs])
    switch = np.flatnonzero(np.concatenate(([True], on[1:] != on[:-1])))
    np.testing.assert_allclose(col["sim_time"], t[switch], atol=1e-9)
    rgba = [int(c) for c in np.asarray(col["Capsules3D:colors"])]
    own = [int(round(255 * float(c))) for c in m.geom_rgba[g]]
    for k, value in zip(switch, rgba):
        r, gg, b = (value >> 24) & 255, (value >> 16) & 255, (value >> 8) & 255
        d_tint = np.abs(np.array([r, gg, b]) - np.array(TINT)).sum()
        d_own = np.abs(np.array([r, gg, b]) - np.array(own[:3])).sum()
        assert (d_tint < d_own) == bool(on[k]), (k, (r, gg, b))


def test_pair_series_are_cleared_on_gaps(arm_run) -> None:  # type: ignore[no-untyped-def]
    recs = arm_run.collector.steps
    names = recs[0].names
    t = np.array([r.t for r in recs])
    tested = 0
    for name in names[:arm_run.recorder._n_collision]:
        member = np.array([name in r.closest[:3] for r in recs])
        if not member.any():
            continue
        path = f"/plots/barrier/pairs/{rr.escape_entity_path_part(name)}"
        gaps = np.flatnonzero(~member & np.concatenate(([False], member[:-1])))
        if gaps.size:
            cl = read_columns(arm_run.path, path, ["Clear:is_recursive"])
            np.testing.assert_allclose(cl["sim_time"], t[gaps], atol=1e-9)
            tested += 1
        vals = read_columns(arm_run.path, path)
        np.testing.assert_allclose(vals["sim_time"], t[member], atol=1e-9)
    assert tested >= 1


def test_xi_thresholds_and_zero_lines(arm_run) -> None:  # type: ignore[no-untyped-def]
    c = arm_run.result.params.c
    recs = arm_run.collector.steps
    for path, value in (("/plots/xi/c", c), ("/plots/xi/zero", 0.0), ("/plots/barrier/zero", 0.0)):
        col = read_columns(arm_run.path, path)
        assert np.all(col["Scalars:scalars"] == value), path
        assert math.isclose(col["sim_time"].min(), recs[0].t, abs_tol=1e-9)
        assert math.isclose(col["sim_time"].max(), recs[-1].t, abs_tol=1e-9)


def test_switch_events_share_one_level(arm_run) -> None:  # type: ignore[no-untyped-def]
    col = read_columns(arm_run.path, "/events")
    kinds = {e.kind for e in arm_run.collector.events}
    assert kinds == {"on", "off"}
    assert set(col["TextLog:level"]) == {"INFO"}


def test_end_effector_trail(arm_run) -> None:  # type: ignore[no-untyped-def]
    recs = arm_run.collector.steps
    trail = read_columns(arm_run.path, "/world/ee_trail")["LineStrips3D:strips"]
    assert len(trail) == len(recs)
    ee = np.array([r.ee_pos for r in recs])
    k = int(round(arm_run.recorder.trail_s / recs[0].dt)) + 1
    for i in (0, 1, len(recs) // 2, len(recs) - 1):
        strip = np.asarray(trail[i], dtype=float).reshape(-1, 3)
        assert 1 <= len(strip) <= ArmRecorder.TRAIL_POINTS
        np.testing.assert_allclose(strip[-1], ee[i], atol=1e-6)  # ends at the current point
        # every point is a past end-effector position within the trail's time
        past = ee[max(0, i - k + 1):i + 1]
        assert np.all(np.min(np.linalg.norm(strip[:, None] - past[None], axis=2), axis=1) < 1e-6)


def test_default_blueprint_frames_the_workspace(arm_run) -> None:  # type: ignore[no-untyped-def]
    reader = RrdReader(arm_run.path)
    positions = []
    for entry in reader.blueprints():
        for chunk in reader.stream(store=entry):
            b = chunk.to_record_batch()
            if "EyeControls3D:position" in b.schema.names:
                positions.append((b.column("EyeControls3D:position").to_pylist()[-1],
                                  b.column("EyeControls3D:look_target").to_pylist()[-1]))
    assert positions, "no camera in any blueprint"
    eye, target = (np.asarray(v, dtype=float).reshape(3) for v in positions[-1])
    draw: MujocoDrawing = arm_run.recorder.drawing
    centre, radius = draw.workspace()
    want_eye, want_target = camera_for(centre, radius)
    np.testing.assert_allclose(eye, want_eye, atol=1e-5)
    np.testing.assert_allclose(target, want_target, atol=1e-5)
    # the camera is a few workspace radii from the arm, whatever the size of the floor
    assert np.linalg.norm(eye - target) < 3 * radius


def test_xi_plot_opens_on_its_thresholds(arm_run) -> None:  # type: ignore[no-untyped-def]
    reader = RrdReader(arm_run.path)
    ranges = [b.column("ScalarAxis:range").to_pylist()[-1] for entry in reader.blueprints()
              for chunk in reader.stream(store=entry) if "ScalarAxis:range" in (b := chunk.to_record_batch()).schema.names]
    c = float(arm_run.collector.info["c"])
    assert ranges and np.allclose(np.asarray(ranges[-1], dtype=float).reshape(2), [-2 * c, 6 * c])
    assert xi_range(float("nan")) is None and xi_range(0.0) is None


def test_the_arm_recorder_takes_blocks_not_single_records(arm_run, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.record import ArmRecorder, open_stream
    from isf_robot.record.errors import RecordError

    rec = ArmRecorder(open_stream("isf_robot_arm", rrd_path=tmp_path / "x.rrd"))
    rec.on_start(arm_run.collector.info)
    with pytest.raises(RecordError, match="blocks of steps"):
        rec.on_step(arm_run.collector.steps[0])
    rec.on_abort(RuntimeError("test"))
