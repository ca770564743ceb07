"""``d_bar`` calibrated with the safety filter in the loop (issue 13: an honest robust term).

The open-loop calibration (:func:`~isf_robot.arm.calibration.calibrate_d_bar`) measures how well the
low-level tracker follows the nominal task with random command offsets, with the obstacles' contacts
off. A filter in the loop makes its own command changes (switches, promotions, swerves around a moving
obstacle whose velocity reverses), and the tracking error it produces can exceed that bound; the robust
term ``|dh/dq| d_bar`` then no longer covers the model error it is meant to cover.

:func:`calibrate_in_loop` closes the loop: it runs the strategy itself on the real scene (contacts on,
moving obstacles on their paths) for a few seeds with the current ``d_bar``, takes the largest 99th
percentile of ``|q_dot - u|`` over those episodes (the figure every result reports as
``tracking_error_q99`` and checks against ``d_bar``), and, if it exceeds ``d_bar``, raises ``d_bar`` to
``factor`` times it and runs again, until the episodes' tracking error is covered or ``max_rounds`` is
reached. It never lowers ``d_bar`` (the open-loop value is the floor). A larger ``d_bar`` makes the filter
more conservative, which changes its commands, hence the rounds. It can also make them harsher: the
intermittent filter's promotion asks for more with a larger robust term, and its tracking error can grow
with ``d_bar`` (measured on panda_servo: 0.72 -> 1.79 -> 2.29 -> 2.95 rad/s). When a raised ``d_bar``
produces a larger tracking error than the round before and still does not cover it, raising further
feeds the error, so the calibration stops and returns the starting ``d_bar`` with ``covered = False``
(``diverged = True``): the run then warns that its tracking error is not covered, which is the honest
answer. Results are cached per scene files, strategy and parameters for the life of the process.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from isf_robot.core.exceptions import ConfigError
from isf_robot.core.strategies import strategy_info

from .calibration import _key
from .records import FilterParams
from .scene import Scene
from .sim import ArmSimulation

__all__ = ["LoopCalibration", "calibrate_in_loop", "loop_params"]


@dataclass(frozen=True)
class LoopCalibration:
    """Result of :func:`calibrate_in_loop`.

    Attributes:
        d_bar: The bound to use [rad/s] (>= ``start_d_bar``).
        strategy: The strategy run in the loop.
        start_d_bar: The ``d_bar`` the first round used (the open-loop calibration, config or argument).
        rounds: ``(d_bar used, largest tracking error q99 over the episodes)`` per round [rad/s].
        covered: Whether the last round's tracking error was within the ``d_bar`` it used (else
            ``max_rounds`` ran out and ``d_bar`` is the last raised value, not yet checked, or the
            calibration diverged).
        seeds: Episode seeds run per round.
        duration_s: Simulated time per episode [s].
        factor: Safety factor applied when raising ``d_bar``.

    """

    d_bar: float
    strategy: str
    start_d_bar: float
    rounds: tuple[tuple[float, float], ...]
    covered: bool
    seeds: tuple[int, ...]
    duration_s: float
    factor: float
    diverged: bool = False

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready)."""
        return dataclasses.asdict(self)


_CACHE: dict[tuple[Any, ...], LoopCalibration] = {}


def calibrate_in_loop(
    scene: Scene,
    strategy: str,
    params: FilterParams,
    *,
    seeds: Sequence[int] = (0, 1, 2, 3, 4, 5),
    duration: float = 6.0,
    factor: float = 1.25,
    max_rounds: int = 4,
    use_cache: bool = True,
) -> LoopCalibration:
    """Raise ``params.d_bar`` until the tracking error ``strategy`` produces is covered (module docstring).

    Args:
        scene: The scene.
        strategy: A registered strategy that filters (``cbf``, ``isf``, ...).
        params: The filter parameters; ``params.d_bar`` is the starting value.
        seeds: Episode seeds per round (non-empty).
        duration: Simulated time per episode [s], > 0.
        factor: Safety factor >= 1 applied to the measured tracking error when raising ``d_bar``.
        max_rounds: Most rounds, >= 1.
        use_cache: Reuse an earlier result for the same scene files, strategy and parameters.

    Returns:
        The :class:`LoopCalibration`.

    Raises:
        ConfigError: Bad arguments, or a strategy that never filters.

    """
    info = strategy_info(strategy)  # an unknown name raises ConfigError naming the valid ones
    if not info.filters:
        raise ConfigError(f"calibrating d_bar in the loop needs a filtering strategy, not {strategy!r}")
    seeds = tuple(int(s) for s in seeds)
    if not seeds:
        raise ConfigError("calibrating d_bar in the loop needs at least one seed")
    if not (math.isfinite(duration) and duration > 0):
        raise ConfigError(f"in-loop calibration duration must be > 0 [s], got {duration}")
    if not factor >= 1.0:
        raise ConfigError(f"in-loop calibration safety factor must be >= 1, got {factor}")
    if int(max_rounds) != max_rounds or max_rounds < 1:
        raise ConfigError(f"in-loop calibration max_rounds must be a whole number >= 1, got {max_rounds}")
    key = _key(scene, (strategy, params, seeds, duration, factor, max_rounds))
    use_cache = use_cache and scene.xml_path is not None
    if use_cache and key in _CACHE:
        return _CACHE[key]
    d = float(params.d_bar)
    rounds: list[tuple[float, float]] = []
    covered = diverged = False
    for _ in range(int(max_rounds)):
        p = dataclasses.replace(params, d_bar=d)
        worst = float(max(ArmSimulation(scene, strategy, seed=s, params=p).run(duration).tracking_error_q99
                          for s in seeds))
        rounds.append((d, worst))
        if worst <= d:
            covered = True
            break
        if len(rounds) > 1 and worst > rounds[-2][1]:  # raising d_bar made it worse: it feeds the error
            diverged, d = True, float(params.d_bar)
            break
        d = factor * worst
    cal = LoopCalibration(d_bar=d, strategy=strategy, start_d_bar=float(params.d_bar), rounds=tuple(rounds),
                          covered=covered, seeds=seeds, duration_s=float(duration), factor=float(factor),
                          diverged=diverged)
    if use_cache:
        _CACHE[key] = cal
    return cal


def loop_params(scene: Scene, strategy: str, params: FilterParams, **kwargs: Any) -> FilterParams:
    """``params`` with ``d_bar`` from :func:`calibrate_in_loop` (``d_bar_source`` gets ``"+loop"``).

    What ``isf-robot run --d-bar-in-loop`` does after resolving the parameters
    (:func:`~isf_robot.arm.params.resolve_params`); ``kwargs`` go to :func:`calibrate_in_loop`.
    """
    cal = calibrate_in_loop(scene, strategy, params, **kwargs)
    return params.replace(d_bar=cal.d_bar, d_bar_source=f"{params.d_bar_source}+loop")
