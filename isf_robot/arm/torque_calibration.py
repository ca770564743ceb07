"""Calibration of the torque level's disturbance bound ``d_bar`` [rad/s^2].

The torque-level filter plans with ``q_ddot = a0 + Minv tau + d`` (:mod:`isf_robot.arm.dynamics`),
the torque held over each control period T. What it does not model is measured, as the
velocity level measures its tracking error (:mod:`isf_robot.arm.calibration`):

1. Copy the simulated arm's model (``plant``: the scene's own, or one with what the filter does not
   know, e.g. a payload), switch off its actuators (the torque goes in ``qfrc_applied``) and its
   contacts with the obstacles.
2. Run the scene's reaching task with the torque nominal (:class:`~isf_robot.arm.torque_nominal.TorqueNominal`)
   at the control rate; every ``switch_period`` seconds the torque gets a new random offset
   (uniform per joint in ``+-excitation * tau_max``, zero half of the time), so the calibration
   also sees the torque steps a filter makes.
3. At every control tick record ``|(q_dot(t_k+1) - q_dot(t_k)) / T - (a0 + Minv tau)(t_k)|``
   (Euclidean norm over the arm joints, the norm the robust term ``|J| d_bar`` bounds), with ``a0``
   and ``Minv`` of the filter's model (the scene's): the model error, the hold over the period,
   friction losses, joint-limit forces.
4. ``d_bar = factor * quantile(samples, q)``.

Results are cached for the life of the process (per scene files, plant and parameters).
"""

from __future__ import annotations

import copy
from typing import Any

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError

from .calibration import Calibration, _key, free_scene
from .dynamics import ArmDynamics, torque_limits
from .nominal import ReachingController
from .scene import Scene
from .torque_nominal import TorqueNominal

__all__ = ["calibrate_torque_d_bar", "torque_plant"]

_CACHE: dict[tuple[Any, ...], Calibration] = {}


def torque_plant(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of ``model`` with its actuators switched off: the arm torques go in ``qfrc_applied``."""
    plant = copy.deepcopy(model)
    plant.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
    return plant


def calibrate_torque_d_bar(
    scene: Scene,
    plant: mujoco.MjModel | None = None,
    *,
    duration: float = 4.0,
    quantile: float = 0.99,
    factor: float = 1.5,
    excitation: float = 0.05,
    switch_period: float = 0.2,
    seed: int = 0,
    kd: float = 40.0,
) -> Calibration:
    """Measure the torque level's ``d_bar`` [rad/s^2] (see the module docstring).

    Args:
        scene: The scene (the filter's model; not modified).
        plant: The simulated arm's model (default: the scene's); not modified.
        duration: Simulated time [s], > 0.
        quantile: Quantile level in (0, 1].
        factor: Safety factor >= 1.
        excitation: Random torque offsets as a fraction of the torque limits, >= 0.
        switch_period: Time between offset changes [s], > 0.
        seed: Seed of the offsets.
        kd: The torque nominal's gain [1/s].

    Returns:
        A :class:`~isf_robot.arm.calibration.Calibration` whose errors are in [rad/s^2]
        (``saturation``: fraction of ticks each joint's torque was at its limit).

    """
    if not duration > 0 or not switch_period > 0 or not excitation >= 0:
        raise ConfigError(f"calibration duration and switch_period must be > 0 [s] and excitation >= 0, got "
                          f"{duration}, {switch_period}, {excitation}")
    if not (0.0 < quantile <= 1.0 and factor >= 1.0):
        raise ConfigError(f"calibration quantile must be in (0, 1] and factor >= 1, got {quantile}, {factor}")
    key = _key(scene, (id(plant) if plant is not None else None, duration, quantile, factor, excitation,
                       switch_period, seed, kd))
    if key in _CACHE:
        return _CACHE[key]
    free = free_scene(scene, torque_plant(scene.model if plant is None else plant))
    model = free.model
    data = free.make_data(0.0)
    dyn = ArmDynamics(scene.model, scene.dof_adr, own_data=plant is not None)
    T = float(scene.config.control.period)
    S = max(1, int(round(T / float(model.opt.timestep))))
    tau_max = torque_limits(scene)
    nominal = TorqueNominal(ReachingController(free), scene.dof_adr, tau_max, T, kd)
    rng = np.random.default_rng(seed)
    n_ctrl = int(round(duration / T))
    per_switch = max(1, int(round(switch_period / T)))
    dofs = np.asarray(scene.dof_adr)
    offset = np.zeros(free.n_joints)
    errors, sat = np.empty(n_ctrl), np.zeros(free.n_joints)
    moving = len(scene.config.moving) > 0
    for k in range(n_ctrl):
        if moving:
            scene.set_moving_obstacles(data, k * T)
        mujoco.mj_step1(model, data)
        if k % per_switch == 0:
            offset = (rng.uniform(-1.0, 1.0, free.n_joints) * excitation * tau_max
                      if rng.random() < 0.5 else np.zeros(free.n_joints))
        terms = dyn.terms(data)
        tau = np.clip(nominal(k * T, data, terms) + offset, -tau_max, tau_max)
        sat += np.abs(tau) >= tau_max * (1 - 1e-9)
        v0, pred = data.qvel[dofs].copy(), terms.acceleration(tau)
        data.qfrc_applied[dofs] = tau
        mujoco.mj_step2(model, data)
        for _ in range(S - 1):
            mujoco.mj_step(model, data)
        errors[k] = float(np.linalg.norm((data.qvel[dofs] - v0) / T - pred))
    qv = float(np.quantile(errors, quantile))
    cal = Calibration(d_bar=factor * qv, quantile=quantile, quantile_value=qv, max_error=float(errors.max()),
                      median_error=float(np.median(errors)), factor=factor, duration_s=n_ctrl * T, samples=n_ctrl,
                      saturation=tuple(float(x) for x in sat / n_ctrl), joint_names=scene.joint_names,
                      friction_fed_forward=False)
    _CACHE[key] = cal
    return cal
