"""What is read back from a saved .rrd equals what the run computed."""

from __future__ import annotations

import math

import numpy as np

from isf_robot.core import compute_metrics
from isf_robot.record import read_columns, read_rrd, replay_metrics


def test_arm_replay_columns_equal_records(arm_run) -> None:  # type: ignore[no-untyped-def]
    (log,) = read_rrd(arm_run.path)
    recs = arm_run.collector.steps
    assert log.kind == "arm" and log.summary is not None
    assert log.info["strategy"] == "isf" and log.info["scene"] == "planar_moving"
    s = log.steps
    assert s["t"].shape == (len(recs),)
    np.testing.assert_array_equal(s["t"], [r.t for r in recs])  # bit-exact float64
    np.testing.assert_array_equal(s["dt"], [r.dt for r in recs])
    np.testing.assert_array_equal(s["on"], [r.on for r in recs])
    np.testing.assert_array_equal(s["qp_solved"], [r.qp_solved for r in recs])
    rate = [float((r.u - r.u_nom) @ (r.u - r.u_nom)) for r in recs]
    # (the recorder sums each row in the metrics' order, BLAS's dot in its own: equal to rounding)
    np.testing.assert_allclose(s["intervention_rate"], rate, rtol=1e-12, atol=0.0)
    assert s["on"].any() and not s["on"].all()


def test_arm_barrier_values_read_back(arm_run) -> None:  # type: ignore[no-untyped-def]
    recs = arm_run.collector.steps
    (log,) = read_rrd(arm_run.path)
    # true-geometry minimum: the run's figure is the minimum of the logged per-step values
    assert math.isclose(float(np.min(np.concatenate([log.steps["min_barrier"], log.terminal]))),
                        arm_run.result.min_barrier, rel_tol=1e-12, abs_tol=1e-15)
    hf = read_columns(arm_run.path, "/plots/barrier/filter_min")
    np.testing.assert_array_equal(hf["Scalars:scalars"], [r.h_min for r in recs])
    xi = read_columns(arm_run.path, "/plots/xi/min")
    np.testing.assert_array_equal(xi["Scalars:scalars"], [r.xi_min for r in recs])
    mode = read_columns(arm_run.path, "/plots/mode")
    np.testing.assert_array_equal(mode["Scalars:scalars"], [1.0 if r.on else 0.0 for r in recs])
    u = read_columns(arm_run.path, "/plots/joints/command/filtered")["Scalars:scalars"]
    np.testing.assert_array_equal(u, np.array([r.u for r in recs]))
    corr = read_columns(arm_run.path, "/plots/joints/correction")["Scalars:scalars"]
    np.testing.assert_array_equal(corr, np.array([r.u - r.u_nom for r in recs]))
    norm = read_columns(arm_run.path, "/plots/command/correction_norm")["Scalars:scalars"]
    np.testing.assert_allclose(norm, [np.linalg.norm(r.u - r.u_nom) for r in recs], rtol=1e-12, atol=1e-15)
    # per-pair series: each logged value is that pair's h at a step where it was among the closest
    names = recs[0].names
    for name in recs[0].closest:
        from rerun import escape_entity_path_part

        col = read_columns(arm_run.path, f"/plots/barrier/pairs/{escape_entity_path_part(name)}")
        want = [(r.t, r.h[names.index(name)]) for r in recs if name in r.closest[:3]]
        np.testing.assert_allclose(col["sim_time"], [w[0] for w in want], atol=1e-9)
        np.testing.assert_array_equal(col["Scalars:scalars"], [w[1] for w in want])


def test_arm_events_read_back(arm_run) -> None:  # type: ignore[no-untyped-def]
    events = arm_run.collector.events
    (log,) = read_rrd(arm_run.path)
    assert len(events) >= 4
    ev = log.events
    np.testing.assert_array_equal(ev["t"], [e.t for e in events])
    assert list(ev["kind"]) == [e.kind for e in events]
    np.testing.assert_array_equal(ev["index"], [e.index for e in events])
    np.testing.assert_array_equal(ev["xi"], [e.xi_min for e in events])
    dur = [math.nan if e.duration_s is None else e.duration_s for e in events]
    np.testing.assert_array_equal(ev["duration_s"], dur)
    text = read_columns(arm_run.path, "/events")["TextLog:text"]
    assert len(text) == len(events) and "filter on" in text[0]


