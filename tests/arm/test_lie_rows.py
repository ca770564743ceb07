"""``CollisionBarriers.lie_rows``: a tick's filter rows in one pass, equal to ``lie(rows(...))``.

The simulation's barrier phase takes its rows from ``lie_rows`` when no observer records the step
(the compiled path then builds no ``NearPairs``); recorded runs and the predictive off trigger's
rollout take ``rows()`` and ``lie()``. These tests pin the two ways to each other and to the numpy
path: the Lie data (``h``, ``lf``, ``lg``, ``grad_norm`` to ``RTOL``, names exactly) and what the tick's
accounting reads (near rows, minima, the smallest joint value), at random states, along a path
with the coherence bounds, with mocap obstacles, with coinciding witness points, and with no pair
near; that the compiled path's outputs stay fresh over many calls; and that a run is the same
recorded (``rows()``) and unrecorded (``lie_rows``).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, JointLimitBarriers, kernels, load_scene
from isf_robot.arm import narrow as narrow_module
from isf_robot.arm.pairs import collision_pairs
from isf_robot.arm.params import resolve_params
from isf_robot.arm.sim import ArmSimulation
from isf_robot.core import Observer

needs_kernel = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")


def _bytes(a: np.ndarray) -> tuple[tuple[int, ...], str, bytes]:
    a = np.ascontiguousarray(a)
    return a.shape, a.dtype.str, a.tobytes()


RTOL = 1e-12
"""The compiled and numpy paths: the same formulas, equal to rounding (the kernel's norm is numba's)."""


def _close(a, b) -> bool:  # type: ignore[no-untyped-def]
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = max(1.0, float(np.max(np.abs(b[np.isfinite(b)]), initial=0.0)))
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=RTOL, atol=RTOL * scale))


def _assert_tick_equals_rows(t, r, lie) -> None:  # type: ignore[no-untyped-def]
    """``t`` (a TickRows) equal to ``rows()``'s ``r`` and its ``lie``: rows and names exactly, numbers to ``RTOL``."""
    for f in ("h", "lf", "lg", "grad_norm"):
        assert _close(getattr(t.lie, f), getattr(lie, f)), f
    assert t.lie.names == lie.names
    assert type(t.row_list) is tuple and t.row_list == tuple(r.near.row_list) and _bytes(t.rows) == _bytes(r.near.rows)
    assert _close([t.h_min, t.dist_min, t.joint_min], [r.near.h_min, r.near.dist_min, r.joint_min])


def _barriers(scene, jit: bool, cutoff: float | None = None, self_collision: bool = False) -> CollisionBarriers:  # type: ignore[no-untyped-def]
    bc = scene.config.barrier
    pairs = collision_pairs(scene.model, scene.robot_geom_ids, scene.obstacle_geom_ids, margin=bc.margin,
                            self_collision=self_collision or scene.config.robot.self_collision,
                            self_margin=bc.self_margin)
    return CollisionBarriers(scene.model, pairs, scene.dof_adr, cutoff or bc.cutoff, jit=jit)


@pytest.mark.parametrize("name,cutoff,self_collision", [("panda_pole", None, False), ("panda_shelf", None, False),
                                                        ("panda_pole", None, True), ("panda_pole", 0.002, False)])
def test_lie_rows_equal_lie_of_rows_at_random_states(random_states, rng, name, cutoff, self_collision) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene(name)
    joints = JointLimitBarriers.from_scene(scene)
    ways = [_barriers(scene, jit, cutoff, self_collision) for jit in (True, False)]
    near = empty = 0
    for d in random_states(scene, rng, 40):
        want = ways[1].rows(d, joints)
        want_lie = ways[1].lie(want, joints)
        for cb in ways:
            _assert_tick_equals_rows(cb.lie_rows(d, joints), want, want_lie)
            r = cb.rows(d, joints)
            _assert_tick_equals_rows(cb.lie_rows(d, joints), r, cb.lie(r, joints))
        near += len(want.near.row_list)
        empty += not want.near.row_list
    assert near > 0
    if cutoff is not None:
        assert empty > 0  # (states with no pair near: the kernel's j = 0 branch)
    if ways[0]._kernel is not None:  # the names by the kernel's key of the set; beyond 62 live pairs by the bytes
        keys = ways[0]._tick_names[1]
        assert keys and all(type(k) is (int if ways[0].broadphase.live.size <= 62 else bytes) for k in keys)


@needs_kernel
def test_names_kept_by_the_kernels_key_follow_the_pairs_and_the_joint_set(random_states, rng) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_pole")
    cb, slow = _barriers(scene, True), _barriers(scene, False)
    joints = JointLimitBarriers.from_scene(scene)
    rng_other = scene.joint_range.copy()
    rng_other[3:] = (-np.inf, np.inf)  # another joint set: other names, rows for three joints only
    other = JointLimitBarriers(scene.qpos_adr, rng_other, scene.config.barrier.joint_margin,
                               [f"other{i}" for i in range(len(scene.qpos_adr))])
    states = [d.qpos.copy() for d in random_states(scene, rng, 30)]
    m, d = scene.model, scene.make_data()
    for q in states:  # the joint set switching: right names and rows either way
        d.qpos[:] = q
        mujoco.mj_forward(m, d)
        for js in (joints, other, joints):
            t = cb.lie_rows(d, js)
            r = slow.rows(d, js)
            _assert_tick_equals_rows(t, r, slow.lie(r, js))
            assert t.lie.names[len(t.row_list):] == js.names
    kept: dict[tuple[int, ...], tuple] = {}
    for q in states + states:  # one joint set: a set of pairs seen before gives the kept names and tuple
        d.qpos[:] = q
        mujoco.mj_forward(m, d)
        t = cb.lie_rows(d, joints)
        first = kept.setdefault(t.row_list, (t.lie.names, t.row_list))
        assert t.lie.names is first[0] and t.row_list is first[1]
    assert len(kept) < len(states)  # (sets of pairs came back)


