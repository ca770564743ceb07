"""Filter parameters of an arm run, resolved once and explicitly.

``d_bar`` (the tracking-error bound of the reduced model ``q_dot = u + d``) is a measured figure:
:func:`resolve_params` takes it from the caller, else from the scene config, else from the
tracking calibration (:func:`isf_robot.arm.calibration.calibrate_d_bar`, about 4 s per scene,
cached per process). The simulation never calibrates behind the caller's back: the command line
and :func:`isf_robot.arm.run_episode` call this function, and a script may too.
"""

from __future__ import annotations

import math

from isf_robot.core import ClassK, ConfigError, Linear

from .records import FilterParams
from .scene import Scene

__all__ = ["resolve_params"]


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
    if d_bar is not None:
        if not (math.isfinite(d_bar) and d_bar >= 0):
            raise ConfigError(f"d_bar must be >= 0 [rad/s], got {d_bar}")
        return FilterParams(a, cc, bb, float(d_bar), "argument")
    if fc.d_bar > 0:
        return FilterParams(a, cc, bb, float(fc.d_bar), "config")
    if not calibrate:
        raise ConfigError(
            f"scene {scene.name!r} has no d_bar ([filter] d_bar = 0): pass d_bar=, or "
            "params=resolve_params(scene) (runs the tracking calibration, about 4 s)")
    from .calibration import calibrate_d_bar

    return FilterParams(a, cc, bb, calibrate_d_bar(scene).d_bar, "calibration")
