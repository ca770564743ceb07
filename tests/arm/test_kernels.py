"""The compiled barrier kernels (``isf_robot.arm.kernels``) against the numpy path, to 1e-12 relative.

Both paths compute the rows with the same formulas (:mod:`isf_robot.arm.narrow`): the kernel must
give the numpy path's pairs and row order exactly, and ``h``, ``dh/dq``, ``dh/dt``, witness points
and minima to ``RTOL`` (relative, with an absolute floor of ``RTOL`` times the array's scale), at
random states, along a run with the coherence bounds, for robot-robot pairs (a second Jacobian),
for mocap obstacles, for coinciding witness points (handed to the numpy path), and in the safety
monitor's sub-steps; whole runs with and without the kernels keep their counts and their floats
close. The formulas' own behaviour (finite differences, on both paths) is tested in
``test_barriers.py``. Skipped where numba is not installed.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, JointLimitBarriers, kernels, load_scene
from isf_robot.arm import narrow as narrow_module
from isf_robot.arm.monitor import SafetyMonitor
from isf_robot.arm.pairs import collision_pairs
from isf_robot.arm.params import resolve_params
from isf_robot.arm.sim import ArmSimulation
from isf_robot.core.exceptions import ShapeError

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")


RTOL = 1e-12
"""Compiled vs numpy: the same formulas, rounded differently only where the compiler orders a sum otherwise."""


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Equal shapes and values to ``RTOL`` (relative, floor ``RTOL`` times the larger magnitude in ``b``)."""
    if a is None or b is None:
        return a is None and b is None
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = max(1.0, float(np.max(np.abs(b[np.isfinite(b)]), initial=0.0)))
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=RTOL, atol=RTOL * scale, equal_nan=True))


def _assert_same_near(x, y) -> None:  # type: ignore[no-untyped-def]
    assert x.row_list == y.row_list and np.array_equal(x.rows, y.rows)
    for field in ("h", "grad", "dhdt", "witness"):
        assert _same(getattr(x, field), getattr(y, field)), field
    assert _same(np.array([x.h_min, x.dist_min]), np.array([y.h_min, y.dist_min]))


def _pair(scene, self_collision: bool = False) -> tuple[CollisionBarriers, CollisionBarriers]:  # type: ignore[no-untyped-def]
    fast = CollisionBarriers.from_scene(scene)
    if self_collision:
        bc = scene.config.barrier
        pairs = collision_pairs(scene.model, scene.robot_geom_ids, scene.obstacle_geom_ids, margin=bc.margin,
                                self_collision=True, self_margin=bc.self_margin)
        fast = CollisionBarriers(scene.model, pairs, scene.dof_adr, bc.cutoff)
    slow = CollisionBarriers(scene.model, fast.pairs, scene.dof_adr, fast.cutoff, jit=False)
    assert fast._kernel is not None and slow._kernel is None
    return fast, slow


@pytest.mark.parametrize("name,self_collision", [("panda_pole", False), ("panda_shelf", False),
                                                 ("panda_pole", True)])
def test_kernel_rows_equal_the_numpy_rows_at_random_states(random_states, rng, name, self_collision) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene(name)
    fast, slow = _pair(scene, self_collision)
    joints = JointLimitBarriers.from_scene(scene)
    seen = selfs = 0
    for d in random_states(scene, rng, 60):
        x, y = fast.near(d, witness=True), slow.near(d, witness=True)
        _assert_same_near(x, y)
        seen += len(x.row_list)
        selfs += sum(bool(fast.pairs.is_self[i]) for i in x.row_list)
        rx, ry = fast.rows(d, joints), slow.rows(d, joints)
        _assert_same_near(rx.near, ry.near)
        assert _same(rx.h, ry.h) and _same(rx.grad, ry.grad) and math.isclose(rx.joint_min, ry.joint_min,
                                                                                rel_tol=RTOL, abs_tol=RTOL)
        assert ry.grad_norm is None and rx.grad_norm is not None  # (the kernel's norms; numpy's made later)
        assert _same(rx.grad_norm, np.linalg.norm(ry.grad, axis=1))
        jh = joints.values(d)
        assert _same(rx.h[len(x.row_list):], jh) and math.isclose(rx.joint_min, min(jh.tolist()), abs_tol=RTOL)
        assert _same(rx.grad[len(x.row_list):], joints.grad)
    assert seen > 100  # the states do bring pairs within the cut-off
    assert selfs > 0 or not self_collision  # the second Jacobian (robot-robot pairs) is exercised


def test_kernel_rows_equal_along_a_path_with_the_coherence_bounds(rng) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_shelf")
    fast, slow = _pair(scene)
    cf, cs = fast.coherence(), slow.coherence()
    assert cf is not None and cs is not None
    m, d = scene.model, scene.make_data()
    q = scene.home.copy()
    skipped = 0
    for _ in range(300):
        q = np.clip(q + rng.normal(0.0, 0.03, q.size), scene.joint_range[:, 0], scene.joint_range[:, 1])
        d.qpos[scene.qpos_adr] = q
        mujoco.mj_forward(m, d)
        x, y = fast.near(d, coherence=cf), slow.near(d)
        _assert_same_near(x, y)
        skipped += int((cf.lower >= cf.cutoff).sum())
        _assert_same_near(slow.near(d, coherence=cs), y)
    assert skipped > 0  # the bounds did skip far pairs


