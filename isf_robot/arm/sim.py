"""The arm simulation loop: nominal task, safety filter, low-level tracking, MuJoCo physics.

One control step at ``t_k = k T`` (T the control period, a whole multiple of the physics
timestep dt; ``S = T / dt`` physics steps per control step)::

    mj_step1                               kinematics, M(q), bias forces at the current state
    safety check on the true geometry      (every physics step)
    barriers  h, dh/dq, dh/dt              collision pairs (cut-off) and joint limits
    u_nom = nominal(t_k)                   task-space reaching (or any NominalController)
    u     = filter(t_k, barriers, u_nom)   strategy: nominal | cbf | isf
    tracker.apply; mj_step2                torques for the held u, then S - 1 more physics steps

Strategies (DESIGN.md, section 3), on the same scene, seed and nominal task:

* ``nominal``: no filter (shows the danger); "on" never.
* ``cbf``: the standard robust safety filter (:class:`~isf_robot.core.SafetyFilter`) solved
  at every control step; the step counts as "on" when a constraint is active.
* ``isf``: the event-triggered intermittent safety filter
  (:class:`~isf_robot.core.IntermittentSafetyFilter`): off until ``min_i Xi_on,i <= 0``, then
  the safety-promoting filter until every ``Xi_on,i >= c``.

Safety is judged on the true MuJoCo geometry at every physics step (not only at control
ticks): ``min_barrier`` is the smallest ``dist - margin`` over all collision pairs and all
physics steps (signed distances from ``mj_geomDistance``), and ``collisions`` counts the
physics steps at which some pair has ``dist - margin < 0``. Pairs farther apart than the
broad-phase cut-off at a control tick are not re-checked within that control period (they
cannot close the gap in a few milliseconds), so ``min_barrier`` saturates at
``cutoff - margin`` when the arm never comes within the cut-off. Joint-limit barriers are
reported separately (``min_joint_barrier``, at control steps).

Rows handed to the filter: the collision pairs within the broad-phase cut-off and the joint
limits, minus the rows whose robust condition has a large slack under ``u_nom``
(``collision_row_slack``, ``joint_row_slack``; never below ``c``, so a left-out row is never
promoted and never decides a switch). Left-out rows are checked at the QP's solution; if one is
violated or active the QP is solved again with every row (``resolves``), so the pruning only
saves time and never changes a command.

If the filter's QP is infeasible even with every promotion relaxed, the arm brakes
(``u = 0``); such steps are counted in ``fallbacks`` and never hidden.

Observers (:class:`isf_robot.core.Observer`) receive ``on_start(info)``, ``on_step`` with an
:class:`ArmStepRecord` per control step, ``on_event`` per :class:`~isf_robot.core.SwitchEvent`
and ``on_finish(summary)``. Records are built only when an observer is attached.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Iterable
from typing import Any

import mujoco
import numpy as np

from isf_robot.core import (
    ConfigError,
    IntermittentSafetyFilter,
    LieData,
    MetricsAccumulator,
    NonFiniteError,
    Observer,
    Observers,
    QPSolver,
    SafetyFilter,
    SwitchEvent,
    UnknownNameError,
)

from .barriers import CollisionBarriers, JointLimitBarriers
from .episode import EpisodeSetup, check_control_period, episode_setup, path_track
from .lowlevel import VelocityTracker
from .nominal import NominalController, ReachingController
from .records import ArmStepRecord, FilterParams, RunResult
from .scene import Scene

__all__ = [
    "STRATEGIES",
    "ArmStepRecord",
    "RunResult",
    "FilterParams",
    "ArmSimulation",
    "EpisodeSetup",
    "episode_setup",
    "run_episode",
    "check_control_period",
    "path_track",
]

STRATEGIES: tuple[str, ...] = ("nominal", "cbf", "isf")


class _SafetyMonitor:
    """True-geometry clearance of the collision pairs, checked at every physics step.

    At a control tick the collision barriers have just been evaluated: their ``h`` is the
    exact ``dist - margin`` of every pair within the cut-off (``mj_geomDistance``), and every
    other pair is at least ``cutoff - margin`` away. At the other physics steps of the control
    step, ``mj_geomDistance`` is called for the pairs that were within the cut-off at the tick,
    with ``distmax`` just above what could change the running minimum or count a collision (a
    pair beyond the cut-off, e.g. 0.25 m, cannot close that gap within one control period).
    So ``min_h`` is exact whenever it is below ``cutoff - margin`` and saturates there when
    the arm never comes within the cut-off.
    """

    def __init__(self, coll: CollisionBarriers) -> None:
        p = coll.pairs
        self.model = coll.model
        self.g1l, self.g2l = p.geom1.tolist(), p.geom2.tolist()
        self.marginl = p.margin.tolist()
        self.min_h = math.inf
        self.collisions = 0
        self.steps = 0
        self.rows: list[int] = []

    def tick(self, h: np.ndarray, rows: np.ndarray, margin: np.ndarray) -> float:
        """Account the tick's barrier values; return the smallest true distance [m] (inf: none).

        Args:
            h: Collision barrier values at the tick, shape (k,).
            rows: Indices of the pairs within the cut-off.
            margin: Margin per pair [m], shape (k,).

        """
        self.steps += 1
        self.rows = rows.tolist()
        hmin = float(h.min())
        if hmin < 0.0:
            self.collisions += 1
        if hmin < self.min_h:
            self.min_h = hmin
        if not self.rows:
            return math.inf
        return float((h[rows] + margin[rows]).min())

    def substep(self, data: mujoco.MjData, bound: float = -math.inf) -> float:
        """Check the pairs near at the last tick; return their smallest distance.

        Args:
            data: The MuJoCo data after ``mj_step1``.
            bound: Distances at or above ``bound`` [m] need not be exact (pass the control
                step's running minimum distance to get that minimum exactly, ``-inf`` when
                only the run's minimum barrier and the collision count matter). Each pair's
                ``distmax`` is the larger of that and what could change the running minimum
                barrier or count a collision, so ``mj_geomDistance`` can stop early.

        Returns:
            The smallest distance found [m]: exact when below ``bound``, otherwise a value
            at or above ``bound`` (or ``inf`` when no pair is near).

        """
        self.steps += 1
        rows = self.rows
        if not rows:
            return math.inf
        m, g1, g2, marg = self.model, self.g1l, self.g2l, self.marginl
        thresh = max(self.min_h, 0.0)
        step_h = math.inf
        step_d = math.inf
        for i in rows:
            cap = max(thresh + marg[i], bound) + 1e-6
            d = mujoco.mj_geomDistance(m, data, g1[i], g2[i], cap, None)
            if d - marg[i] < step_h:
                step_h = d - marg[i]
            if d < step_d:
                step_d = d
        if step_h < 0.0:
            self.collisions += 1
        if step_h < self.min_h:
            self.min_h = step_h
        return step_d


class _Timer:
    """Accumulates wall time per phase (a no-op when disabled)."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.totals: dict[str, float] = {}

    def add(self, key: str, seconds: float) -> None:
        self.totals[key] = self.totals.get(key, 0.0) + seconds


# ----------------------------------------------------------------------------- simulation


class ArmSimulation:
    """One episode of an arm scene under a strategy.

    Args:
        scene: The scene.
        strategy: ``"nominal"``, ``"cbf"`` or ``"isf"``.
        seed: Episode seed (initial configuration, goal jitter, obstacle phase; see
            :func:`episode_setup`). ``None``: the scene exactly as configured.
        nominal: The nominal controller; default a :class:`ReachingController` through the
            (seeded) goals.
        tracker: The low-level controller; default :class:`VelocityTracker` with the scene's
            gains.
        alpha: Class-K gain [1/s]; default ``[filter] alpha``.
        c: Off-trigger margin; default ``[filter] c``.
        b: Promotion rate; default ``[filter] b``.
        d_bar: Tracking-error bound [rad/s]; default ``[filter] d_bar`` when positive, else
            the calibrated bound (:func:`isf_robot.arm.calibration.calibrate_d_bar`).
        control_period: Control period [s]; default ``[control] period``. Must be a whole
            multiple of the model timestep.
        observers: Observers called during :meth:`run`.
        timing: Accumulate wall time per phase (physics, safety check, barriers, nominal,
            trigger, QP) into ``RunResult.timings``.
        solver: QP solver for the filters (default ProxQP at eps_abs 1e-9).
        joint_row_slack: Joint-limit rows whose robust condition has at least this slack
            under ``u_nom`` [rad/s] are left out of the QP (and checked at its solution; a
            violated or active one makes the QP be solved again with every row). Default
            ``max(c, 0.5)``; ``inf`` keeps every row. The threshold is never below ``c``, so
            a left-out row can neither be promoted nor decide a switch.
        collision_row_slack: The same for the collision pairs within the cut-off [m/s];
            default ``max(c, 0.1)``.
        fast_off: For ``isf``: while the filter is off and every
            ``Xi_on`` (computed here for the row pruning, same formula) is positive, do not
            call the filter (its step would return ``u_nom`` with no switch and no QP). Step
            records then carry the rows' own ``min Xi_on``.

    Raises:
        UnknownNameError: Unknown strategy (the message lists the valid ones).
        ConfigError: Invalid parameters.

    """

    def __init__(
        self,
        scene: Scene,
        strategy: str = "isf",
        *,
        seed: int | None = 0,
        nominal: NominalController | None = None,
        tracker: VelocityTracker | None = None,
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
        fast_off: bool = True,
    ) -> None:
        if strategy not in STRATEGIES:
            raise UnknownNameError("strategy", strategy, STRATEGIES)
        self.scene = scene
        self.strategy = strategy
        self.seed = seed
        model = scene.model
        self.timestep = float(model.opt.timestep)
        self.control_period = float(scene.config.control.period if control_period is None
                                    else control_period)
        self.substeps = check_control_period(self.control_period, self.timestep)
        self.setup = (episode_setup(scene, seed) if seed is not None else
                      EpisodeSetup(scene.home.copy(), scene.goal_positions.copy(), 0.0))
        self.nominal = nominal if nominal is not None else ReachingController(
            scene, goals=self.setup.goals)
        if self.nominal.n != scene.n_joints:
            raise ConfigError(f"nominal controller has {self.nominal.n} joints, the scene "
                              f"{scene.n_joints}")
        self.tracker = tracker if tracker is not None else VelocityTracker(scene)
        self.params = self._resolve_params(alpha, c, b, d_bar)
        self.coll = CollisionBarriers.from_scene(scene)
        self.joints = JointLimitBarriers.from_scene(scene)
        self.names = self.coll.names + self.joints.names
        # joint and sign of each joint-limit row (its gradient is +-e_j)
        jgrad = self.joints.evaluate(scene.make_data()).grad
        self._jidx = np.argmax(np.abs(jgrad), axis=1) if jgrad.size else np.zeros(0, int)
        self._jsign = (jgrad[np.arange(jgrad.shape[0]), self._jidx] if jgrad.size
                       else np.zeros(0))
        self.observers = Observers(observers)
        self.fast_off = bool(fast_off)
        self.joint_row_slack = 0.5 if joint_row_slack is None else float(joint_row_slack)
        self.collision_row_slack = (max(self.params.c, 0.1) if collision_row_slack is None
                                    else max(self.params.c, float(collision_row_slack)))
        self.joint_row_slack = max(self.params.c, self.joint_row_slack)
        if not (self.joint_row_slack > 0 and self.collision_row_slack > 0):
            raise ConfigError("joint_row_slack and collision_row_slack must be > 0")
        self.timing = bool(timing)
        p = self.params
        cutoff_h = float(np.min(self.coll.cutoff - self.coll.pairs.margin))
        if strategy == "isf" and p.alpha * cutoff_h < p.c:
            raise ConfigError(
                f"alpha * (cutoff - margin) = {p.alpha * cutoff_h:.3g} < c = {p.c}: pairs beyond "
                "the broad-phase cut-off would keep the intermittent filter on; raise the cut-off")
        solver = solver if solver is not None else QPSolver()
        self.filter: SafetyFilter | IntermittentSafetyFilter | None
        if strategy == "cbf":
            self.filter = SafetyFilter(p.alpha, p.d_bar, solver=solver, on_infeasible="fallback",
                                       fallback=self._brake, validate=False)
        elif strategy == "isf":
            self.filter = IntermittentSafetyFilter(p.alpha, p.c, p.b, p.d_bar, solver=solver,
                                                   on_infeasible="fallback", fallback=self._brake,
                                                   validate=False)
        else:
            self.filter = None

    # -- parameters ----------------------------------------------------------------------
    def _resolve_params(self, alpha: float | None, c: float | None, b: float | None,
                        d_bar: float | None) -> FilterParams:
        fc = self.scene.config.filter
        a = float(fc.alpha if alpha is None else alpha)
        cc = float(fc.c if c is None else c)
        bb = float(fc.b if b is None else b)
        for label, v in (("alpha", a), ("c", cc), ("b", bb)):
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"filter parameter {label} must be > 0, got {v}")
        if d_bar is not None:
            if not (math.isfinite(d_bar) and d_bar >= 0):
                raise ConfigError(f"d_bar must be >= 0 [rad/s], got {d_bar}")
            return FilterParams(a, cc, bb, float(d_bar), "argument")
        if fc.d_bar > 0:
            return FilterParams(a, cc, bb, float(fc.d_bar), "config")
        from .calibration import calibrate_d_bar

        return FilterParams(a, cc, bb, calibrate_d_bar(self.scene).d_bar, "calibration")

    @staticmethod
    def _brake(t: float, x: Any, lie: LieData, res: Any) -> np.ndarray:
        """Fallback when no command satisfies the safety constraints: stop (u = 0)."""
        return np.zeros(lie.m)

    # -- the loop ------------------------------------------------------------------------
    def run(self, duration: float | None = None) -> RunResult:
        """Simulate ``duration`` seconds (default ``[task] duration``) and summarise.

        Raises:
            ConfigError: ``duration`` is not a positive number.

        """
        dur = float(self.scene.config.task.duration if duration is None else duration)
        if not (math.isfinite(dur) and dur > 0):
            raise ConfigError(f"duration must be a positive number of seconds, got {duration!r}")
        scene, model = self.scene, self.scene.model
        T, dt, S = self.control_period, self.timestep, self.substeps
        n_ctrl = max(1, int(round(dur / T)))
        observers = self.observers
        recording = bool(observers)
        timing = self.timing
        tm = _Timer(timing)
        perf = time.perf_counter

        wall0 = perf()
        data = mujoco.MjData(model)
        data.qpos[scene.qpos_adr] = self.setup.q0
        moving = len(scene.config.moving) > 0
        off = self.setup.time_offset
        if moving:  # the obstacles' track for the whole episode, computed once
            t_phys = np.arange(n_ctrl * S + 1) * dt + off
            mocap_rows = scene.moving_mocap_ids
            mocap_track = np.zeros((t_phys.size, len(mocap_rows), 3))
            lin_all = np.zeros((n_ctrl, model.nmocap, 3))
            for j, mv in enumerate(scene.config.moving):
                pos, vel = path_track(mv.path, t_phys)
                mocap_track[:, j] = pos
                lin_all[:, mocap_rows[j]] = vel[: n_ctrl * S : S]
            data.mocap_pos[mocap_rows] = mocap_track[0]
        mujoco.mj_forward(model, data)
        self.nominal.reset()
        self.tracker.reset(data)
        flt = self.filter
        if isinstance(flt, IntermittentSafetyFilter):
            flt.reset(0.0)
        monitor = _SafetyMonitor(self.coll)
        margins = self.coll.pairs.margin
        metrics = MetricsAccumulator()
        coll, joints, nominal, tracker = self.coll, self.joints, self.nominal, self.tracker
        cnames, jnames = self.coll.names, self.joints.names
        strategy = self.strategy
        need_barriers = flt is not None or recording  # joint barriers (cb is always needed)
        need_rows = flt is not None
        dofs = scene.dof_adr
        min_joint = math.inf
        fallbacks = relaxations = resolves = 0
        alpha, d_bar = self.params.alpha, self.params.d_bar
        keep_j = self.joint_row_slack
        keep_c = self.collision_row_slack
        ones = np.ones(max(1, self.joints.evaluate(data).k))
        active_tol = flt.solver.active_tol if flt is not None else 0.0
        jidx, jsign = self._jidx, self._jsign
        fast_off = self.fast_off and strategy == "isf"
        skip = False
        name_cache: dict[tuple[bytes, bytes], tuple[str, ...]] = {}
        qp_times: list[float] = []
        proxqp_times: list[float] = []
        closed_form = 0
        track_err = np.empty(n_ctrl)
        prev_on = False
        n_on = n_off = 0
        t_switch: float | None = None

        if recording:
            observers.on_start({
                "scene": scene.name, "model_path": str(scene.xml_path),
                "config_path": str(scene.config.source) if scene.config.source else None,
                "strategy": strategy, "seed": self.seed, "dt": dt, "control_period": T,
                "duration": n_ctrl * T, "names": self.names, "joint_names": scene.joint_names,
                "n_collision": coll.pairs.k, "goals": getattr(nominal, "goal_positions", None),
                "alpha": self.params.alpha, "c": self.params.c, "b": self.params.b,
                "d_bar": self.params.d_bar,
            })

        lin = None
        for k in range(n_ctrl):
            t = k * T
            base = k * S
            # -- first physics step of the control step: sense, decide, act
            t0 = perf() if timing else 0.0
            if moving:
                data.mocap_pos[mocap_rows] = mocap_track[base]
                lin = lin_all[k]
            mujoco.mj_step1(model, data)
            if timing:
                t1 = perf()
                tm.add("physics", t1 - t0)
            cb = coll.evaluate(data, lin)
            act = cb.active.nonzero()[0]
            dmin = monitor.tick(cb.h, act, margins)
            if timing:
                t2 = perf()
            u_nom = nominal(t, data)
            if timing:
                t3 = perf()
                tm.add("nominal", t3 - t2)
            if need_barriers:
                jb = joints.evaluate(data)
                if need_rows:  # the filter's rows (a nominal run only logs h)
                    # Rows for the filter: collision pairs within the cut-off and joint limits
                    # whose robust condition has a slack below the keep threshold under u_nom
                    # (>= c, so a left-out row is never promoted nor decides a switch). The
                    # left-out rows are checked at the solution below; if one is violated or
                    # active, the QP is solved again with every row, so the pruning never
                    # changes the answer.
                    ch, cg, cd = cb.h[act], cb.grad[act], cb.dhdt[act]
                    cn = np.sqrt(np.einsum("ij,ij->i", cg, cg))
                    cxi = cg @ u_nom
                    cxi += cd
                    cxi += alpha * ch
                    cxi -= cn * d_bar
                    ckeep = (cxi < keep_c).nonzero()[0]
                    jxi = u_nom[jidx]
                    jxi *= jsign
                    jxi += alpha * jb.h
                    jkeep = (jxi < keep_j + d_bar).nonzero()[0]
                    if not math.isfinite(float(cxi.sum()) + float(jxi.sum())):
                        # the filter is built with validate=False: this check stands in for it
                        raise NonFiniteError(
                            f"barrier data or nominal command not finite at t={t:.6g} "
                            f"(scene {scene.name}, strategy {strategy}); u_nom = {u_nom}")
                    # Off and every Xi_on > 0: the intermittent filter's step would only pass
                    # u_nom through (no switch, no QP), so it is not called.
                    skip = (fast_off and not flt.on  # type: ignore[union-attr]
                            and (cxi.size == 0 or float(cxi.min()) > 0.0)
                            and (jxi.size == 0 or float(jxi.min()) - d_bar > 0.0))
            if need_rows and not skip:
                if ckeep.size == 0 and jkeep.size == 0:
                    if act.size:
                        ckeep = np.array([int(np.argmin(cxi))])
                    elif jb.k:
                        jkeep = np.array([int(np.argmin(jxi))])
                pruned = ckeep.size < act.size or jkeep.size < jb.k
                crows = act[ckeep]
                key = (crows.tobytes(), jkeep.tobytes())
                lnames = name_cache.get(key)
                if lnames is None:
                    lnames = (tuple(cnames[i] for i in crows.tolist())
                              + tuple(jnames[i] for i in jkeep.tolist()))
                    name_cache[key] = lnames
                lie = LieData(np.concatenate((ch[ckeep], jb.h[jkeep])),
                              np.concatenate((cd[ckeep], jb.dhdt[jkeep])),
                              np.concatenate((cg[ckeep], jb.grad[jkeep])),
                              np.concatenate((cn[ckeep], ones[:jkeep.size])), lnames)
            if need_barriers:
                jmin = float(jb.h.min()) if jb.k else math.inf
                if jmin < min_joint:
                    min_joint = jmin
            if timing:
                t4 = perf()
                tm.add("barriers", (t4 - t3) + (t2 - t1))  # with the tick's safety accounting
            qd = data.qvel[dofs]
            if flt is None or skip:
                u = u_nom
                on = False
                step = None
                metrics.add(t, T, False, u, u_nom, False)
            else:
                step = flt.step_lie(t, lie, u_nom)
                qp_time = step.qp.solve_time_s if step.qp is not None else 0.0
                if step.qp is not None and pruned:
                    u_f = step.u
                    sc = cg @ u_f
                    sc += cd
                    sc += alpha * ch
                    sc -= cn * d_bar
                    sj = u_f[jidx]
                    sj *= jsign
                    sj += alpha * jb.h
                    sj -= d_bar
                    sc[ckeep] = np.inf
                    sj[jkeep] = np.inf
                    if (sc.size and sc.min() < active_tol) or (sj.size and sj.min() < active_tol):
                        resolves += 1
                        key = (act.tobytes(), b"all")
                        fnames = name_cache.get(key)
                        if fnames is None:
                            fnames = tuple(cnames[i] for i in act.tolist()) + jnames
                            name_cache[key] = fnames
                        full = LieData(np.concatenate((ch, jb.h)), np.concatenate((cd, jb.dhdt)),
                                       np.concatenate((cg, jb.grad)),
                                       np.concatenate((cn, ones[:jb.k])), fnames)
                        again = flt.step_lie(t, full, u_nom)
                        step = dataclasses.replace(again, event=step.event)
                        qp_time += step.qp.solve_time_s if step.qp is not None else 0.0
                u, on = step.u, step.on
                metrics.add_step(step, T)
                if step.qp is not None:
                    qp_times.append(qp_time)
                    if step.qp.status == "closed_form":
                        closed_form += 1
                    else:
                        proxqp_times.append(qp_time)
                if step.fallback:
                    fallbacks += 1
                if step.relaxed:
                    relaxations += 1
            e = qd - tracker.u
            track_err[k] = math.sqrt(float(e @ e))
            tracker.set_command(u, T)
            if timing:
                t5 = perf()
                tm.add("filter", t5 - t4)
                if step is not None and step.qp is not None:
                    tm.add("qp", qp_time)
            tracker.apply(data)
            mujoco.mj_step2(model, data)
            if timing:
                tm.add("physics", perf() - t5)
            # -- the remaining physics steps hold u
            for s in range(1, S):
                if timing:
                    t6 = perf()
                if moving:
                    data.mocap_pos[mocap_rows] = mocap_track[base + s]
                mujoco.mj_step1(model, data)
                if timing:
                    t7 = perf()
                d2 = monitor.substep(data, dmin if recording else -math.inf)
                if timing:
                    t8 = perf()
                if d2 < dmin:
                    dmin = d2
                tracker.apply(data)
                mujoco.mj_step2(model, data)
                if timing:
                    t9 = perf()
                    tm.add("physics", (t7 - t6) + (t9 - t8))
                    tm.add("safety_check", t8 - t7)

            # -- events and records
            event = step.event if step is not None else None
            if step is not None and strategy == "cbf" and on != prev_on:
                if on:
                    n_on += 1
                else:
                    n_off += 1
                event = SwitchEvent(t, "on" if on else "off", step.xi_min,
                                    n_on if on else n_off,
                                    None if t_switch is None else t - t_switch)
                t_switch = t
            prev_on = on
            if recording:
                if event is not None:
                    observers.on_event(event)
                if skip:  # the filter was not called: its Xi_on values are the rows' own
                    xi_rec = min(float(cxi.min()) if cxi.size else math.inf,
                                 float(jxi.min()) - d_bar if jxi.size else math.inf)
                else:
                    xi_rec = step.xi_min if step is not None else math.inf
                observers.on_step(self._record(data, t, T, u, u_nom, on, step, event, cb, jb,
                                               dmin, xi_rec))

        # the state after the last step
        if moving:
            data.mocap_pos[mocap_rows] = mocap_track[n_ctrl * S]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        last = coll.evaluate(data)
        monitor.tick(last.h, last.active.nonzero()[0], margins)
        wall = perf() - wall0

        mres = metrics.result()
        q99 = float(np.quantile(track_err, 0.99)) if n_ctrl else 0.0
        timings = {k: v for k, v in tm.totals.items()} if timing else {}
        if timing:
            timings["trigger"] = timings.get("filter", 0.0) - timings.get("qp", 0.0)
        p = self.params
        result = RunResult(
            scene=scene.name, filter=strategy, seed=-1 if self.seed is None else int(self.seed),
            duration_s=mres.duration_s, control_steps=mres.control_steps,
            physics_steps=monitor.steps, duty_cycle=mres.duty_cycle,
            on_switches=mres.on_switches, off_switches=mres.off_switches,
            mean_on_s=mres.mean_on_s, min_on_s=mres.min_on_s, mean_off_s=mres.mean_off_s,
            min_off_s=mres.min_off_s, max_off_s=mres.max_off_s,
            intervention=mres.intervention, qp_solves=mres.qp_solves,
            min_barrier=float(monitor.min_h), collisions=monitor.collisions,
            min_joint_barrier=float(min_joint) if math.isfinite(min_joint) else float(
                np.min(joints.evaluate(data).h)) if joints.names else math.inf,
            goals_reached=nominal.goals_reached, goals_missed=nominal.goals_missed,
            fallbacks=fallbacks, relaxations=relaxations, resolves=resolves,
            d_bar=p.d_bar, d_bar_source=p.d_bar_source, alpha=p.alpha, c=p.c, b=p.b,
            control_period=T, timestep=dt, tracking_error_q99=q99,
            qp_time_median_us=float(np.median(qp_times)) * 1e6 if qp_times else None,
            qp_closed_form=closed_form,
            proxqp_time_median_us=(float(np.median(proxqp_times)) * 1e6 if proxqp_times
                                   else None),
            wall_s=wall, timings=timings,
        )
        self.metrics = metrics
        self.data = data
        if recording:
            observers.on_finish(result.as_dict())
        return result

    def _record(self, data: mujoco.MjData, t: float, T: float, u: np.ndarray,
                u_nom: np.ndarray, on: bool, step: Any, event: SwitchEvent | None, cb: Any,
                jb: Any, dmin: float, xi_min: float) -> ArmStepRecord:
        scene = self.scene
        h = np.concatenate((cb.h, jb.h))
        order = np.argsort(cb.h)[:3].tolist()
        act = np.flatnonzero(cb.active)
        nominal = self.nominal
        gi = nominal.goal_index
        goal = (nominal.goal_positions[gi].copy() if isinstance(nominal, ReachingController)
                else np.full(3, np.nan))
        return ArmStepRecord(
            t=t, dt=T, q=data.qpos[scene.qpos_adr], qd=data.qvel[scene.dof_adr],  # fancy indexing copies
            u=np.array(u, dtype=float), u_nom=np.array(u_nom, dtype=float), on=bool(on),
            h_min=float(h.min()), xi_min=xi_min,
            dist_min=float(dmin), qp_solved=step is not None and step.qp is not None, h=h,
            names=self.names, closest=tuple(cb.names[i] for i in order),
            witness=cb.witness[act], witness_names=tuple(cb.names[i] for i in act.tolist()),
            mocap_pos=data.mocap_pos.copy(), mocap_quat=data.mocap_quat.copy(),
            ee_pos=data.site_xpos[scene.ee_site_id].copy(), goal_index=gi, goal_pos=goal,
            event=event,
            fallback=bool(step.fallback) if step is not None else False,
            relaxed=tuple(step.relaxed) if step is not None else (),
        )


def run_episode(
    scene: Scene,
    strategy: str = "isf",
    duration: float | None = None,
    seed: int | None = 0,
    **kwargs: Any,
) -> RunResult:
    """Build an :class:`ArmSimulation` and run it once (keyword arguments as its constructor)."""
    return ArmSimulation(scene, strategy, seed=seed, **kwargs).run(duration)

