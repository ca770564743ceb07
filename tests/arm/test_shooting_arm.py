"""Maneuvers by shooting on the arm: the rollout's first command, the wiring, a run, the command line.

``NominalRollout(t, data, first=u)`` holds ``u`` over the first Euler step and lets the nominal take
over: its first point must be the state ``q + dt u`` (the scene's own rows there, computed here), the
compiled and numpy paths must agree, and ``first = u_nom`` must give the rollout without it.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from isf_robot.arm import ArmSimulation, load_scene
from isf_robot.arm.params import resolve_params
from isf_robot.cli import main as cli_main
from isf_robot.core import ConfigError

RTOL = 1e-12


def _flat(points):  # type: ignore[no-untyped-def]
    return [(s, lie.names, np.concatenate((lie.h, lie.lf, lie.lg.ravel(), lie.grad_norm, u))) for s, lie, u in points]


def _close(a, b) -> bool:  # type: ignore[no-untyped-def]
    return len(a) == len(b) and all(pa[:2] == pb[:2] and np.allclose(pa[2], pb[2], rtol=RTOL, atol=RTOL * max(
        1.0, float(np.max(np.abs(pb[2]))))) for pa, pb in zip(a, b))


@pytest.fixture(scope="module")
def shooting_sim():  # type: ignore[no-untyped-def]
    scene = load_scene("panda_pole")
    params = resolve_params(scene, d_bar=0.05, shoot=0.5, calibrate=False)
    return scene, ArmSimulation(scene, "isf", seed=2, params=params)


def test_the_wiring_holds_a_shooting_rollout_over_its_horizon(shooting_sim) -> None:  # type: ignore[no-untyped-def]
    _, sim = shooting_sim
    shooter = sim.strategy.shooter
    assert shooter is not None
    roll = shooter.rollout
    assert roll is not sim.strategy.predictor.rollout
    assert roll.n * roll.dt == pytest.approx(0.5)
    assert sim.params.shoot == 0.5


def test_first_command_moves_the_first_point_and_the_paths_agree(shooting_sim) -> None:  # type: ignore[no-untyped-def]
    scene, sim = shooting_sim
    roll = sim.strategy.shooter.rollout
    nom = sim.nominal
    data = mujoco.MjData(scene.model)
    rng = np.random.default_rng(3)
    whole, step = roll._whole, roll._step
    for k in range(4):
        t = 0.3 + 0.1 * k
        q0 = sim.setup.q0 + rng.normal(scale=0.3, size=scene.n_joints)
        data.qpos[scene.qpos_adr] = q0
        mujoco.mj_forward(scene.model, data)
        nom.reset()
        nom(t - 0.01, data)  # (a previous command for the rate limit)
        first = rng.normal(scale=0.5, size=scene.n_joints)
        roll._whole, roll._step = whole, step
        fast = _flat(roll(t, data, first=first))
        roll._whole = None
        euler = _flat(roll(t, data, first=first))
        roll._step = None
        slow = _flat(roll(t, data, first=first))
        assert _close(fast, slow) and _close(euler, slow)
        # the first point is the state q0 + dt * first: its rows as the simulation builds them there
        probe = mujoco.MjData(scene.model)
        probe.qpos[:] = data.qpos
        probe.qpos[scene.qpos_adr] = q0 + roll.dt * first
        mujoco.mj_kinematics(scene.model, probe)
        mujoco.mj_comPos(scene.model, probe)
        lie = sim.coll.lie_rows(probe, sim.joints, None)[0]
        assert slow[0][1] == lie.names
        np.testing.assert_allclose(slow[0][2][: lie.h.size], lie.h, rtol=1e-12, atol=1e-12)
        # first = the nominal's own command: the rollout without it
        u_now = nom.snapshot()
        u = np.array(nom(t, data), dtype=float)
        nom.restore(u_now)
        roll._whole, roll._step = whole, step
        assert _close(_flat(roll(t, data, first=u)), _flat(roll(t, data)))
    roll._whole, roll._step = whole, step
    with pytest.raises(ConfigError, match="first command"):
        roll(0.3, data, first=np.zeros(scene.n_joints + 1))


def test_a_shooting_run_is_safe_and_chooses() -> None:
    scene = load_scene("panda_pole")
    params = resolve_params(scene, d_bar=0.05, shoot=0.5, calibrate=False)
    sim = ArmSimulation(scene, "isf", seed=1, params=params)
    res = sim.run(4.0)
    assert res.collisions == 0 and res.min_barrier > 0
    # the level in use moves at a bounded rate: the arm tracks the filter's command within d_bar
    # (level steps of up to 10 b in one control step took the tracking error q99 to 5x d_bar)
    assert res.tracking_error_q99 <= 0.05
    shooter = sim.strategy.shooter
    assert shooter.choices > 0 and len(shooter.last_tau) == 3
    assert res.params.shoot == 0.5 and res.as_dict()["shoot"] == 0.5
    # the run reports the choices: how many, and how many raised the push above b
    d = res.as_dict()
    assert (d["shoot_choices"], d["shoot_raised"]) == (shooter.choices, shooter.raised)
    assert 0 <= d["shoot_raised"] <= d["shoot_choices"]
    plain = ArmSimulation(scene, "isf", seed=1, params=resolve_params(scene, d_bar=0.05, calibrate=False)).run(0.2)
    assert "shoot_choices" not in plain.as_dict()


def test_the_command_line_takes_shoot_and_refuses_a_bad_one(capsys) -> None:  # type: ignore[no-untyped-def]
    assert cli_main(["run", "--scene", "panda_pole", "--filter", "isf", "--shoot", "-1", "--duration", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "shoot" in err and ">= 0" in err and len(err.strip().splitlines()) == 1
