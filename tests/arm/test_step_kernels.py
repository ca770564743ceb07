"""The compiled tracker and reaching controller (``isf_robot.arm.kernels.step_kernels``) against numpy, to 1e-12.

Both paths call the same formulas (:mod:`isf_robot.arm.tracking_law`, :mod:`isf_robot.arm.reaching_law`):
the compiled ``VelocityTracker.apply``/``command`` must write the numpy path's torques, references and
tracking errors to ``RTOL`` relative (torque limits reached too), and the compiled ``ReachingController``
its commands and exactly its goal bookkeeping (goal switches, the speed cap, the rate limit, a rollout's
snapshot/restore, another MjData). The laws' own behaviour: ``test_control_laws.py``. Skipped where
numba is not installed.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, kernels, load_scene
from isf_robot.arm.lowlevel import VelocityTracker
from isf_robot.arm.monitor import SafetyMonitor
from isf_robot.arm.nominal import ReachingController

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")


RTOL = 1e-12
"""Compiled vs numpy: the same formulas (the Cholesky solve, sums of a few products) rounded alike to a few ulp."""


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal shapes and values to ``RTOL`` (relative, floor ``RTOL`` times the larger magnitude in ``b``)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = max(1.0, float(np.max(np.abs(b[np.isfinite(b)]), initial=0.0)))
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=RTOL, atol=RTOL * scale))


def test_tracker_kernel_equals_numpy(rng) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_pole")
    model = scene.model
    datas = [scene.make_data(), scene.make_data()]
    fast, slow = VelocityTracker(scene), VelocityTracker(scene, jit=False)
    assert fast._kernels is not None and slow._kernels is None
    for tr, d in ((fast, datas[0]), (slow, datas[1])):
        tr.reset(d)
    errs = []
    for i in range(400):
        u = rng.normal(scale=2.0 if i % 60 < 6 else 0.3, size=scene.n_joints)
        for d in datas:
            mujoco.mj_step1(model, d)
        if i % 3 == 0:  # the sub-step path: apply alone
            for tr, d in ((fast, datas[0]), (slow, datas[1])):
                tr.apply(d)
        else:  # the control tick: tracking error, command and apply in one
            period = None if i % 7 == 0 else 0.001
            e = [tr.command(d, u, period) for tr, d in ((fast, datas[0]), (slow, datas[1]))]
            assert _same(np.array(e[0]), np.array(e[1]))
            errs.append(e[0])
        assert _same(datas[0].ctrl, datas[1].ctrl)
        for a, b in ((fast.q_ref, slow.q_ref), (fast.u, slow.u), (fast.a_ff, slow.a_ff)):
            assert _same(a, b)
        for d in datas:
            mujoco.mj_step2(model, d)
    assert np.allclose(datas[0].qpos, datas[1].qpos, rtol=1e-9, atol=1e-9)  # (400 steps of feedback)
    lim = model.actuator_ctrlrange[: scene.n_joints, 1]
    assert np.any(np.abs(datas[0].ctrl) >= lim - 1e-12) or max(errs) > 1.0  # driven hard: limits or large errors


def test_tracker_kernel_follows_a_new_mjdata_and_changed_gains() -> None:
    scene = load_scene("panda_pole")
    fast, slow = VelocityTracker(scene), VelocityTracker(scene, jit=False)
    for tr in (fast, slow):
        tr.kp *= 0.5  # in place: the kernel reads the same buffer
        tr.kd = 30.0  # set: copied into it
        tr.max_ref_error = 0.01
    assert fast.kd.tolist() == [30.0] * scene.n_joints
    out = []
    for tr in (fast, slow):
        first, second = scene.make_data(), scene.make_data()
        second.qpos[scene.qpos_adr] += 0.05
        mujoco.mj_forward(scene.model, second)
        for d in (first, second):
            tr.reset(first)
            mujoco.mj_step1(scene.model, d)
            tr.command(d, np.full(scene.n_joints, 0.2), 0.001)
        out.append((first.ctrl.copy(), second.ctrl.copy()))
    assert _same(out[0][0], out[1][0]) and _same(out[0][1], out[1][1])
    assert not _same(out[0][0], out[0][1])  # each data got its own torques


def test_substep_check_and_apply_in_one_call_equal_the_separate_calls(rng) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_shelf")
    model = scene.model
    fast_c = CollisionBarriers.from_scene(scene)
    slow_c = CollisionBarriers(model, fast_c.pairs, scene.dof_adr, fast_c.cutoff, jit=False)
    runs = [(fast_c, VelocityTracker(scene)), (slow_c, VelocityTracker(scene, jit=False))]
    out = []
    for coll, tr in runs:
        mon, d = SafetyMonitor(coll), scene.make_data()
        d.qpos[scene.qpos_adr] += np.linspace(-0.3, 0.5, scene.n_joints)  # toward the shelf
        mujoco.mj_forward(model, d)
        tr.reset(d)
        seq, fused = [], 0
        for i in range(300):
            mujoco.mj_step1(model, d)
            near = coll.near(d)
            mon.tick_min(min(near.h_min, coll.h_far_min), near.row_list, near.rows)
            tr.command(d, np.sin(0.02 * i + np.arange(scene.n_joints)) * 0.8, 0.002)
            mujoco.mj_step2(model, d)
            mujoco.mj_step1(model, d)
            fused += bool(near.row_list) and tr.compiled_apply(d) is not None
            seq.append(np.concatenate(([mon.substep(d, near.h_min if i % 2 else -np.inf, tr)], d.ctrl)))
            mujoco.mj_step2(model, d)
        out.append((np.array(seq), mon.min_h, mon.collisions, mon.steps, d.qpos.copy(), fused))
    (sa, ha, ca, na, qa, fa), (sb, hb, cb, nb, qb, fb) = out
    assert (ca, na) == (cb, nb) and np.allclose(sa, sb, rtol=1e-9, atol=1e-9) and np.allclose(qa, qb, atol=1e-9)
    assert np.isclose(ha, hb, rtol=1e-9, atol=1e-12)
    assert fa > 50 and fb == 0  # the fused call did run (and not on the numpy side)


def _controllers(scene, **kw):  # type: ignore[no-untyped-def]
    fast, slow = ReachingController(scene, **kw), ReachingController(scene, jit=False, **kw)
    assert fast._reach is not None and slow._reach is None
    return fast, slow


@pytest.mark.parametrize("kw", [{}, {"max_joint_acc": float("inf"), "max_joint_speed": 0.05}, {"max_joint_speed": 0.2, "max_ee_speed": 0.05}])
def test_reaching_kernel_equals_numpy_along_random_motion(rng, kw) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_shelf")
    goals = scene.goal_positions + rng.normal(0.0, 0.02, scene.goal_positions.shape)
    fast, slow = _controllers(scene, goals=goals, tolerance=0.2, dwell=np.full(len(goals), 0.01), timeout=0.05, **kw)
    d = scene.make_data()
    q = scene.home.copy()
    seen_goals, capped, limited = set(), 0, 0
    for k in range(600):
        t = 0.002 * k + (0.0 if k % 97 else 0.002)  # sometimes the same tick twice (dt = 0)
        q = np.clip(q + rng.normal(0.0, 0.01, q.size), scene.joint_range[:, 0], scene.joint_range[:, 1])
        d.qpos[scene.qpos_adr] = q
        mujoco.mj_forward(scene.model, d)
        prev = fast._rate.prev.copy()
        a, b = fast(t, d), slow(t, d)
        assert _same(a, b) and a is not fast._rate.prev
        gf, gs = dict(vars(fast.goals)), dict(vars(slow.goals))
        assert _same(gf.pop("dwell"), gs.pop("dwell")) and fast._rate.t_prev == slow._rate.t_prev
        assert gf.keys() == gs.keys() and all(
            _same(np.asarray(gf[key], dtype=float), np.asarray(gs[key], dtype=float)) if isinstance(gf[key], float)
            else gf[key] == gs[key] for key in gf)
        assert _same(fast._rate.prev, slow._rate.prev)
        seen_goals.add(fast.goal_index)
        capped += bool(np.max(np.abs(a)) >= fast.max_joint_speed * (1 - 1e-12))
        limited += bool(np.max(np.abs(a - prev)) >= fast._rate.a_max * 0.002 * (1 - 1e-12))
        if k % 50 == 25:  # a rollout: calls at predicted states, then back to the snapshot
            snaps = fast.snapshot(), slow.snapshot()
            for _ in range(3):
                assert _same(fast(t + 0.01, d), slow(t + 0.01, d))
            fast.restore(snaps[0])
            slow.restore(snaps[1])
    assert len(seen_goals) > 1 and fast.goals_reached + fast.goals_missed > 1  # goals switched
    assert capped > 0 or limited > 0
