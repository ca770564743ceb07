"""The compiled ``psi`` rows (``_second_order_jit``: phi_rate, psi_tick) against the numpy path of SecondOrderRows.

Both paths compute the rows with the same formulas (:mod:`isf_robot.arm.psi_law`) on the same shifted state;
the tick's ``psi`` rows and their Lie data must agree to ``RTOL`` (relative, with a floor of ``RTOL`` times each
array's scale) at random states with near pairs, with a moving obstacle, and when the kernels hand coinciding
witness points to the numpy path; a pair that is not near at the shifted state is refused on both. Skipped where
numba is not installed.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from isf_robot.arm import CollisionBarriers, JointLimitBarriers, kernels, load_scene
from isf_robot.arm.dynamics import ArmDynamics
from isf_robot.arm.second_order import SecondOrderRows
from isf_robot.core import ConfigError

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")
k2 = pytest.importorskip("isf_robot.arm._second_order_jit")  # (the kernel's return codes; needs numba)

RTOL = 1e-12
"""Compiled vs numpy: the same formulas (equal to the bit on these states; a compiler may order a sum otherwise)."""


def _rows(scene, monkeypatch, compiled: bool) -> SecondOrderRows:  # type: ignore[no-untyped-def]
    clock = None
    if scene.config.moving:
        def clock(data, t):  # type: ignore[no-untyped-def]
            scene.set_moving_obstacles(data, t)
            return scene.mocap_velocities(t)[0]
    coll, joints = CollisionBarriers.from_scene(scene), JointLimitBarriers.from_scene(scene)
    with monkeypatch.context() as m:
        if not compiled:
            m.setattr(kernels, "second_order_kernels", lambda: None)
        rows = SecondOrderRows(coll, joints, scene.qpos_adr, 5.0, clock, approaching=True)
    assert (rows._kernel is not None) == compiled
    return rows


def _states(scene, rng, count: int):  # type: ignore[no-untyped-def]
    """Random states near home with near pairs: ``(data, lin)``."""
    d = mujoco.MjData(scene.model)
    coll = CollisionBarriers.from_scene(scene)
    made = 0
    while made < count:
        d.qpos[scene.qpos_adr] = scene.home + rng.uniform(-0.6, 0.6, scene.n_joints)
        d.qvel[scene.dof_adr] = rng.uniform(-1.0, 1.0, scene.n_joints)
        d.time = float(rng.uniform(0.0, 6.0))
        lin = None
        if scene.config.moving:
            scene.set_moving_obstacles(d, d.time)
            lin = scene.mocap_velocities(d.time)[0]
        mujoco.mj_forward(scene.model, d)
        if coll.near(d, lin).rows.size:
            made += 1
            yield d, lin


def _close(a: np.ndarray, b: np.ndarray) -> bool:
    scale = max(1.0, float(np.max(np.abs(b), initial=0.0)))
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=RTOL, atol=RTOL * scale))


def _assert_same_tick(fast, slow, d, lin, terms) -> None:  # type: ignore[no-untyped-def]
    pf, tf = fast.tick(d, d.time, terms, lin)
    ps, ts = slow.tick(d, d.time, terms, lin)
    assert np.array_equal(tf[1], ts[1]) and pf.names == ps.names
    for field in ("h", "lf", "lg", "grad_norm"):
        assert _close(getattr(pf, field), getattr(ps, field)), field


@pytest.mark.parametrize("name", ["panda_pole", "panda_moving"])
def test_compiled_phi_rate_is_the_numpy_paths(name: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene(name)
    fast, slow = _rows(scene, monkeypatch, True), _rows(scene, monkeypatch, False)
    dyn = ArmDynamics(scene.model, scene.dof_adr)
    for d, lin in _states(scene, np.random.default_rng(3), 40):
        _assert_same_tick(fast, slow, d, lin, dyn.terms(d))


def test_coinciding_witness_points_go_to_the_numpy_path(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Kernels that report coinciding witness points: the numpy path on the shifted state the kernel left."""
    scene = load_scene("panda_pole")
    fast, slow = _rows(scene, monkeypatch, True), _rows(scene, monkeypatch, False)
    real_rate, real_tick, calls = fast._kernel, fast._tick_kernel, []

    def touching_rate(*args):  # type: ignore[no-untyped-def]
        calls.append(real_rate(*args))
        return k2.TOUCHING

    def touching_tick(*args):  # type: ignore[no-untyped-def]
        calls.append(real_tick(*args))
        return k2.TOUCHING

    fast._kernel, fast._tick_kernel = touching_rate, touching_tick
    dyn = ArmDynamics(scene.model, scene.dof_adr)
    for d, lin in _states(scene, np.random.default_rng(4), 5):
        _assert_same_tick(fast, slow, d, lin, dyn.terms(d))
    assert len(calls) == 10 and set(calls) == {k2.DONE}