def test_arm_geometry_and_poses(arm_run) -> None:  # type: ignore[no-untyped-def]
    recs = arm_run.collector.steps
    assert arm_run.recorder.drawing.geoms_drawn >= 6
    tf = read_columns(arm_run.path, "/world/bodies/ball")
    np.testing.assert_allclose(tf["Transform3D:translation"], [r.mocap_pos[0] for r in recs], atol=1e-6)
    ee = read_columns(arm_run.path, "/world/ee")["Points3D:positions"]
    np.testing.assert_allclose(ee, [r.ee_pos for r in recs], atol=1e-6)  # float32 points
    wit = read_columns(arm_run.path, "/world/witness")["LineStrips3D:strips"]
    assert len(wit) == len(recs)
    # only the pairs among the three closest get a segment
    k = next(i for i, r in enumerate(recs) if len(r.witness))
    want = [w for w, n in zip(recs[k].witness, recs[k].witness_names) if n in recs[k].closest[:3]]
    np.testing.assert_allclose(np.asarray(wit[k], dtype=float).reshape(-1, 2, 3), want, atol=1e-6)


def test_arm_poses_and_barriers_are_the_tick_state(arm_run) -> None:  # type: ignore[no-untyped-def]
    """A row's body poses and barrier values are those of its own ``q`` (the state at the control tick)."""
    import mujoco

    from isf_robot.arm import load_scene
    from isf_robot.arm.sim import ArmSimulation

    recs = arm_run.collector.steps
    draw = arm_run.recorder.drawing
    sim = ArmSimulation(load_scene("planar_moving"), "nominal", params=arm_run.result.params)
    model, qadr = draw.model, sim.scene.qpos_adr
    data = mujoco.MjData(model)
    links = [b for b in draw.moving.tolist() if model.body_mocapid[b] < 0]
    assert links
    cols = {b: read_columns(arm_run.path, draw.body_paths[b])["Transform3D:translation"] for b in links}
    for i in range(0, len(recs), 97):
        data.qpos[qadr] = recs[i].q
        data.mocap_pos[:], data.mocap_quat[:] = recs[i].mocap_pos, recs[i].mocap_quat
        mujoco.mj_kinematics(model, data)
        for b in links:
            np.testing.assert_allclose(cols[b][i], data.xpos[b], atol=1e-6)  # float32 translations
        joints = sim.joints.evaluate(data)
        np.testing.assert_array_equal(recs[i].h[len(recs[i].h) - joints.k:], joints.h)


def test_arm_replay_metrics_equal_run(arm_run) -> None:  # type: ignore[no-untyped-def]
    (log,) = read_rrd(arm_run.path)
    m = replay_metrics(log)
    r = arm_run.result.as_dict()
    for key in ("duty_cycle", "on_switches", "off_switches", "control_steps", "qp_solves"):
        assert m[key] == r[key], key
    for key in ("mean_off_s", "min_off_s", "mean_on_s", "intervention", "min_barrier", "duration_s"):
        assert math.isclose(m[key], r[key], rel_tol=1e-9), key
    acc = compute_metrics(log.steps["t"], log.steps["dt"], log.steps["on"], log.steps["intervention_rate"],
                          log.steps["qp_solved"])
    assert acc.duty_cycle == r["duty_cycle"]


