"""The paired study (``isf-satellite study``): every trigger x controller from the same starts.

A *start* is one initial orbit, ``(seed, inclination)`` (:class:`satellite.orbit.model.InitialOrbit`:
radius 2R, circular speed, node, argument of latitude and body phase drawn from the seed). A
*configuration* is a trigger (``greedy``, ``maneuver`` with the controller's fitted tau_p,
``periodic`` every T hours) with a safeguarding controller (``kepler``, the paper's; any other
name :data:`satellite.control.controller.CONTROLLERS` offers is passed through ``ControlParams``). Every
configuration flies every start, so configurations are compared orbit by orbit
(:mod:`satellite.study.stats`: mean paired reduction with a 95 % confidence interval).

Runs go through :func:`isf_robot.support.parallel.run_tasks` (local processes or Ray); a
``checkpoint`` callback gets the document after every finished run (the CLI writes it atomically,
marked partial), and ``done_runs`` (from such a file) are not run again.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from isf_robot.core import ConfigError, UnknownNameError
from isf_robot.support.parallel import Interrupted, run_tasks
from satellite.control import controller
from satellite.control.controller import ControlParams
from satellite.control.tau import load_tau
from satellite.gravity.fields import load_field
from satellite.orbit.model import InitialOrbit, OrbitModel
from satellite.orbit.simulate import IntegratorSettings, simulate
from satellite.shape.mesh_surface import load_surface
from satellite.study.stats import paired_comparison, summarize_config

__all__ = ["StudyConfig", "StudySettings", "StudyTask", "run_one", "run_study", "plan", "controllers",
           "STUDY_TRIGGERS"]

STUDY_TRIGGERS = ("greedy", "maneuver", "periodic")
"""Triggers a study can compare."""

SURFACE_BARRIER_TRIGGERS = ("greedy", "maneuver")
"""Triggers that can add the surface barrier (a periodic run fires on the clock, not on a barrier)."""

CI_METHOD = ("paired t (mean +- t_0.975,n-1 sd/sqrt(n)) of the per-orbit reductions 1 - a/b; "
             "percentile bootstrap (10,000 resamples of the orbits) beside it")


def controllers() -> tuple[str, ...]:
    """Controllers available in this tree (``kepler`` always; others as :mod:`satellite.control.controller` offers)."""
    return tuple(getattr(controller, "CONTROLLERS", ("kepler",)))


@dataclass(frozen=True)
class StudyConfig:
    """One configuration: trigger, controller and (periodic only) the period [h]."""

    trigger: str
    controller: str = "kepler"
    period_h: float | None = None

    @property
    def label(self) -> str:
        trig = f"periodic {self.period_h:g}h" if self.trigger == "periodic" else self.trigger
        return f"{trig}/{self.controller}"


@dataclass(frozen=True)
class StudySettings:
    """What every run of a study shares (recorded in the output; a resumed study must match it)."""

    hours: float
    gravity: str = "table"
    spin: bool = True
    disturbance_scale: float = 1.0
    alpha_gain: float | None = None
    rtol: float = 1e-10
    tau: Mapping[str, str] = field(default_factory=dict)
    """tau_p file per controller (``maneuver`` needs its controller's)."""
    surface_barrier: bool = False
    """Greedy and maneuver runs add the surface-clearance barrier (``isf-satellite run --surface-barrier``)."""

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["tau"] = dict(self.tau)
        return out


@dataclass(frozen=True)
class StudyTask:
    """One orbit run: a configuration from a start."""

    config: StudyConfig
    seed: int
    inclination_deg: float
    settings: StudySettings

    @property
    def key(self) -> tuple[str, int, float]:
        return self.config.label, self.seed, self.inclination_deg


def _control(settings: StudySettings, controller: str) -> ControlParams:
    if controller == "kepler":
        return ControlParams(alpha_gain=settings.alpha_gain)
    return ControlParams(alpha_gain=settings.alpha_gain, controller=controller)  # type: ignore[call-arg]


_LOADED: dict[tuple[str, str], Any] = {}
"""Gravity fields and the shape read once per process (a worker flies many orbits; read-only objects)."""


def _loaded(kind: str, name: str) -> Any:
    key = (kind, name)
    if key not in _LOADED:
        if kind == "gravity":

            _LOADED[key] = load_field(name)
        else:

            _LOADED[key] = load_surface()
    return _LOADED[key]


def run_one(task: StudyTask) -> dict[str, Any]:
    """Fly one orbit; return its JSON-ready record (the study's per-run row)."""
    cfg, st = task.config, task.settings
    tau = load_tau(st.tau[cfg.controller]) if cfg.trigger == "maneuver" else None
    initial = InitialOrbit(seed=task.seed, inclination_deg=task.inclination_deg)
    model = OrbitModel(_loaded("gravity", st.gravity), spin=st.spin, disturbance_scale=st.disturbance_scale)
    res = simulate(
        cfg.trigger, st.hours, initial=initial, model=model, control=_control(st, cfg.controller), tau=tau,
        integrator=IntegratorSettings(rtol=st.rtol), miet_samples=200, contact="count",
        contact_surface=_loaded("shape", "default"), period_h=cfg.period_h,
        surface_barrier=st.surface_barrier and cfg.trigger in SURFACE_BARRIER_TRIGGERS,
    )
    s = res.summary()
    keys = ("triggers", "kinds", "min_xi_tau", "min_h", "surface_min_h_m", "surface_impulses", "r_min_over_R",
            "r_max_over_R", "total_dv", "min_inter_event_h",
            "mean_inter_event_h", "miet_bound_h", "left_band_h", "band_exits", "simulated_h", "wall_s", "nfev",
            "surface_contacts", "min_pass_clearance_m", "first_contact_h", "physical_h", "triggers_physical",
            "total_dv_physical")
    out: dict[str, Any] = {"config": cfg.label, "seed": task.seed, "inclination_deg": task.inclination_deg}
    start = model.with_phase(initial.body_phase())  # as simulate() sets the run up: the pairing's evidence
    out["x0"] = initial.state(start).tolist()
    out["body_phase_rad"] = start.body_phase
    out.update({k: s.get(k) for k in keys})
    out["completed"] = bool(res.simulated_h >= st.hours * (1.0 - 1e-9))
    end_s = 3600.0 * s["physical_h"]  # the impulses before the first contact, for paired physical counts
    out["impulses_physical"] = [[j.t / 3600.0, float(np.linalg.norm(j.v))] for j in res.events if j.t < end_s]
    return out


def plan(triggers: Sequence[str], ctrls: Sequence[str], periods_h: Sequence[float]) -> list[StudyConfig]:
    """The configurations: every trigger with every controller (periodic once per period).

    Raises:
        UnknownNameError: A trigger or controller that does not exist.
        ConfigError: A bad period, or periods without the periodic trigger.

    """
    for t in triggers:
        if t not in STUDY_TRIGGERS:
            raise UnknownNameError("study trigger", t, STUDY_TRIGGERS)
    for c in ctrls:
        if c not in controllers():
            raise UnknownNameError("controller", c, controllers())
    for p in periods_h:
        if not (math.isfinite(p) and p > 0):
            raise ConfigError(f"--period-h must be positive numbers of hours, got {p:g}")
    if "periodic" in triggers and not periods_h:
        raise ConfigError("the periodic trigger needs at least one --period-h")
    out = []
    for c in dict.fromkeys(ctrls):
        for t in dict.fromkeys(triggers):
            if t == "periodic":
                out += [StudyConfig(t, c, float(p)) for p in dict.fromkeys(periods_h)]
            else:
                out.append(StudyConfig(t, c))
    if not out:
        raise ConfigError("no configuration to run (give --triggers and --controllers)")
    return out


def _comparisons(configs: Sequence[StudyConfig], runs: Mapping[str, list[dict[str, Any]]]) -> list[dict[str, Any]]:
    pairs: list[tuple[StudyConfig, StudyConfig]] = []
    for a in configs:
        for b in configs:
            same_ctrl = a.controller == b.controller
            if same_ctrl and a.trigger == "maneuver" and b.trigger in ("greedy", "periodic"):
                pairs.append((a, b))
            elif same_ctrl and a.trigger == "greedy" and b.trigger == "periodic":
                pairs.append((a, b))
            elif (a.trigger, a.period_h) == (b.trigger, b.period_h) and a.controller != "kepler" == b.controller:
                pairs.append((a, b))
    pairs.sort(key=lambda ab: (ab[0].controller != ab[1].controller, ab[1].trigger != "greedy"))
    return [{"a": a.label, "b": b.label, **paired_comparison(runs.get(a.label, []), runs.get(b.label, []))}
            for a, b in pairs]


def _document(configs: Sequence[StudyConfig], starts: Sequence[tuple[int, float]], settings: StudySettings,
              done: Sequence[dict[str, Any]], total: int, partial: bool) -> dict[str, Any]:
    by_label: dict[str, list[dict[str, Any]]] = {}
    for r in sorted(done, key=lambda r: (r["seed"], r["inclination_deg"])):
        by_label.setdefault(r["config"], []).append(r)
    return {
        "partial": partial,
        "orbits_done": len(done),
        "orbits_total": total,
        "settings": settings.as_dict(),
        "starts": [list(s) for s in starts],
        "ci_method": CI_METHOD,
        "configs": [{"label": c.label, "trigger": c.trigger, "controller": c.controller, "period_h": c.period_h,
                     "summary": summarize_config(by_label.get(c.label, []))} for c in configs],
        "comparisons": _comparisons(configs, by_label),
        "runs": [r for c in configs for r in by_label.get(c.label, [])],
    }


def run_study(
    configs: Sequence[StudyConfig],
    starts: Sequence[tuple[int, float]],
    settings: StudySettings,
    *,
    jobs: int = 1,
    backend: str = "processes",
    address: str | None = None,
    done_runs: Sequence[dict[str, Any]] = (),
    progress: Callable[[int, int, StudyTask, dict[str, Any]], None] | None = None,
    checkpoint: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Run every configuration from every start; return the study document.

    Args:
        configs: From :func:`plan`.
        starts: ``(seed, inclination_deg)`` pairs, the same for every configuration.
        settings: Shared settings (``tau`` must name a file for every controller with ``maneuver``).
        jobs: Worker processes or Ray tasks in flight (:func:`isf_robot.support.parallel.run_tasks`).
        backend: ``processes`` or ``ray``.
        address: Ray cluster to join (``ray`` only).
        done_runs: Runs of an earlier, interrupted call with the same settings (not run again).
        progress: ``progress(done, total, task, run)`` after each run.
        checkpoint: Gets the (partial) document after each run.

    Raises:
        ConfigError: No starts, duplicate starts, a missing tau file.
        Interrupted: Ctrl-C / SIGTERM; ``exc.partial`` is the document of the finished runs.

    """
    if not starts:
        raise ConfigError("no starts (give --seeds >= 1 and at least one --inclinations)")
    if len(set(starts)) != len(starts):
        raise ConfigError("duplicate starts (seed, inclination)")
    if not (math.isfinite(settings.hours) and settings.hours > 0):
        raise ConfigError(f"--hours must be a finite number > 0, got {settings.hours:g}")
    if settings.surface_barrier and any(c.trigger not in SURFACE_BARRIER_TRIGGERS for c in configs):
        raise ConfigError(f"--surface-barrier works with the triggers {' and '.join(SURFACE_BARRIER_TRIGGERS)}, "
                          "not periodic (give --triggers greedy maneuver)")
    for c in configs:
        if c.trigger == "maneuver" and c.controller not in settings.tau:
            raise ConfigError(f"maneuver/{c.controller} needs a tau_p file: --tau FILE or --tau {c.controller}=FILE "
                              f"(make one with `isf-satellite tau --out FILE`)")
    # start by start: an interrupted study keeps whole pairs (every configuration of a start) where it can
    tasks = [StudyTask(c, int(s), float(i), settings) for s, i in starts for c in configs]
    total = len(tasks)
    keep = {(r["config"], r["seed"], r["inclination_deg"]): r for r in done_runs}
    done = [keep[t.key] for t in tasks if t.key in keep]
    todo = [t for t in tasks if t.key not in keep]

    def on_result(k: int, n: int, task: StudyTask, run: dict[str, Any]) -> None:
        done.append(run)
        if progress is not None:
            progress(len(done), total, task, run)
        if checkpoint is not None:
            checkpoint(_document(configs, starts, settings, done, total, True))

    try:
        run_tasks(run_one, todo, jobs=jobs, on_result=on_result, backend=backend, address=address)
    except Interrupted as exc:
        exc.partial = _document(configs, starts, settings, done, total, True)
        raise
    return _document(configs, starts, settings, done, total, False)
