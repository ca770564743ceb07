"""Calibration of the tracking-error bound ``d_bar`` of the reduced-order model.

The filter plans with ``q_dot = u + d``; ``d = q_dot - u`` is what the low-level controller
(:func:`~isf_robot.arm.actuation.make_actuation`: computed torque for motors, integrated targets
for position servos, ``ctrl = u`` for velocity servos) fails to track. Its bound is measured, not
guessed (the paper takes the bound ``|d| <= d_bar`` as known, Section II):

1. Copy the model and switch off contacts with the obstacles (``contype = conaffinity = 0``
   on the obstacle geoms), so that the arm moves freely through the scene.
2. Run the scene's reaching task with the tracker at the physics rate (the command held over
   each control period, as in a run). Every
   ``switch_period`` seconds the command gets a new random offset (uniform per joint in
   ``+-excitation * max_joint_speed``, zero half of the time), so the calibration also sees
   the step changes a safety filter makes when it acts or switches.
3. At every physics step record ``|q_dot - u|`` (Euclidean norm over the arm joints [rad/s],
   the norm the robust term ``|dh/dq| d_bar`` bounds by Cauchy-Schwarz).
4. ``d_bar = factor * quantile(samples, q)``.
5. Also record, per arm joint, the fraction of physics steps at which its actuator was at its
   torque or force limit (``saturation``): a tracker that saturates measures the actuator's
   limits, not its tracking, and :mod:`isf_robot.arm.diagnostics` warns about it.

A high quantile rather than the maximum: right after a step change of the command the error
equals the step for an instant and then decays within a few tens of milliseconds, so the
maximum measures the size of the largest step, not the tracking quality. Results are
cached per scene files and parameters for the life of the process.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError

from .actuation import make_actuation
from .nominal import ReachingController
from .scene import Scene
from .team_nominal import TeamReaching
from .tracking_law import tracking_error

__all__ = ["Calibration", "calibrate_d_bar", "clear_calibration_cache", "free_scene"]


@dataclass(frozen=True)
class Calibration:
    """Result of a tracking-error calibration.

    Attributes:
        d_bar: The bound to use, ``factor * quantile`` [rad/s].
        quantile: The quantile level q used.
        quantile_value: ``quantile(|q_dot - u|, q)`` [rad/s].
        max_error: Largest ``|q_dot - u|`` seen [rad/s].
        median_error: Median ``|q_dot - u|`` [rad/s].
        factor: Safety factor applied.
        duration_s: Simulated time [s].
        samples: Number of physics steps measured.
        saturation: Per arm joint, the fraction of physics steps its actuator was at its
            torque/force limit.
        joint_names: The arm joints, in the order of ``saturation``.
        friction_fed_forward: Whether the tracker fed the model's joint friction forward.

    """

    d_bar: float
    quantile: float
    quantile_value: float
    max_error: float
    median_error: float
    factor: float
    duration_s: float
    samples: int
    saturation: tuple[float, ...] = ()
    joint_names: tuple[str, ...] = ()
    friction_fed_forward: bool = True

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready)."""
        return dataclasses.asdict(self)


_CACHE: dict[tuple[Any, ...], Calibration] = {}
_OTHER_CACHES: list[dict[Any, Any]] = []


def clear_calibration_cache() -> None:
    """Forget every cached calibration (this module's and the other calibrations' registered with it)."""
    _CACHE.clear()
    for cache in _OTHER_CACHES:
        cache.clear()


def register_cache(cache: dict[Any, Any]) -> None:
    """Have :func:`clear_calibration_cache` clear ``cache`` too (the torque level's calibration cache)."""
    _OTHER_CACHES.append(cache)


def _key(scene: Scene, params: tuple[Any, ...]) -> tuple[Any, ...]:
    files: list[tuple[str, int | None] | None] = []
    for p in (scene.xml_path, scene.config.source):
        if p is None:
            files.append(None)
            continue
        try:
            files.append((str(p), p.stat().st_mtime_ns))
        except OSError:
            files.append((str(p), None))
    return (scene.name, *files, repr(scene.config), params)  # (the config as run: a control period set in memory)


