"""The arm simulation loop: nominal task, strategy, low-level tracking, MuJoCo physics.

One control step at ``t_k = k T`` (T the control period, a whole multiple of the physics
timestep dt; ``S = T / dt`` physics steps per control step)::

    sense        mj_step1: kinematics, M(q), bias forces at the current state
    barriers     collision pairs (cut-off) and joint limits: h, dh/dq, dh/dt; the tick's
                 safety accounting on the true geometry
    nominal      u_nom = nominal(t_k)
    strategy     u = strategy.step_lie(t_k, rows, u_nom)      (nominal | cbf | isf | ...)
    act          torques for the held u, mj_step2, then S - 1 more physics steps, each
                 checked on the true geometry (:class:`~isf_robot.arm.monitor.SafetyMonitor`)

Everything the filter decides (the trigger, promotions, screening of far rows, the re-solve
when a screened row is needed, switch events of every strategy, the infeasibility policy)
lives in the core's strategies (:mod:`isf_robot.core.strategies`); the loop only assembles the
rows. Rows: the collision pairs within the broad-phase cut-off and the joint limits. Rows whose
robust condition has a large slack under ``u_nom`` (``collision_row_slack``,
``joint_row_slack``, never below ``c``) are screened out of the QP by the core and checked at its
solution, so screening only saves time.

If a filter's QP is infeasible even with every promotion relaxed, the arm brakes (``u = 0``);
such steps are counted in ``fallbacks`` and never hidden.

Observers (:class:`isf_robot.core.Observer`) receive ``on_start(info)`` (see
:meth:`ArmSimulation.start_info`, plus ``data``: the live MjData), the steps, ``on_event`` per
:class:`~isf_robot.core.SwitchEvent` and ``on_finish(summary)``. The loop writes each step into a
:class:`~isf_robot.arm.step_columns.StepColumns` block (only when an observer is attached), at the
tick (the state the rows were computed from, the command), and the smallest true-geometry barrier
value ``dist - margin`` (each pair's own margin) over its physics steps after them: observers that
take blocks (``on_steps``, the Rerun recorder) get the block when it is full and at the end; the
others get ``on_step`` with an :class:`~isf_robot.arm.records.ArmStepRecord` at every step. Timing
per phase (``timing=True``) wraps the phases with timers; the loop itself has none.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from typing import Any

import mujoco
import numpy as np

from isf_robot.core import ConfigError, LieData, MetricsAccumulator, Observer, Observers, QPSolver, as_class_k
from isf_robot.core.hooks import takes_blocks
from isf_robot.core.strategies import make_strategy, strategy_info

from .actuation import Actuation, make_actuation, tracking_step
from .barriers import CollisionBarriers, JointLimitBarriers
from .episode import EpisodeSetup, check_control_period, episode_setup, path_track
from .lowlevel import as_slice
from .monitor import SafetyMonitor
from .nominal import NominalController, ReachingController
from .params import filter_options, resolve_params
from .records import FilterParams, RunResult
from .scene import Scene
from .step_columns import StepColumns, TickValues
from .timing import PhaseTimers

__all__ = ["ArmSimulation", "run_episode"]

_new = tuple.__new__  # a NamedTuple from a tuple of its fields (as _make, without the length check)

PHASES = ("sense", "barriers", "nominal", "strategy", "act")
MAX_CONTROL_STEPS = 10_000_000
"""Longest run in control steps (the obstacle paths and tracking errors are stored per step)."""
BLOCK_STEPS = 2048
"""Steps per block handed to block observers (an observer's ``block_steps`` attribute lowers it)."""
PROGRESS_STEPS = 256
"""Control steps between calls of a simulation's ``progress`` (when it has one)."""


def _brake(t: float, x: Any, lie: LieData, res: Any) -> np.ndarray:
    """Fallback when no command satisfies the safety constraints: stop (u = 0)."""
    return np.zeros(lie.m)


class ArmSimulation:
    """One episode of an arm scene under a strategy.

    Args:
        scene: The scene.
        strategy: A registered strategy name (:func:`isf_robot.core.strategies.strategy_names`).
        seed: Episode seed (initial configuration, goal jitter, obstacle phase; see
            :func:`episode_setup`). ``None``: the scene exactly as configured.
        nominal: The nominal controller; default a :class:`ReachingController` through the
            (seeded) goals.
        tracker: The low-level controller; default :func:`~isf_robot.arm.actuation.make_actuation`.
        params: Resolved filter parameters (:func:`isf_robot.arm.resolve_params`); or give
            ``alpha``, ``c``, ``b``, ``d_bar`` (config values fill the rest; ``d_bar`` must be
            known: no calibration is run here).
        control_period: Control period [s]; default ``[control] period``. Must be a whole
            multiple of the model timestep.
        observers: Observers called during :meth:`run`.
        timing: Measure wall time per phase (``RunResult.timings``).
        solver: QP solver for the filters (default :class:`QPSolver`).
        joint_row_slack: Screening threshold of the joint-limit rows [rad/s] (default 0.5,
            never below ``c``; ``inf`` keeps every row).
        collision_row_slack: Screening threshold of the collision rows [m/s] (default 0.1,
            never below ``c``).

    Raises:
        UnknownNameError: Unknown strategy (the message lists the valid ones).
        ConfigError: Invalid parameters.

    """

    episode: type[_Episode]

    def __init__(
        self,
        scene: Scene,
        strategy: str = "isf",
        *,
        seed: int | None = 0,
        nominal: NominalController | None = None,
        tracker: Actuation | None = None,
        params: FilterParams | None = None,
        alpha: float | None = None,
        c: float | None = None,
        b: float | None = None,
        d_bar: float | None = None,
        control_period: float | None = None,
        observers: Iterable[Observer] = (),
        timing: bool = False,
        solver: QPSolver | None = None,
        joint_row_slack: float | None = None,
        collision_row_slack: float | None = None,
    ) -> None:
        self.info = strategy_info(strategy)
        self.scene = scene
        self.seed = seed
        model = scene.model
        self.timestep = float(model.opt.timestep)
        self.control_period = float(scene.config.control.period if control_period is None else control_period)
        self.substeps = check_control_period(self.control_period, self.timestep)
        self.setup = (episode_setup(scene, seed) if seed is not None else
                      EpisodeSetup(scene.home.copy(), scene.goal_positions.copy(), 0.0))
        self.nominal = nominal if nominal is not None else ReachingController(scene, goals=self.setup.goals)
        if self.nominal.n != scene.n_joints:
            raise ConfigError(f"nominal controller has {self.nominal.n} joints, the scene {scene.n_joints}")
        self.tracker = self._make_tracker(tracker)
        self.params = p = params if params is not None else resolve_params(scene, alpha, c, b, d_bar, calibrate=False)
        self.coll = CollisionBarriers.from_scene(scene)
        self.joints = JointLimitBarriers.from_scene(scene)
        self.names = self.coll.names + self.joints.names
        self.observers = Observers(observers)
        self.timing = bool(timing)
        self.progress: Callable[[float, float], None] | None = None
        """Called as ``progress(t, duration)`` every :data:`PROGRESS_STEPS` control steps of a run (``None``: not)."""
        keep_j = 0.5 if joint_row_slack is None else float(joint_row_slack)
        keep_c = 0.1 if collision_row_slack is None else float(collision_row_slack)
        if not (keep_j >= 0 and keep_c >= 0):
            raise ConfigError(f"joint_row_slack and collision_row_slack must be >= 0, got {keep_j} and {keep_c}")
        self.keep_collision, self.keep_joint = max(p.c, keep_c), max(p.c, keep_j)
        far = as_class_k(p.alpha)(self.far_value())
        if self.info.intermittent and far < p.c:
            raise ConfigError(
                f"alpha({self.far_formula}) = {far:.3g} < c = {p.c}: pairs beyond the broad-phase cut-off would "
                "keep the intermittent filter on; raise the cut-off")
        self.strategy = self._make_strategy(strategy, solver if solver is not None else QPSolver(few_rows=True))

    far_formula = "cutoff - margin"
    """How :meth:`far_value` is made (for messages)."""

    def far_value(self) -> float:
        """The least value of a collision row beyond the broad-phase cut-off: ``h = cutoff - margin`` [m].

        A pair there counts with this value; the intermittent filter needs ``alpha`` of it to be at least ``c``.
        """
        return float(np.min(self.coll.cutoff - self.coll.pairs.margin))

    def _make_tracker(self, tracker: Actuation | None) -> Actuation | None:
        """The low-level controller (the argument, else :func:`~isf_robot.arm.actuation.make_actuation`).

        A level that drives the joints otherwise returns ``None`` (its episode's ``act`` does not track).
        """
        return tracker if tracker is not None else make_actuation(self.scene)

    def _make_strategy(self, strategy: str, solver: QPSolver) -> Any:
        """The strategy of this level (called once, last in ``__init__``; a level with rows of its own overrides)."""
        spec, wiring = filter_options(self)
        return make_strategy(strategy, spec, **wiring, solver=solver, on_infeasible="fallback", fallback=_brake,
                             validate=False)

    def start_info(self, duration: float) -> dict[str, Any]:
        """What observers learn when a run starts: the run's settings and the model's geometry."""
        s, p = self.scene, self.params
        return {
            "scene": s.name, "model_path": str(s.xml_path) if s.xml_path is not None else None,
            "config_path": str(s.config.source) if s.config.source else None,
            "strategy": self.info.name, "seed": self.seed, "dt": self.timestep,
            "control_period": self.control_period, "duration": duration, "names": self.names,
            "joint_names": s.joint_names, "n_collision": self.coll.pairs.k,
            "goals": getattr(self.nominal, "goal_positions", None), **p.as_dict(),
            "model": s.model, "qpos_adr": np.asarray(s.qpos_adr), "dof_adr": np.asarray(s.dof_adr),
            "ee_site_id": int(s.ee_site_id), "pair_margins": np.asarray(self.coll.pairs.margin, dtype=float),
            "robot_geom_ids": np.asarray(s.robot_geom_ids), "obstacle_geom_ids": np.asarray(s.obstacle_geom_ids),
        }

    def control_steps(self, duration: float | None = None) -> int:
        """Control steps of a run of ``duration`` seconds (default ``[task] duration``), checked.

        Raises:
            ConfigError: ``duration`` is not a positive number, or the run would be longer than
                :data:`MAX_CONTROL_STEPS`.

        """
        dur = float(self.scene.config.task.duration if duration is None else duration)
        if not (math.isfinite(dur) and dur > 0):
            raise ConfigError(f"duration must be a positive number of seconds, got {duration!r}")
        T = self.control_period
        n_ctrl = max(1, int(round(dur / T)))
        if n_ctrl > MAX_CONTROL_STEPS:
            raise ConfigError(f"duration {dur:g} s is {n_ctrl:.3g} control steps of {T:g} s; at most "
                              f"{MAX_CONTROL_STEPS:.0e} per run (split a longer study into runs)")
        return n_ctrl

    # -- the loop ------------------------------------------------------------------------
    def run(self, duration: float | None = None) -> RunResult:
        """Simulate ``duration`` seconds (default ``[task] duration``) and summarise.

        Raises:
            ConfigError: ``duration`` is not a positive number.

        """
        n_ctrl = self.control_steps(duration)
        wall0 = time.perf_counter()
        T = self.control_period
        ep = self.episode(self, n_ctrl)
        phases: dict[str, Callable[..., Any]] = {name: getattr(ep, name) for name in PHASES}
        timers = PhaseTimers(phases) if self.timing else None
        sense, barriers, nominal, strategy, act = (phases[name] for name in PHASES)
        observers, recording = self.observers, bool(self.observers)
        stepwise = Observers([o for o in observers.items if not takes_blocks(o)])
        blockwise = Observers([o for o in observers.items if takes_blocks(o)])
        per_step = bool(stepwise)
        block = ep.block(min((getattr(o, "block_steps", BLOCK_STEPS) for o in blockwise.items),
                             default=BLOCK_STEPS)) if recording else None
        write, end_row = (ep.write, block.end_row) if block is not None else (None, None)
        if recording:
            observers.on_start({**self.start_info(n_ctrl * T), "data": ep.data})  # live data: a viewer can perturb it
        progress, total = self.progress, n_ctrl * T
        report = 0 if progress is not None else n_ctrl  # (the next step that reports)
        try:
            for k in range(n_ctrl):
                t = k * T
                if k == report:
                    report += PROGRESS_STEPS
                    progress(t, total)  # type: ignore[misc]
                sense(k)
                values, lie = barriers()
                u_nom = nominal(t)
                step = strategy(t, lie, u_nom)
                if block is not None:  # (the row holds the tick's state: written before the physics steps)
                    write(block, t, step, values)  # type: ignore[misc]
                act(k, step.u)
                if block is not None:
                    full = end_row(ep.true_min)  # type: ignore[misc]
                    if step.event is not None:
                        observers.on_event(step.event)
                    if per_step:
                        stepwise.on_step(block.record(block.size - 1))
                    if full:
                        block.seal()
                        try:
                            blockwise.on_steps(block)
                        finally:
                            block.clear()  # (handed on once, also when an observer fails or Ctrl-C comes)
            if block is not None and len(block) and blockwise:  # (the last steps)
                block.seal()
                try:
                    blockwise.on_steps(block)
                finally:
                    block.clear()
            result = ep.finish(time.perf_counter() - wall0, timers.totals if timers else {})
        except BaseException as exc:  # an error or Ctrl-C: observers keep what they have, marked partial
            if recording:
                if block is not None and len(block) and blockwise:
                    try:
                        block.seal()
                        blockwise.on_steps(block)  # (the steps done so far reach the partial files)
                    except Exception:  # noqa: BLE001, S110 - the run's own error is the one to report
                        pass
                observers.on_abort(exc)
            raise
        if recording:
            observers.on_finish(result.as_dict())
        return result


class _Episode:
    """The state of one run and its phases (see the module docstring)."""

    def __init__(self, sim: ArmSimulation, n_ctrl: int) -> None:
        self.sim = sim
        scene, model = sim.scene, sim.scene.model
        self.model, self.S, self.n_ctrl = model, sim.substeps, n_ctrl
        self.data = data = mujoco.MjData(model)
        data.qpos[scene.qpos_adr] = sim.setup.q0
        self.moving = len(scene.config.moving) > 0
        self.lin: np.ndarray | None = None
        if self.moving:  # the obstacles' track for the whole episode, computed once
            t_phys = np.arange(n_ctrl * self.S + 1) * sim.timestep + sim.setup.time_offset
            self.mocap_rows = scene.moving_mocap_ids
            self.track = np.zeros((t_phys.size, len(self.mocap_rows), 3))
            self.lin_all = np.zeros((n_ctrl, model.nmocap, 3))
            for j, mv in enumerate(scene.config.moving):
                pos, vel = path_track(mv.path, t_phys)
                self.track[:, j] = pos
                self.lin_all[:, self.mocap_rows[j]] = vel[: n_ctrl * self.S: self.S]
            sel = as_slice(np.asarray(self.mocap_rows))
            self._mocap_view = data.mocap_pos[sel] if type(sel) is slice else None  # (a view: cheaper to write)
            self._place(0)
        mujoco.mj_forward(model, data)
        sim.nominal.reset()
        if sim.tracker is not None:
            sim.tracker.reset(data)
        sim.strategy.reset(0.0)
        self.monitor = SafetyMonitor(sim.coll)
        self.metrics = MetricsAccumulator()
        self.track_err = np.empty(n_ctrl)
        self.min_joint = math.inf
        self.true_min = math.inf
        self.recording = bool(sim.observers)
        self.uses_rows = bool(getattr(sim.strategy, "uses_rows", True))
        nj = sim.joints.evaluate(data).k
        self._h_far_min = sim.coll.h_far_min
        self.coherence = sim.coll.coherence()  # this run's distance bounds (None: not applicable)
        self._screen_j = np.full(nj, sim.keep_joint)
        self._screen_cache: dict[int, np.ndarray] = {}
        self._step_lie, self._add_step, self._period = sim.strategy.step_lie, self.metrics.add_step, sim.control_period
        self._command = (tracking_step(sim.tracker, scene.dof_adr)  # tracking error, set_command and apply in one
                         if sim.tracker is not None else None)
        self._qpos_sel, self._dof_sel = as_slice(np.asarray(scene.qpos_adr)), as_slice(np.asarray(scene.dof_adr))
        self._ee: np.ndarray | None = None  # (a block's end-effector buffer when the arm has no site)

    # -- phases --------------------------------------------------------------------------
    def sense(self, k: int) -> None:
        """Move the obstacles to their place at the tick and run ``mj_step1``."""
        if self.moving:
            self._place(k * self.S)
            self.lin = self.lin_all[k]
        mujoco.mj_step1(self.model, self.data)

    def _place(self, i: int) -> None:
        """Put the moving obstacles where they are at physics step ``i`` of the run."""
        if self._mocap_view is not None:
            self._mocap_view[...] = self.track[i]
        else:
            self.data.mocap_pos[self.mocap_rows] = self.track[i]

    def barriers(self) -> tuple[TickValues | None, LieData | None]:
        """The tick's rows (the pairs within the cut-off, the joint limits) and its safety accounting.

        Returns the tick's barrier values for a record (``None`` when nothing records) and the Lie
        data (``None`` for a strategy without rows). ``tick_h`` keeps the tick's ``h`` (the near pairs',
        in ``monitor.rows`` order, then the joint limits') whatever the strategy.
        """
        sim = self.sim
        if self.uses_rows:  # (the rows in one pass, without the NearPairs; witness points only for a record)
            lie, idx, row_list, h_min, _, jmin, wit = sim.coll.lie_rows(
                self.data, sim.joints, self.lin, coherence=self.coherence, witness=self.recording)
            values = _new(TickValues, (idx, lie.h, wit)) if self.recording else None
            self.tick_h = lie.h
        else:
            rows = sim.coll.rows(self.data, sim.joints, self.lin, witness=self.recording, coherence=self.coherence)
            near = rows.near
            idx, row_list, h_min, jmin = near.rows, near.row_list, near.h_min, rows.joint_min
            values = _new(TickValues, (idx, rows.h, near.witness)) if self.recording else None
            lie = None
            self.tick_h = rows.h
        self.true_min = self.monitor.tick_min(min(h_min, self._h_far_min), row_list, idx)
        self.min_joint = min(self.min_joint, jmin)  # (jmin when smaller)
        return values, lie

    def nominal(self, t: float) -> np.ndarray:
        """The nominal command at the tick."""
        return self.sim.nominal(t, self.data)

    def strategy(self, t: float, lie: LieData | None, u_nom: np.ndarray) -> Any:
        """The strategy's step (screening thresholds per row: collision rows, then joint rows)."""
        if lie is None:
            step = self._step_lie(t, lie, u_nom)
        else:
            nc = lie.h.shape[0] - self._screen_j.shape[0]
            screen = self._screen_cache.get(nc)
            if screen is None:
                screen = self._screen_cache[nc] = np.concatenate(
                    (np.full(nc, self.sim.keep_collision), self._screen_j))
            step = self._step_lie(t, lie, u_nom, self.data, screen=screen)  # x: for a rollout
        self._add_step(step, self._period)
        return step

    def act(self, k: int, u: np.ndarray) -> None:
        """Track ``u`` over the control period: S physics steps, each checked for safety."""
        data, model = self.data, self.model
        command = self._command
        assert command is not None  # (a level without a tracker has an act of its own)
        self.track_err[k] = command(data, u, self.sim.control_period)
        mujoco.mj_step2(model, data)
        if self.S == 1:
            return
        bound, base = (self.true_min if self.recording else -math.inf), k * self.S
        for s in range(1, self.S):
            if self.moving:
                self._place(base + s)
            mujoco.mj_step1(model, data)
            h2 = self.monitor.substep(data, bound, self.sim.tracker)  # (then tracker.apply: one compiled call)
            if h2 < self.true_min:
                self.true_min = h2
                bound = h2 if self.recording else bound
            mujoco.mj_step2(model, data)

    # -- records and summary ---------------------------------------------------------------
    def block(self, capacity: int) -> StepColumns:
        """An empty block of ``capacity`` steps for this run's observers."""
        sim = self.sim
        goals = sim.nominal.goal_positions if isinstance(sim.nominal, ReachingController) else None
        block = StepColumns(capacity, len(sim.scene.qpos_adr), sim.names, sim.coll.pairs.k, self.model.nmocap,
                            sim.control_period, sim.coll.h_far, goals, nbody=self.model.nbody)
        self.bind(block)
        return block

    def bind(self, block: StepColumns) -> None:
        """Point ``block`` at this run's data (the end effector: its site, else a buffer :meth:`write` fills)."""
        scene = self.sim.scene
        self._ee = None if scene.ee_site_id >= 0 else np.zeros(3)
        block.bind(self.data, self._qpos_sel, self._dof_sel,
                   self.data.site_xpos[scene.ee_site_id] if self._ee is None else self._ee)

    def write(self, block: StepColumns, t: float, step: Any, values: TickValues) -> None:
        """Write the step just decided into the next row of ``block``, at the tick (before its physics steps)."""
        if self._ee is not None:
            self._ee[:] = self.sim.scene.ee_position(self.data)
        block.write(t, step, values, self.sim.nominal.goal_index)

    def finish(self, wall: float, timings: dict[str, float]) -> RunResult:
        """Account the state after the last step and summarise the run."""
        sim, model, data = self.sim, self.model, self.data
        if self.moving:
            self._place(self.n_ctrl * self.S)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        last = sim.coll.evaluate(data)
        self.monitor.tick(last.h, last.active.nonzero()[0])
        return RunResult(
            scene=sim.scene.name, filter=sim.info.name, seed=-1 if sim.seed is None else int(sim.seed),
            physics_steps=self.monitor.steps, metrics=self.metrics.result(), stats=self.metrics.stats(),
            params=sim.params, min_barrier=float(self.monitor.min_h), collisions=self.monitor.collisions,
            min_joint_barrier=float(self.min_joint), goals_reached=sim.nominal.goals_reached,
            goals_missed=sim.nominal.goals_missed, control_period=sim.control_period,
            timestep=sim.timestep, tracking_error_q99=float(np.quantile(self.track_err, 0.99)),
            wall_s=wall, timings=timings, goal_times=tuple(getattr(sim.nominal, "goal_times", ())),
            maneuvers=_maneuvers(sim.strategy),
        )


def _maneuvers(strategy: Any) -> tuple[int, int] | None:
    """``(choices, raised)`` of an intermittent filter's maneuvers by shooting, ``None`` without them."""
    shooter = getattr(strategy, "shooter", None)
    return None if shooter is None else (int(shooter.choices), int(shooter.raised))


ArmSimulation.episode = _Episode
"""The class of one run's state and phases (a subclass may add to a phase: :mod:`isf_robot.arm.multi_arm`)."""


def run_episode(
    scene: Scene,
    strategy: str = "isf",
    duration: float | None = None,
    seed: int | None = 0,
    *,
    alpha: float | None = None,
    c: float | None = None,
    b: float | None = None,
    d_bar: float | None = None,
    **kwargs: Any,
) -> RunResult:
    """Resolve the filter parameters (calibrating ``d_bar`` if needed), then run one episode.

    Keyword arguments other than the filter parameters go to :class:`ArmSimulation`.
    """
    params = kwargs.pop("params", None) or resolve_params(scene, alpha, c, b, d_bar)
    return ArmSimulation(scene, strategy, seed=seed, params=params, **kwargs).run(duration)
