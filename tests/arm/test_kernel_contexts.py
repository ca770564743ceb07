"""The collision kernel's cached contexts (``NarrowPhase._kernel_context``): a lookup, never a stale table.

The predictive off trigger's rollout evaluates its own scratch ``MjData`` between two steps of the
episode's, so the kernel keeps a few contexts (the tables' addresses for one ``MjData``, coherence
bounds and joint set). These tests alternate states and objects and compare every row with a fresh
numpy-path evaluation: a context of the wrong ``MjData``, or of coherence bounds a reset replaced,
gives other rows. Skipped where numba is not installed (the numpy path is then the only one).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, JointLimitBarriers, kernels, load_scene
from isf_robot.arm import narrow as narrow_module

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")


RTOL = 1e-12
"""The kernel and the numpy path: the same formulas; a stale table gives other pairs or values far beyond this."""


def _same_rows(x, y) -> None:  # type: ignore[no-untyped-def]
    """Rows of the kernel (x) and of the numpy path (y): the same pairs, the same values to ``RTOL``."""
    assert x.near.row_list == y.near.row_list
    for field in ("h", "grad", "lf"):
        a, b = getattr(x, field), getattr(y, field)
        scale = max(1.0, float(np.max(np.abs(b[np.isfinite(b)]), initial=0.0)))
        assert a.shape == b.shape and np.allclose(a, b, rtol=RTOL, atol=RTOL * scale), field
    assert np.isclose(x.joint_min, y.joint_min, rtol=RTOL, atol=RTOL)


def _builds(monkeypatch, cb: CollisionBarriers) -> list[int]:  # type: ignore[no-untyped-def]
    count: list[int] = []
    build = cb._build_context
    monkeypatch.setattr(cb, "_build_context", lambda *a: count.append(1) or build(*a))
    return count


def _state(scene, d, q) -> mujoco.MjData:  # type: ignore[no-untyped-def]
    d.qpos[scene.qpos_adr] = q
    mujoco.mj_forward(scene.model, d)
    return d


def test_alternating_data_reuse_their_contexts_and_give_their_own_rows(rng, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The episode's data (with coherence bounds) and a rollout's scratch data (without), in turns."""
    scene = load_scene("panda_pole")
    fast = CollisionBarriers.from_scene(scene)
    slow = CollisionBarriers(scene.model, fast.pairs, scene.dof_adr, fast.cutoff, jit=False)
    joints = JointLimitBarriers.from_scene(scene)
    coh = fast.coherence()
    assert fast._kernel is not None and coh is not None
    builds = _builds(monkeypatch, fast)
    episode, scratch = scene.make_data(), scene.make_data()
    q = scene.home.copy()
    near = 0
    for _ in range(40):
        q = np.clip(q + rng.normal(0.0, 0.03, q.size), scene.joint_range[:, 0], scene.joint_range[:, 1])
        d = _state(scene, episode, q)
        _same_rows(fast.rows(d, joints, coherence=coh), slow.rows(d, joints))
        for _ in range(3):  # the rollout's points: other states on the scratch data
            p = _state(scene, scratch, q + rng.normal(0.0, 0.3, q.size))
            x = fast.rows(p, joints)
            _same_rows(x, slow.rows(p, joints))
            near += len(x.near.row_list)
    assert len(builds) == 2  # one context per (data, coherence), each built once
    assert near > 0  # the rows compared include collision pairs


def test_a_coherence_reset_rebuilds_the_context(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """After ``coherence.reset`` (a jump other than by the joints: here the pole comes back from far
    away), the kernel must use the new bounds; the old ones would skip the pole as far away."""
    scene = load_scene("panda_pole")  # (a fresh model: its pole is moved below)
    fast = CollisionBarriers.from_scene(scene)
    slow = CollisionBarriers(scene.model, fast.pairs, scene.dof_adr, fast.cutoff, jit=False)
    joints = JointLimitBarriers.from_scene(scene)
    coh = fast.coherence()
    builds = _builds(monkeypatch, fast)
    pole = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, "pole")
    pole_rows = {i for i, n in enumerate(fast.pairs.names) if n.endswith("|pole")}
    at = scene.model.geom_pos[pole].copy()
    scene.model.geom_pos[pole] = at + np.array([3.0, 0.0, 0.0])  # far away
    d = _state(scene, scene.make_data(), scene.home)
    for _ in range(3):
        x = fast.rows(d, joints, coherence=coh)
        _same_rows(x, slow.rows(d, joints))
    assert not pole_rows & set(x.near.row_list)
    assert (coh.lower[np.isin(fast.broadphase.live, list(pole_rows))] > coh.cutoff).all()  # the bounds prove it
    coh.reset()
    scene.model.geom_pos[pole] = at  # back by the arm, the joints unmoved
    mujoco.mj_forward(scene.model, d)
    x, y = fast.rows(d, joints, coherence=coh), slow.rows(d, joints)
    assert pole_rows & set(y.near.row_list)  # the pole is within the cut-off again
    _same_rows(x, y)
    assert coh.qstate[0] == 1 and np.isfinite(coh.lower).all()  # the kernel wrote into the new bounds
    assert len(builds) == 2


def test_more_objects_than_contexts_each_get_their_own_rows(rng) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_shelf")
    fast = CollisionBarriers.from_scene(scene)
    slow = CollisionBarriers(scene.model, fast.pairs, scene.dof_adr, fast.cutoff, jit=False)
    joints = JointLimitBarriers.from_scene(scene)
    datas = [scene.make_data() for _ in range(narrow_module.KERNEL_CONTEXTS + 2)]
    lo, hi = scene.joint_range[:, 0], scene.joint_range[:, 1]
    for _ in range(3):
        for d in datas:
            _state(scene, d, scene.home + rng.uniform(lo - scene.home, hi - scene.home) * 0.6)
        for d in datas + datas[::-1]:
            _same_rows(fast.rows(d, joints), slow.rows(d, joints))
    assert len(fast._kctxs) == narrow_module.KERNEL_CONTEXTS  # bounded
