"""ArmDynamics: the terms from MuJoCo's factor of M against a dense numpy inverse of mj_fullM."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest

from isf_robot.arm import load_scene
from isf_robot.arm.dynamics import ArmDynamics
from isf_robot.arm.torque_calibration import torque_plant


def _dense(model: mujoco.MjModel, data: mujoco.MjData, dof: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(M_aa, [M^-1]_aa, a0, hold)`` by numpy: the inverse of the full mass matrix."""
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    inv = np.linalg.inv(full)
    free = data.qfrc_passive - data.qfrc_bias
    return full[np.ix_(dof, dof)], inv[np.ix_(dof, dof)], (inv @ free)[dof], -free[dof]


def _random_state(scene, data, rng) -> None:  # type: ignore[no-untyped-def]
    lo, hi = scene.joint_range[:, 0], scene.joint_range[:, 1]
    data.qpos[scene.qpos_adr] = rng.uniform(lo, hi)
    data.qvel[scene.dof_adr] = rng.uniform(-2.0, 2.0, len(scene.dof_adr))


@pytest.mark.parametrize("name", ["panda_pole", "ur5e_pole", "panda_pair"])
def test_terms_match_the_numpy_inverse_on_random_states(name: str) -> None:
    """Every term, on 200 random states after mj_step1 of the torque plant, equals the dense computation."""
    scene = load_scene(name)
    plant = torque_plant(scene.model)
    data = mujoco.MjData(plant)
    rng = np.random.default_rng(5)
    all_dofs = np.asarray(scene.dof_adr, dtype=np.int64)
    # every dof, and a non-contiguous subset ([M^-1]_aa is then not the inverse of M_aa: the test tells them apart)
    for dof in (all_dofs, all_dofs[[1, 3, 4]]):
        dyn = ArmDynamics(scene.model, dof)
        for _ in range(200):
            _random_state(scene, data, rng)
            mujoco.mj_step1(plant, data)
            got = dyn.terms(data)
            want = _dense(scene.model, data, dof)
            for a, b in zip((got.mass, got.minv, got.a0, got.hold), want, strict=True):
                np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * max(1.0, float(np.max(np.abs(b)))))
            if dof.size < all_dofs.size:
                assert not np.allclose(got.minv, np.linalg.inv(got.mass), rtol=1e-3)


def test_terms_of_another_models_state_are_the_filter_models() -> None:
    """``own_data``: a state of a heavier plant gets the filter model's terms (its own factor, not the plant's)."""
    scene = load_scene("panda_pole")
    plant = torque_plant(scene.model)
    plant.body_mass[scene.model.site_bodyid[scene.ee_site_id]] += 2.0
    data = mujoco.MjData(plant)
    dyn = ArmDynamics(scene.model, scene.dof_adr, own_data=True)
    ref = mujoco.MjData(scene.model)
    rng = np.random.default_rng(6)
    dof = np.asarray(scene.dof_adr, dtype=np.int64)
    for _ in range(50):
        _random_state(scene, data, rng)
        mujoco.mj_step1(plant, data)
        ref.qpos[:], ref.qvel[:] = data.qpos, data.qvel
        mujoco.mj_forward(scene.model, ref)
        got = dyn.terms(data)
        for a, b in zip((got.mass, got.minv, got.a0, got.hold), _dense(scene.model, ref, dof), strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * max(1.0, float(np.max(np.abs(b)))))
        assert not np.allclose(got.minv, _dense(plant, data, dof)[1], rtol=1e-6)  # (the plant's would differ)


