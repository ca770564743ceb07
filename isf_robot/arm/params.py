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

import math
from typing import Any

import numpy as np

from isf_robot.core import ClassK, ConfigError, Linear

from .calibration import calibrate_d_bar
from .records import FilterParams
from .rollout import NominalRollout
from .scene import Scene

__all__ = ["resolve_params", "filter_options"]


def _positive(label: str, v: float) -> float:
    v = float(v)
    if not (math.isfinite(v) and v > 0):
        raise ConfigError(f"filter parameter {label} must be > 0, got {v}")
    return v


def resolve_params(
    scene: Scene,
    alpha: float | ClassK | None = None,
    c: float | None = None,
    b: float | None = None,
    d_bar: float | None = None,
    *,
    calibrate: bool = True,
    min_off: float | None = None,
    c_max: float | None = None,
    blend: float | None = None,
    horizon: float | None = None,
    predict_every: int | None = None,
    c_pred: float | None = None,
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
        min_off: Asked-for shortest off period [s]; default ``[filter] min_off`` (0: the fixed margin ``c``).
        c_max: Largest margin ``min_off`` may design (``None``: no cap beyond the scene's).
        blend: Hand-over time after each switch [s]; default ``[filter] blend`` (0: none).
        horizon: Horizon of the predictive off trigger [s]; default ``[filter] horizon`` (0: none).
        predict_every: Control steps between its rollouts (``None``: 5).
        c_pred: Off margin when the rollout predicts the nominal safe over the horizon (``0 < c_pred <= c``);
            default ``[filter] c_pred`` (0: none, the prediction only delays the off switch at ``c``).

    Raises:
        ConfigError: A parameter is not a positive number (``d_bar``: not >= 0), or ``d_bar``
            is unknown and ``calibrate`` is False.

    """
    fc = scene.config.filter
    a: float | ClassK
    if isinstance(alpha, ClassK):
        a = alpha.gain if isinstance(alpha, Linear) else alpha
    else:
        a = _positive("alpha", fc.alpha if alpha is None else alpha)
    cc = _positive("c", fc.c if c is None else c)
    bb = _positive("b", fc.b if b is None else b)
    min_off = (fc.min_off or None) if min_off is None else min_off  # the scene's [filter] when not given
    blend = fc.blend if blend is None else blend
    horizon = fc.horizon if horizon is None else horizon
    c_pred = (fc.c_pred or None) if c_pred is None else c_pred
    opts = _options(cc, min_off, c_max, blend, horizon, predict_every)
    if c_pred is not None:
        c_pred = _positive("c_pred", c_pred)
        if c_pred > cc:
            raise ConfigError(f"filter parameter c_pred must be <= c = {cc}, got {c_pred}")
        if not opts.get("horizon", 0.0) > 0:
            raise ConfigError("filter parameter c_pred needs the predictive off trigger: a horizon > 0 [s]")
        opts["c_pred"] = c_pred
    if d_bar is not None:
        if not (math.isfinite(d_bar) and d_bar >= 0):
            raise ConfigError(f"d_bar must be >= 0 [rad/s], got {d_bar}")
        p = FilterParams(a, cc, bb, float(d_bar), "argument", **opts)
    elif fc.d_bar > 0:
        p = FilterParams(a, cc, bb, float(fc.d_bar), "config", **opts)
    elif not calibrate:
        raise ConfigError(
            f"scene {scene.name!r} has no d_bar ([filter] d_bar = 0): pass d_bar=, or "
            "params=resolve_params(scene) (runs the tracking calibration, about 4 s)")
    else:
        p = FilterParams(a, cc, bb, calibrate_d_bar(scene).d_bar, "calibration", **opts)
    return p


def _options(c: float, min_off: float | None, c_max: float | None, blend: float | None,
             horizon: float | None, every: int | None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    if min_off is not None:
        out["min_off"] = _positive("min_off [s]", min_off)
    if c_max is not None:
        if not (float(c_max) >= c):  # inf allowed
            raise ConfigError(f"filter parameter c_max must be >= c = {c}, got {c_max}")
        out["c_max"] = float(c_max)
    for label, v in (("blend", blend), ("horizon", horizon)):
        if v is not None:
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"filter parameter {label} must be >= 0 [s] (0: off), got {v}")
            out[label] = float(v)
    if every is not None:
        if isinstance(every, bool) or int(every) != every or every < 1:
            raise ConfigError(f"filter parameter predict_every must be a whole number of control steps >= 1, "
                              f"got {every}")
        out["predict_every"] = int(every)
    return out


def filter_options(sim: Any) -> dict[str, Any]:
    """Keyword arguments of the strategy of ``sim`` besides ``alpha, c, b, d_bar``.

    ``sim`` is an :class:`~isf_robot.arm.ArmSimulation` being built. The options are those of its
    :class:`FilterParams` and, with a horizon, the rollout of the nominal on the reduced model
    (:class:`~isf_robot.arm.rollout.NominalRollout`); empty for a strategy that is not intermittent.
    With ``min_off`` the designed margin is capped at ``alpha(cutoff - margin)`` too: a larger one
    could not be met by a pair at the broad-phase cut-off.
    """
    p: FilterParams = sim.params
    if not sim.info.intermittent:
        return {}
    out = p.intermittent_options()
    if p.min_off is not None:  # no margin above what a pair at the broad-phase cut-off can reach
        cutoff_h = float(np.min(sim.coll.cutoff - sim.coll.pairs.margin))
        out["c_max"] = max(p.c, min(p.c_max, p.class_k(cutoff_h)))
    if p.horizon > 0:
        out["rollout"] = NominalRollout(sim, p.horizon)
    return out