@needs_kernel
def test_lie_rows_along_a_path_with_the_coherence_bounds(rng) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_shelf")
    fast, slow = _barriers(scene, True), _barriers(scene, False)
    joints = JointLimitBarriers.from_scene(scene)
    coh = fast.coherence()
    assert coh is not None and fast._kernel is not None
    m, d = scene.model, scene.make_data()
    q = scene.home.copy()
    skipped = 0
    for _ in range(200):
        q = np.clip(q + rng.normal(0.0, 0.03, q.size), scene.joint_range[:, 0], scene.joint_range[:, 1])
        d.qpos[scene.qpos_adr] = q
        mujoco.mj_forward(m, d)
        t = fast.lie_rows(d, joints, coherence=coh)
        skipped += int((coh.lower >= coh.cutoff).sum())
        r = slow.rows(d, joints)
        _assert_tick_equals_rows(t, r, slow.lie(r, joints))
    assert skipped > 0  # the bounds did skip far pairs


@needs_kernel
@pytest.mark.parametrize("kernel_dhdt", [True, False])
def test_lie_rows_with_mocap_obstacles(random_states, rng, kernel_dhdt) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_moving")
    fast, slow = _barriers(scene, True), _barriers(scene, False)
    if not kernel_dhdt:
        fast._kdhdt = 0  # dh/dt by numpy after the kernel (the path taken with an angular velocity)
    joints = JointLimitBarriers.from_scene(scene)
    lin = rng.normal(0.0, 0.3, (scene.model.nmocap, 3))
    moving = 0
    for d in random_states(scene, rng, 40):
        t = fast.lie_rows(d, joints, lin)
        r = slow.rows(d, joints, lin)
        _assert_tick_equals_rows(t, r, slow.lie(r, joints))
        moving += int(np.count_nonzero(t.lie.lf))
    assert moving > 0


@needs_kernel
def test_lie_rows_with_coinciding_witness_points(random_states, rng, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_pole")
    fast, slow = _barriers(scene, True), _barriers(scene, False)
    monkeypatch.setattr(narrow_module, "_EPS_DIST", 10.0)  # every near pair counts as touching: the numpy path
    joints = JointLimitBarriers.from_scene(scene)
    coh = fast.coherence()
    hit = 0
    for d in random_states(scene, rng, 15):
        t = fast.lie_rows(d, joints, coherence=coh)
        r = slow.rows(d, joints)
        _assert_tick_equals_rows(t, r, slow.lie(r, joints))
        hit += len(t.row_list)
    assert hit > 0


@needs_kernel
def test_compiled_outputs_stay_fresh_over_many_calls(random_states, rng) -> None:  # type: ignore[no-untyped-def]
    """Results kept from 150 calls (three allocations of output blocks, each at most 256 kB) are never written again."""
    scene = load_scene("panda_pole")
    cb = _barriers(scene, True)
    joints = JointLimitBarriers.from_scene(scene)
    kept = []
    for i, d in enumerate(random_states(scene, rng, 150)):
        t = cb.lie_rows(d, joints) if i % 2 else cb.rows(d, joints)
        arrays = [t.lie.h, t.lie.lf, t.lie.lg, t.lie.grad_norm, t.rows] if i % 2 else \
                 [t.h, t.lf, t.grad, t.near.rows, t.near.h, t.near.grad, t.near.dhdt]
        kept.append((arrays, [a.copy() for a in arrays]))
    assert len(cb._kblocks) == 1  # (one layout: rows() and lie_rows() share its blocks)
    allocations = {id(arrays[0].base) for arrays, _ in kept}
    assert len(allocations) >= 3 and all(arrays[0].base.nbytes <= 256 * 1024 for arrays, _ in kept)
    for arrays, copies in kept:
        for a, c in zip(arrays, copies):
            assert _bytes(a) == _bytes(c)


class _Nothing(Observer):
    def on_start(self, info) -> None: ...  # type: ignore[no-untyped-def]
    def on_step(self, rec) -> None: ...  # type: ignore[no-untyped-def]
    def on_event(self, ev) -> None: ...  # type: ignore[no-untyped-def]
    def on_finish(self, summary) -> None: ...  # type: ignore[no-untyped-def]
    def on_abort(self, exc) -> None: ...  # type: ignore[no-untyped-def]


@pytest.mark.parametrize("strategy", ["cbf", "isf"])
def test_a_run_is_the_same_recorded_and_unrecorded(strategy) -> None:  # type: ignore[no-untyped-def]
    """Unrecorded, the loop's rows come from lie_rows; recorded, from rows() and lie(): the same run."""
    scene = load_scene("panda_pole")
    params = resolve_params(scene)
    out = []
    for observers in ([], [_Nothing()]):
        d = ArmSimulation(scene, strategy, seed=0, params=params, observers=observers).run(0.6).as_dict()
        for k in ("wall_s", "timings"):
            d.pop(k, None)
        out.append({k: v for k, v in d.items() if "time_median" not in k})
    assert out[0] == out[1]