def free_scene(scene: Scene, model: mujoco.MjModel | None = None) -> Scene:
    """``scene`` on a copy of ``model`` (default: its own) without contacts with the obstacles (calibration step 1).

    With several arms, the arms' contacts with each other are off too.
    """
    model = copy.deepcopy(scene.model if model is None else model)
    for g in (scene.obstacle_geom_ids if not scene.arms else
              np.concatenate([scene.obstacle_geom_ids, scene.robot_geom_ids])):
        model.geom_contype[g] = 0
        model.geom_conaffinity[g] = 0
    return dataclasses.replace(scene, model=model)


def calibrate_d_bar(
    scene: Scene,
    *,
    duration: float = 4.0,
    quantile: float = 0.99,
    factor: float = 1.5,
    excitation: float = 0.05,
    switch_period: float = 0.2,
    seed: int = 0,
    use_cache: bool = True,
    friction: bool = True,
) -> Calibration:
    """Measure the tracking-error bound ``d_bar`` of a scene (see the module docstring).

    Args:
        scene: The scene (its model is not modified; a copy is).
        duration: Simulated time [s], at least one control period.
        quantile: Quantile level in (0, 1].
        factor: Safety factor >= 1 applied to the quantile.
        excitation: Size of the random command offsets, as a fraction of ``max_joint_speed``.
        switch_period: Time between random offset changes [s], > 0.
        seed: Seed of the random offsets.
        use_cache: Reuse an earlier result for the same scene files and parameters.
        friction: The tracker feeds the model's joint friction forward, as in a run
            (:mod:`isf_robot.arm.lowlevel`); ``False`` measures the arm without it.

    Returns:
        The :class:`Calibration`.

    """
    if not duration >= scene.config.control.period:
        raise ConfigError(f"calibration duration must cover a control period ({scene.config.control.period:g} s), "
                          f"got {duration} s")
    if not 0.0 < quantile <= 1.0:
        raise ConfigError(f"calibration quantile must be in (0, 1], got {quantile}")
    if not factor >= 1.0:
        raise ConfigError(f"calibration safety factor must be >= 1, got {factor}")
    if not switch_period > 0 or excitation < 0:
        raise ConfigError("switch_period must be > 0 [s] and excitation >= 0")
    params = (duration, quantile, factor, excitation, switch_period, seed, friction)
    key = _key(scene, params)
    use_cache = use_cache and scene.xml_path is not None  # a scene built in memory has no file to key on
    if use_cache and key in _CACHE:
        return _CACHE[key]

    free = free_scene(scene)
    model = free.model
    data = free.make_data(0.0)
    nominal = ReachingController(free) if not scene.arms else TeamReaching(free)
    tracker = make_actuation(free, friction=friction)
    tracker.reset(data)
    rng = np.random.default_rng(seed)
    dt = float(model.opt.timestep)
    n_steps = int(round(duration / dt))
    per_switch = max(1, int(round(switch_period / dt)))
    per_control = max(1, int(round(scene.config.control.period / dt)))
    vmax = float(scene.config.gains.max_joint_speed)
    offset = np.zeros(free.n_joints)
    errors = np.empty(n_steps)
    sat = np.zeros(free.n_joints)
    moving = len(scene.config.moving) > 0
    dofs = scene.dof_adr
    for i in range(n_steps):
        t = i * dt
        if moving:
            scene.set_moving_obstacles(data, t)
        mujoco.mj_step1(model, data)
        if i % per_switch == 0:
            offset = (rng.uniform(-1.0, 1.0, free.n_joints) * excitation * vmax
                      if rng.random() < 0.5 else np.zeros(free.n_joints))
        if i % per_control == 0:  # the command changes at the control rate, as in a run
            u = nominal(t, data) + offset
            peak = float(np.max(np.abs(u)))
            if peak > vmax:
                u *= vmax / peak
            tracker.set_command(u, per_control * dt)
        errors[i] = tracking_error(data.qvel[dofs].tolist(), tracker.u.tolist())  # (as the run measures it)
        tracker.apply(data)
        mujoco.mj_step2(model, data)
        sat += tracker.saturated(data)
    qv = float(np.quantile(errors, quantile))
    cal = Calibration(d_bar=factor * qv, quantile=quantile, quantile_value=qv,
                      max_error=float(errors.max()), median_error=float(np.median(errors)),
                      factor=factor, duration_s=n_steps * dt, samples=n_steps,
                      saturation=tuple(float(x) for x in sat / n_steps), joint_names=scene.joint_names,
                      friction_fed_forward=bool(friction))
    if use_cache:
        _CACHE[key] = cal
    return cal