def test_a_copied_dynamics_computes_on_its_own_data() -> None:
    """A deep copy binds its compiled call again: it must not compute on the original's model and data (addresses)."""
    scene = load_scene("panda_pole")
    data = mujoco.MjData(scene.model)
    rng = np.random.default_rng(3)
    _random_state(scene, data, rng)
    mujoco.mj_step1(scene.model, data)
    dyn = ArmDynamics(scene.model, scene.dof_adr, own_data=True)
    dyn.terms(data)  # (bound to its own data)
    twin = copy.deepcopy(dyn)
    _random_state(scene, data, rng)
    mujoco.mj_step1(scene.model, data)
    dyn._own.qpos[:] = 0.0  # (the original's data elsewhere: a copy reading it would see this state)
    fresh = ArmDynamics(scene.model, scene.dof_adr, own_data=True).terms(data)
    got = twin.terms(data)
    for a, b in zip((got.minv, got.a0), (fresh.minv, fresh.a0), strict=True):
        np.testing.assert_array_equal(a, b)


def test_terms_do_not_share_buffers_between_states() -> None:
    """The terms of one state are not changed by the next call (the solve's buffers are reused)."""
    scene = load_scene("panda_pole")
    data = scene.make_data(0.0)
    dyn = ArmDynamics(scene.model, scene.dof_adr)
    mujoco.mj_forward(scene.model, data)
    first = dyn.terms(data)
    kept = copy.deepcopy(first)
    data.qpos[scene.qpos_adr] += 0.3
    data.qvel[scene.dof_adr] = 1.0
    mujoco.mj_forward(scene.model, data)
    second = dyn.terms(data)
    assert not np.allclose(second.minv, kept.minv)
    for a, b in zip((first.mass, first.minv, first.a0, first.hold), (kept.mass, kept.minv, kept.a0, kept.hold),
                    strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", ["panda_pole", "ur5e_pole"])
def test_compiled_terms_equal_the_bindings_calls(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled terms (``_dynamics_jit``: mj_fullM, the free force, mj_solveM in one call) equal the bindings'.

    The same C calls on the same inputs: equal to the bit (tolerance 0), every dof and a subset, a second data too.
    """
    from isf_robot.arm import kernels

    if kernels.dynamics_kernel() is None:
        pytest.skip("compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")
    scene = load_scene(name)
    plant = torque_plant(scene.model)
    rng = np.random.default_rng(7)
    all_dofs = np.asarray(scene.dof_adr, dtype=np.int64)
    for dof in (all_dofs, all_dofs[[0, 2, 5]]):
        fast = ArmDynamics(scene.model, dof)
        with monkeypatch.context() as m:
            m.setattr(kernels, "dynamics_kernel", lambda: None)
            slow = ArmDynamics(scene.model, dof)
        assert fast._kernel is not None and slow._kernel is None
        for data in (mujoco.MjData(plant), mujoco.MjData(plant)):  # (a second data: the kernel rebinds)
            for _ in range(30):
                _random_state(scene, data, rng)
                mujoco.mj_step1(plant, data)
                got, want = fast.terms(data), slow.terms(data)
                for a, b in zip((got.mass, got.minv, got.a0, got.hold), (want.mass, want.minv, want.a0, want.hold),
                                strict=True):
                    np.testing.assert_array_equal(a, b)


def test_compiled_model_error_agrees_with_the_plain_formula() -> None:
    """``dynamics_law.model_error`` compiled (the torque episode's) and as written: 1e-12 relative, and the norm."""
    from isf_robot.arm import kernels
    from isf_robot.arm.dynamics_law import model_error
    from isf_robot.core.jit import compiled

    rng = np.random.default_rng(8)
    fast = compiled(model_error)
    if not kernels.available() or fast is model_error:
        pytest.skip("compiled kernels off (ISF_ROBOT_JIT=0) or numba not importable")
    dof = np.array([0, 1, 2, 4, 5, 6, 7], dtype=np.int64)
    for _ in range(100):
        qvel, v0, pred = rng.normal(size=9), rng.normal(size=7), rng.normal(scale=50.0, size=7)
        want = float(np.linalg.norm((qvel[dof] - v0) / 0.002 - pred))
        assert model_error(qvel, dof, v0, pred, 0.002) == pytest.approx(want, rel=1e-12)
        assert fast(qvel, dof, v0, pred, 0.002) == pytest.approx(model_error(qvel, dof, v0, pred, 0.002), rel=1e-12)
