"""Static figures for people who would rather look than read (matplotlib: the ``plots`` extra).

* :func:`run_figure`: an arm run's ``min h`` over time with the filter's on-intervals shaded,
  ``min Xi_on`` with its thresholds 0 (on) and ``c`` (off), and ``|u - u_nom|``.
* :func:`compare_figure`: ``min h`` over time per strategy, and bars of duty cycle, on
  switches, intervention and ``min h`` per strategy (range over episodes as whiskers).
* :func:`satellite_figure`: the paper's figure of a satellite run, ``r/R`` inside the band and
  ``Xi`` with a star at each trigger, over the first 150 h.
* :func:`tau_figure`: the time-to-trigger samples per radius, their medians and the fitted ``tau_p``.
* :func:`team_run_figure`, :func:`team_compare_figure`: arms sharing a workspace, a row per arm
  (its pairs' ``min h``, its own on-intervals, its correction), and each arm's figures per way of
  filtering (:class:`TeamBars`).
* :func:`pareto_figure`: a parameter sweep's points per scene, duty cycle vs intervention, the
  Pareto front marked and cbf as the reference (:func:`sweep_scenes` reads the sweep JSON).

The figures take the small series of :mod:`isf_robot.plots.data` and know no engine or file
format; this package imports only the core, numpy and (when a figure is made) matplotlib.
"""

from __future__ import annotations

from .data import OrbitSeries, RunSeries, StrategyBars, TauSamples, break_gaps, on_intervals
from .figures import ON_COLOR, compare_figure, run_figure, satellite_figure, strategy_color, tau_figure
from .output import FORMATS, PlotsUnavailableError, check_figure_path, new_figure, require_matplotlib, save_figure
from .pareto import ParetoPoint, pareto_figure, sweep_scenes
from .team import CHATTER_S, TeamBars, team_compare_figure, team_run_figure

__all__ = [
    "RunSeries", "StrategyBars", "OrbitSeries", "TauSamples", "on_intervals", "break_gaps",
    "run_figure", "compare_figure", "satellite_figure", "tau_figure", "ON_COLOR", "strategy_color",
    "ParetoPoint", "pareto_figure", "sweep_scenes",
    "TeamBars", "team_run_figure", "team_compare_figure", "CHATTER_S",
    "FORMATS", "PlotsUnavailableError", "require_matplotlib", "new_figure", "save_figure", "check_figure_path",
]
