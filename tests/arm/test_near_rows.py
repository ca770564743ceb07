"""The rows a filter needs, evaluated alone: ``CollisionBarriers.near``, joint-limit values, ``tick_min``.

The arm loop evaluates only the collision pairs within the cut-off (``near``) and the joint-limit
values; the full batches are built from them only when an observer records. These tests pin the
pieces to independent per-pair computations and to the full batches, bit for bit.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, JointLimitBarriers, load_scene
from isf_robot.arm.monitor import SafetyMonitor


def _by_hand(cb: CollisionBarriers, m: mujoco.MjModel, d: mujoco.MjData) -> dict[int, tuple[float, float, np.ndarray]]:
    """Every pair within the cut-off: distance, h and dh/dq from its own mj_geomDistance and mj_jac calls."""
    out = {}
    for i, (g1, g2) in enumerate(zip(cb.pairs.geom1.tolist(), cb.pairs.geom2.tolist())):
        ft = np.zeros(6)
        dist = mujoco.mj_geomDistance(m, d, int(g1), int(g2), cb.cutoff, ft)
        if dist >= cb.cutoff:
            continue
        jac1 = np.zeros((3, m.nv))
        mujoco.mj_jac(m, d, jac1, None, ft[:3], int(m.body_weldid[m.geom_bodyid[g1]]))
        n = (ft[:3] - ft[3:]) * (1.0 / dist)
        out[i] = (dist, dist - float(cb.pairs.margin[i]), (n @ jac1)[cb.dof_adr])
    return out


@pytest.mark.parametrize("cutoff", [None, 5.0])  # 5 m: every candidate is within the cut-off
def test_near_rows_equal_a_per_pair_evaluation_and_the_batch(rng, cutoff) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_pole")
    m, cb = scene.model, CollisionBarriers.from_scene(scene)
    if cutoff is not None:
        cb = CollisionBarriers(m, cb.pairs, scene.dof_adr, cutoff)
    d = scene.make_data()
    lo, hi = scene.joint_range[:, 0], scene.joint_range[:, 1]
    partial = full = 0  # states where some candidates are beyond the cut-off / all within it
    for trial in range(40):
        step = rng.uniform(lo - scene.home, hi - scene.home) * 0.6 if trial else 0.0
        d.qpos[scene.qpos_adr] = scene.home + step
        mujoco.mj_forward(m, d)
        near = cb.near(d)
        want = _by_hand(cb, m, d)
        assert near.row_list == sorted(want) and near.rows.tolist() == near.row_list
        if not want:
            assert near.h_min == math.inf and near.dist_min == math.inf and near.grad.shape == (0, 7)
            continue
        assert near.witness is None
        cand = cb.broadphase.candidates(d)
        partial += len(cand) > len(want)
        full += len(cand) == len(want)
        np.testing.assert_array_equal(near.h, [want[i][1] for i in near.row_list])
        np.testing.assert_allclose(near.grad, np.array([want[i][2] for i in near.row_list]), rtol=0, atol=1e-14)
        assert near.h_min == min(near.h.tolist())
        assert near.dist_min == min(want[i][0] for i in near.row_list)
        assert not near.dhdt.any()
        # the full batch is the near rows plus saturated far rows, the same numbers
        batch = cb.evaluate(d)
        act = np.flatnonzero(batch.active).tolist()
        assert act == near.row_list
        np.testing.assert_array_equal(batch.h[act], near.h)
        np.testing.assert_array_equal(batch.grad[act], near.grad)
        far = np.setdiff1d(np.arange(cb.pairs.k), act)
        np.testing.assert_array_equal(batch.h[far], cb.cutoff - cb.pairs.margin[far])
        assert cb.h_far_min == float(np.min(cb.cutoff - cb.pairs.margin))
        with_w = cb.near(d, witness=True)
        np.testing.assert_array_equal(with_w.witness, batch.witness[act])
    assert (partial > 0) if cutoff is None else (full > 0 and partial == 0)  # both ways of packing the rows


def test_tick_min_accounts_like_tick() -> None:
    scene = load_scene("panda_pole")
    m, cb = scene.model, CollisionBarriers.from_scene(scene)
    d = scene.make_data()
    mujoco.mj_forward(m, d)
    a, b = SafetyMonitor(cb), SafetyMonitor(cb)
    for shift in (0.0, 0.4, -0.3):
        d.qpos[scene.qpos_adr] = scene.home + shift
        mujoco.mj_forward(m, d)
        batch, near = cb.evaluate(d), cb.near(d)
        da = a.tick(batch.h, batch.active.nonzero()[0])
        db = b.tick_min(min(near.h_min, cb.h_far_min), near.row_list)
        assert abs(da - db) <= 1e-15 * max(1.0, abs(da)) or da == db == math.inf
        assert (a.min_h, a.collisions, a.steps, a.rows) == (b.min_h, b.collisions, b.steps, b.rows)
    assert a.steps == 3 and a.min_h < cb.h_far_min


def test_joint_values_and_batch_match_evaluate(rng) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_pole")
    jb = JointLimitBarriers.from_scene(scene)
    d = scene.make_data()
    for _ in range(5):
        d.qpos[scene.qpos_adr] = rng.uniform(scene.joint_range[:, 0], scene.joint_range[:, 1])
        full = jb.evaluate(d)
        h = jb.values(d)
        np.testing.assert_array_equal(h, full.h)
        np.testing.assert_array_equal(jb.batch(h).grad, full.grad)
        assert jb.grad is full.grad and not jb.grad.flags.writeable
        # every row is +-e_i: the filter's |dh/dq| of a joint row is exactly 1
        np.testing.assert_array_equal(np.abs(jb.grad).sum(axis=1), 1.0)


@pytest.mark.parametrize("name", ["panda_pole", "panda_shelf"])
def test_joint_coherence_skips_far_pairs_and_changes_nothing(name) -> None:  # type: ignore[no-untyped-def]
    """Along a smooth joint path the rows with the run's distance bounds equal those without."""
    scene = load_scene(name)
    m, cb = scene.model, CollisionBarriers.from_scene(scene)
    coh = cb.coherence()
    assert coh is not None
    sizes: list[int] = []
    plain = coh.candidates
    coh.candidates = lambda data: sizes.append(len(r := plain(data))) or r  # type: ignore[method-assign]
    d = scene.make_data()
    lo, hi = scene.joint_range[:, 0], scene.joint_range[:, 1]
    amp = 0.45 * np.minimum(scene.home - lo, hi - scene.home)
    narrow_plain = n_near = 0
    for k in range(300):
        d.qpos[scene.qpos_adr] = scene.home + amp * np.sin(0.0005 * k * np.arange(1, amp.size + 1))
        mujoco.mj_forward(m, d)
        a = cb.near(d, witness=True)
        b = cb.near(d, witness=True, coherence=coh)
        narrow_plain += len(cb.broadphase.candidates(d))
        n_near += len(a.row_list)
        assert a.row_list == b.row_list
        for x, y in zip(a[2:6], b[2:6]):
            np.testing.assert_array_equal(x, y)
        assert (a.h_min, a.dist_min) == (b.h_min, b.dist_min)
        true = [mujoco.mj_geomDistance(m, d, int(cb.pairs.geom1[i]), int(cb.pairs.geom2[i]), 10.0, None)
                for i in cb.broadphase.live.tolist()]
        assert np.all(coh.lower <= np.array(true))  # every bound is below the pair's distance
    # most candidates beyond the cut-off skipped the narrow phase (after the first state's full pass)
    assert sum(sizes[1:]) - n_near < 0.5 * (narrow_plain - n_near)


def test_joint_coherence_refuses_motion_the_angles_miss() -> None:
    scene = load_scene("panda_moving")  # mocap obstacles: their motion is no joint's
    assert CollisionBarriers.from_scene(scene).coherence() is None