def test_kernel_dhdt_of_mocap_obstacles_equals_numpy(random_states, rng) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_moving")
    fast, slow = _pair(scene)
    joints = JointLimitBarriers.from_scene(scene)
    assert fast._kdhdt == 1  # dh/dt in the kernel
    lin = rng.normal(0.0, 0.3, (scene.model.nmocap, 3))
    moving = 0
    for d in random_states(scene, rng, 60):
        x, y = fast.near(d, lin, witness=True), slow.near(d, lin, witness=True)
        _assert_same_near(x, y)
        moving += int(np.count_nonzero(x.dhdt))
        rx, ry = fast.rows(d, joints, lin), slow.rows(d, joints, lin)
        _assert_same_near(rx.near, ry.near)
        assert _same(rx.lf, ry.lf) and _same(rx.lf[: len(rx.near.row_list)], x.dhdt)
        assert not rx.lf[len(rx.near.row_list):].any()  # the joint rows' dh/dt is zero
    assert moving > 0
    with pytest.raises(ShapeError, match="mocap velocities"):
        fast.rows(scene.make_data(), joints, np.zeros((scene.model.nmocap + 1, 3)))


def test_coinciding_witness_points_go_to_the_numpy_path(random_states, rng, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_pole")
    fast, slow = _pair(scene)
    monkeypatch.setattr(narrow_module, "_EPS_DIST", 10.0)  # every near pair counts as touching
    joints = JointLimitBarriers.from_scene(scene)
    cf = fast.coherence()
    hit = 0
    for d in random_states(scene, rng, 20):
        y = slow.near(d, witness=True)
        _assert_same_near(fast.near(d, witness=True, coherence=cf), y)
        rx = fast.rows(d, joints)
        assert _same(rx.h, np.concatenate((y.h, joints.values(d))))
        hit += len(y.row_list)
    assert hit > 0


def test_monitor_substeps_equal_the_per_pair_calls(random_states, rng) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_shelf")
    fast, slow = _pair(scene)
    mf, ms = SafetyMonitor(fast), SafetyMonitor(slow)
    assert mf._kernel is not None and ms._kernel is None
    checked = 0
    for d in random_states(scene, rng, 40, spread=0.8):
        near = slow.near(d)
        for mon, arr in ((mf, near.rows), (ms, None)):
            mon.tick_min(min(near.h_min, slow.h_far_min), near.row_list, arr)
        for bound in (-math.inf, 0.05, near.h_min):
            assert _same(np.array(mf.substep(d, bound)), np.array(ms.substep(d, bound)))
            assert (mf.collisions, mf.steps) == (ms.collisions, ms.steps) and _same(np.array(mf.min_h),
                                                                                  np.array(ms.min_h))
        checked += bool(near.row_list)
    assert checked > 5


@pytest.mark.parametrize("strategy", ["cbf", "isf"])
def test_runs_agree_with_and_without_the_kernels(monkeypatch, strategy) -> None:  # type: ignore[no-untyped-def]
    """A 0.4 s closed-loop run: the same counts, and every step's command and rows to 1e-9 (the loop feeds back)."""
    scene = load_scene("panda_pole")
    params = resolve_params(scene)
    out = []
    for jit in ("1", "0"):
        monkeypatch.setenv("ISF_ROBOT_JIT", jit)
        cmds: list[np.ndarray] = []

        class Obs:
            def on_start(self, info): ...  # type: ignore[no-untyped-def]
            def on_step(self, rec): cmds.append(np.concatenate((np.asarray(rec.u), np.asarray(rec.h))))  # type: ignore[no-untyped-def]
            def on_event(self, ev): ...  # type: ignore[no-untyped-def]
            def on_finish(self, summary): ...  # type: ignore[no-untyped-def]
            def on_abort(self, exc): ...  # type: ignore[no-untyped-def]

        sim = ArmSimulation(scene, strategy, seed=0, params=params, observers=[Obs()])
        assert (sim.coll._kernel is not None) == (jit == "1")
        r = sim.run(0.4)
        quiet = ArmSimulation(scene, strategy, seed=0, params=params).run(0.4)  # no observer: no witness points
        out.append((cmds, (r.collisions, r.physics_steps, quiet.collisions, quiet.qp_solves, quiet.on_switches),
                    np.array([r.min_barrier, r.min_joint_barrier, quiet.min_barrier, quiet.duty_cycle,
                              quiet.min_joint_barrier])))
    (ca, na, fa), (cb, nb, fb) = out
    assert na == nb and len(ca) == len(cb) == 200
    assert all(a.shape == b.shape and np.allclose(a, b, rtol=1e-9, atol=1e-9) for a, b in zip(ca, cb))
    assert np.allclose(fa, fb, rtol=1e-9, atol=1e-12)