def test_satellite_round_trip(sat_run) -> None:  # type: ignore[no-untyped-def]
    (log,) = read_rrd(sat_run.path)
    res = sat_run.result
    assert log.kind == "satellite"
    m = replay_metrics(log)
    assert m["triggers"] == res.triggers > 3
    assert m["kinds"] == res.kinds
    assert math.isclose(m["total_dv"], res.total_dv, rel_tol=1e-12)  # (the replay adds |dv| by numpy, the run by sums)
    assert math.isclose(m["min_inter_event_h"], res.min_inter_event_h, rel_tol=1e-12)
    assert math.isclose(m["mean_inter_event_h"], res.mean_inter_event_h, rel_tol=1e-12)
    samples = sat_run.collector.steps
    np.testing.assert_array_equal(log.steps["t"], [s.t for s in samples])
    np.testing.assert_array_equal(log.steps["min_barrier"], [s.h for s in samples])
    rr_ = read_columns(sat_run.path, "/plots/radius")["Scalars:scalars"]
    R = log.info["R_m"]
    np.testing.assert_array_equal(rr_, [s.r / R for s in samples])
    xi = read_columns(sat_run.path, "/plots/xi/xi")["Scalars:scalars"]
    np.testing.assert_array_equal(xi, [s.xi for s in samples])
    imp = log.impulses
    np.testing.assert_array_equal(imp["t"], [e.t for e in res.events])
    np.testing.assert_array_equal(np.column_stack([imp["dv_x"], imp["dv_y"], imp["dv_z"]]),
                                  np.array([e.v for e in res.events]))
    arrows = read_columns(sat_run.path, "/world/impulses")
    assert len(arrows["sim_time"]) == res.triggers
    assert "h" in str(arrows["Arrows3D:labels"][0])
    np.testing.assert_allclose(np.asarray(arrows["Arrows3D:origins"], dtype=float).reshape(-1, 3),
                               [e.x_before[:3] for e in res.events], rtol=1e-6)  # float32 points
    scale = sat_run.recorder.arrow_scale
    np.testing.assert_allclose(np.asarray(arrows["Arrows3D:vectors"], dtype=float).reshape(-1, 3),
                               [np.asarray(e.v) * scale for e in res.events], rtol=1e-6, atol=1e-9 * scale)


def test_satellite_replay_gives_the_run_figures_only(sat_run) -> None:  # type: ignore[no-untyped-def]
    (log,) = read_rrd(sat_run.path)
    res = sat_run.result
    m = replay_metrics(log)
    # exact, from the run (the 10-minute samples miss the extremes between them)
    assert m["min_barrier"] == res.min_h and m["min_barrier_source"] == "run"
    assert m["r_min_over_R"] == res.r_min_over_R and m["r_max_over_R"] == res.r_max_over_R
    assert m["min_barrier"] <= float(np.min(log.steps["min_barrier"]))
    assert math.isclose(m["duration_s"], 3600.0 * res.simulated_h, rel_tol=1e-12)
    # nothing of a sampled-data filter: no duty cycle, switches or QP solves
    for key in ("duty_cycle", "on_switches", "qp_solves", "intervention", "mean_off_s"):
        assert key not in m, key


def test_replay_min_barrier_is_the_runs_with_pairs_of_different_margins(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Each step's logged true-geometry minimum uses each pair's own margin: replay gives the run's figure exactly.

    At the torque level the arm's own link pairs (margin 0.01 m) join the obstacle pairs (0.02 m) on ur5e_pole; the
    closest pair of this run is one of the arm's own, so a minimum taken with one margin for every pair would be off
    by 0.01 m (it was: replay said 0.0062 m where the run said 0.0162 m).
    """
    from isf_robot.arm import load_scene
    from isf_robot.arm.torque_sim import TorqueSimulation, resolve_torque_params
    from isf_robot.record import ArmRecorder, arm_blueprint, open_stream

    scene = load_scene("ur5e_pole")
    path = tmp_path / "torque.rrd"
    rec = ArmRecorder(open_stream("isf_robot_arm", rrd_path=path, blueprint=arm_blueprint()), capacity=256)
    sim = TorqueSimulation(scene, "isf", seed=0, params=resolve_torque_params(scene, d_bar=0.32), observers=[rec])
    margins = np.asarray(sim.start_info(2.0)["pair_margins"])
    assert margins.min() < margins.max()  # (the case under test: pairs of different margins)
    res = sim.run(2.0)
    (log,) = read_rrd(path)
    logged = float(np.min(np.concatenate([log.steps["min_barrier"], log.terminal])))
    assert math.isclose(logged, res.min_barrier, rel_tol=1e-12, abs_tol=1e-15)
    assert math.isclose(replay_metrics(log)["min_barrier"], res.min_barrier, rel_tol=1e-12, abs_tol=1e-15)