def test_a_pair_beyond_the_probe_is_refused_on_both_paths(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    scene = load_scene("panda_pole")
    d, _ = next(_states(scene, np.random.default_rng(5), 1))
    for compiled in (True, False):
        rows = _rows(scene, monkeypatch, compiled)
        far = np.setdiff1d(np.arange(rows.coll.pairs.k), rows._probe.near(d).rows)[:1]
        assert far.size
        with pytest.raises(ConfigError, match="left the probe's reach"):
            rows.phi_rate(d, d.time, far, d.qvel[scene.dof_adr], np.zeros(1))


@pytest.mark.parametrize("name", ["panda_pole", "panda_moving"])
def test_given_pairs_get_the_probes_near_rows(name: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The compiled difference measures the tick's pairs alone (``near_packed`` with them given): each gets, to the
    bit, the row the probe's collision kernel gives it among all its near pairs; a pair beyond the cut-off is dropped."""
    from isf_robot.arm import _kernels_jit as kj
    from isf_robot.core.jit import compiled

    scene = load_scene(name)
    rows = _rows(scene, monkeypatch, True)
    probe, s, a = rows._probe, rows._scratch, rows._kargs
    fn = compiled(kj.near_packed)
    m, n = probe.broadphase.live.size, scene.n_joints  # (the probe's block: no joint rows)
    checked = 0
    for d, lin in _states(scene, np.random.default_rng(6), 20):
        s.qpos[:], s.mocap_pos[:], s.mocap_quat[:] = d.qpos, d.mocap_pos, d.mocap_quat
        mujoco.mj_kinematics(scene.model, s)
        mujoco.mj_comPos(scene.model, s)
        near = probe.near(s, lin)  # (the compiled kernel: every pair within the probe's cut-off)
        want_g, want_dhdt = near.grad.copy(), near.dhdt.copy()
        given = rows._live_of[near.rows]
        k = given.size
        far = np.setdiff1d(np.arange(m), given)[:1]  # (a live pair beyond the probe's cut-off)
        lv, dl = probe.packed_velocities(lin)
        for extra in (np.zeros(0, dtype=np.int64), far):
            blk, out = np.full_like(a[3], np.nan), np.empty_like(a[4])
            got = fn(a[0], a[1], a[2], blk, out, False, a[5], a[5], 0.0, a[6], 0, lv, dl,
                     np.concatenate((given, extra)))
            assert got[0] == k and not got[4]
            assert np.array_equal(out[:k], near.rows)
            assert np.array_equal(blk[m: m + m * n].reshape(m, n)[:k], want_g)
            assert np.array_equal(blk[2 * m + m * n: 2 * m + m * n + k], want_dhdt)
        checked += k
    assert checked > 20


def test_repeated_pairs_beyond_the_live_count_go_to_the_numpy_path(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """More rows than the probe has live pairs (repeats): the kernel leaves them to the numpy path (it wrote one
    scratch entry per row, past its arrays), and both paths give each repeat its pair's value."""
    scene = load_scene("panda_pole")
    fast, slow = _rows(scene, monkeypatch, True), _rows(scene, monkeypatch, False)
    d, _ = next(_states(scene, np.random.default_rng(6), 1))
    near = fast._probe.near(d).rows
    live = int(np.count_nonzero(fast._live_of >= 0))
    rows = np.resize(near, live + 5).astype(np.int64)
    q_dot, phi = d.qvel[scene.dof_adr], np.zeros(rows.size)
    got, want = fast.phi_rate(d, d.time, rows, q_dot, phi), slow.phi_rate(d, d.time, rows, q_dot, phi)
    assert _close(got, want)
    single = slow.phi_rate(d, d.time, near.astype(np.int64), q_dot, np.zeros(near.size))
    assert _close(got[: near.size], single)
