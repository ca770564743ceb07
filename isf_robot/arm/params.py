"""Filter parameters of an arm run, resolved once and explicitly.

``d_bar`` (the tracking-error bound of the reduced model ``q_dot = u + d``) is a measured figure:
:func:`resolve_params` takes it from the caller, else from the scene config, else from the
tracking calibration (:func:`isf_robot.arm.calibration.calibrate_d_bar`, about 4 s per scene,
cached per process). The simulation never calibrates behind the caller's back: the command line
and :func:`isf_robot.arm.run_episode` call this function, and a script may too. Raising ``d_bar``
with the filter in the loop is a step after this one (:func:`isf_robot.arm.calibration_loop.loop_params`,
which runs simulations).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from isf_robot.core import ClassK, ConfigError, FilterSpec, Linear

from .actuation import servo_lead
from .calibration import calibrate_d_bar
from .filter_design import with_design
from .records import FilterParams
from .rollout import NominalRollout
from .scene import Scene

__all__ = ["resolve_params", "filter_options"]


def resolve_params(
    scene: Scene,
    alpha: float | ClassK | None = None,
    c: float | None = None,
    b: float | None = None,
    d_bar: float | None = None,
    *,
    calibrate: bool = True,
    servos: bool = True,
    **options: Any,
) -> FilterParams:
    """The filter parameters of a run on ``scene``: arguments first, then ``[filter]`` of the config.

    Args:
        scene: The scene.
        alpha: Class-K gain [1/s] or function; default ``[filter] alpha``.
        c: Off-trigger margin; default ``[filter] c``.
        b: Promotion rate; default ``[filter] b``.
        d_bar: Tracking-error bound [rad/s]; default ``[filter] d_bar`` when positive, else
            calibrated (when ``calibrate``).
        calibrate: Allow the calibration run.
        servos: The arm's position servos drive the joints (the velocity level), so the designed hand-over
            is no shorter than their time constant (:func:`~isf_robot.arm.actuation.servo_lead`);
            ``False`` for a level that drives the joints by torque with the actuators off.
        **options: Any other field of :class:`~isf_robot.core.FilterSpec` (``min_off``, ``c_max``,
            ``blend``, ``horizon``, ``predict_every``, ``c_pred``, ...); ``None``: the scene's. A
            ``blend`` or ``horizon`` that neither gives is designed from the scene
            (:mod:`isf_robot.arm.filter_design`).

    Raises:
        ConfigError: A parameter the spec refuses, an unknown one, ``c_pred`` without a horizon,
            or ``d_bar`` unknown and ``calibrate`` False.

    """
    given = {"alpha": alpha.gain if isinstance(alpha, Linear) else alpha, "c": c, "b": b, **options}
    spec = FilterSpec.from_mapping(given, scene.config.filter)
    spec = with_design(scene.config, spec, servo_lead(scene) if servos else 0.0)
    if spec.c_pred and not spec.horizon > 0:
        raise ConfigError("filter parameter c_pred needs the predictive off trigger: a horizon > 0 [s]")
    fields = {f.name: getattr(spec, f.name) for f in dataclasses.fields(FilterSpec)}
    if d_bar is not None:
        fields["d_bar"], source = d_bar, "argument"
    elif spec.d_bar > 0:
        source = "config"
    elif not calibrate:
        raise ConfigError(
            f"scene {scene.name!r} has no d_bar ([filter] d_bar = 0): pass d_bar=, or "
            "params=resolve_params(scene) (runs the tracking calibration, about 4 s)")
    else:
        fields["d_bar"], source = calibrate_d_bar(scene).d_bar, "calibration"
    return FilterParams(**fields, d_bar_source=source)


def filter_options(sim: Any, rollout: Callable[[float], Any] | None = None) -> tuple[FilterParams, dict[str, Any]]:
    """The strategy's parameters and wiring for ``sim``, an :class:`~isf_robot.arm.ArmSimulation` being built.

    With ``min_off`` the designed margin is capped at ``alpha`` of the rows' value beyond the cut-off too
    (``sim.far_value()``: a larger one could not be met by a pair at the broad-phase cut-off; ``cutoff - margin``,
    at the torque level ``alpha_1 (cutoff - margin)``); with a horizon, the wiring holds the rollout of the
    nominal on the reduced model (:class:`~isf_robot.arm.rollout.NominalRollout`), and with ``shoot`` the
    shooting's rollout (the same, over ``shoot`` seconds). ``rollout(horizon)``: the level's own rollout instead
    (the torque level's).
    """
    p: FilterParams = sim.params
    if not sim.info.intermittent:
        return p, {}
    wiring: dict[str, Any] = {}
    if p.min_off:  # no margin above what a pair at the broad-phase cut-off can reach
        p = p.replace(c_max=max(p.c, min(p.c_max, p.class_k(sim.far_value()))))
    for key, horizon in (("rollout", p.horizon), ("shoot_rollout", p.shoot)):
        if horizon > 0:
            wiring[key] = (rollout(horizon) if rollout is not None else
                           NominalRollout(sim.scene, sim.nominal, sim.coll, sim.joints, sim.control_period,
                                          sim.setup.time_offset, horizon))
    return p, wiring
