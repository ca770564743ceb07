"""The arm simulation at the torque level: the paper's filters on the full dynamics.

The same loop as the velocity level (:class:`~isf_robot.arm.sim.ArmSimulation`: sense, barriers,
nominal, strategy, act; safety judged on the true geometry at every physics step), with:

* **rows**: the second-order barriers ``psi = h_dot + alpha_1 h`` of every near collision pair (the
  arm's own non-adjacent link pairs included, whatever the scene says: ``self_collision``) and
  joint limit, with their Lie data on ``q_ddot = a0 + Minv tau + d``
  (:mod:`isf_robot.arm.second_order`, :mod:`isf_robot.arm.dynamics`); a moving obstacle's part of
  ``h_dot`` is taken as approaching (``approaching=True``: a bouncing obstacle's reversal would make
  ``psi`` jump);
* **nominal**: computed torque on the velocity level's reaching command
  (:mod:`isf_robot.arm.torque_nominal`);
* **strategy**: the core's strategies, unchanged (``step_lie`` on the ``psi`` rows), with the arm's
  torque limits as input bounds; ``alpha`` is the outer class-K function of ``psi``, ``c`` and ``b``
  are in ``psi``'s units ([m/s], [m/s^2]); the predictive off trigger (``horizon``, designed as at the
  velocity level) rolls the torque nominal's closed loop forward
  (:class:`~isf_robot.arm.torque_rollout.TorqueRollout`); maneuvers by shooting (``shoot``) are the
  velocity level's only;
* **act**: the torque goes in ``qfrc_applied`` of a copy of the model with its actuators switched
  off (:func:`~isf_robot.arm.torque_calibration.torque_plant`), held over the control period.

Infeasibility: when no torque within the limits satisfies every robust condition, the arm gets
the safe fallback ``clip(M (-FALLBACK_KD q_dot) + hold)`` (damping toward rest with gravity
compensation, the torque nominal's law with a zero reference); such steps are counted in ``fallbacks``.

``d_bar`` [rad/s^2] is the torque level's own, calibrated by
:func:`~isf_robot.arm.torque_calibration.calibrate_torque_d_bar` (:func:`resolve_torque_params`);
the result's ``tracking_error_q99`` is the 99th percentile of the same model error measured in the
run (``d_bar_covered`` compares them) and ``reference_error_q99`` the velocity tracking error
``|q_dot - v_ref|`` [rad/s] of the torque nominal's reference.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import mujoco
import numpy as np

from isf_robot.core import ClassK, ConfigError, LieData, NonFiniteError, QPSolver
from isf_robot.core.jit import compiled
from isf_robot.core.strategies import make_strategy

from .dynamics import ArmDynamics, DynamicsTerms, torque_limits
from .dynamics_law import model_acceleration, model_error
from .filter_design import designed_kd
from .params import filter_options, resolve_params
from .records import FilterParams, RunResult
from .scene import Scene
from .second_order import SecondOrderRows
from .sim import ArmSimulation, _Episode
from .step_columns import TickValues
from .torque_calibration import calibrate_torque_d_bar, check_plant, inner_gain, torque_plant
from .torque_nominal import TorqueNominal, computed_torque, torque_clip, torque_peak
from .torque_rollout import TorqueRollout

__all__ = ["TorqueSimulation", "TorqueRunResult", "resolve_torque_params", "run_torque_episode", "FALLBACK_KD"]

FALLBACK_KD = 40.0
"""Gain [1/s] of the infeasibility fallback's damping toward rest (the first pass's nominal gain)."""


def resolve_torque_params(scene: Scene, alpha: float | ClassK | None = None, c: float | None = None,
                          b: float | None = None, d_bar: float | None = None, *, calibrate: bool = True,
                          plant: mujoco.MjModel | None = None, kd: float | None = None,
                          **options: Any) -> FilterParams:
    """The torque level's filter parameters: as :func:`~isf_robot.arm.params.resolve_params` (the same design).

    The designed hand-over is the nominal's ramp time alone (``servos=False``: this level drives the joints
    by torque with the actuators off, so their servo time constant does not apply).

    ``d_bar`` [rad/s^2]: the argument, else the torque calibration on ``plant`` with the torque nominal's
    gain ``kd`` (default designed; give the run's own when it sets one) (the scene's ``[filter] d_bar`` is
    the velocity level's, in [rad/s], and is not used).

    Raises:
        ConfigError: As ``resolve_params``; ``d_bar`` not given and ``calibrate`` False; a ``shoot > 0``.

    """
    if options.get("shoot"):
        raise ConfigError("maneuvers by shooting (shoot) are not available at the torque level; give shoot = 0")
    if d_bar is None and not calibrate:
        raise ConfigError(f"scene {scene.name!r}: the torque level's d_bar [rad/s^2] is not known: pass d_bar=, "
                          "or calibrate=True (runs the torque calibration)")
    p = resolve_params(scene, alpha, c, b, 0.0 if d_bar is None else d_bar, calibrate=False, servos=False,
                       **options)  # (the actuators are off: no servo lead in the hand-over)
    if d_bar is not None:
        return dataclasses.replace(p, d_bar_source="argument")
    cal = calibrate_torque_d_bar(scene, plant, alpha_1=inner_gain(p.alpha), kd=kd)
    return dataclasses.replace(p, d_bar=cal.d_bar, d_bar_source="torque calibration")


@dataclasses.dataclass(frozen=True)
class TorqueRunResult(RunResult):
    """A :class:`~isf_robot.arm.records.RunResult` of the torque level.

    Attributes:
        tau_peak_ratio: Largest ``|tau_i| / tau_max,i`` applied (<= 1: the limits held).
        reference_error_q99: 99th percentile of ``|q_dot - v_ref|`` at the ticks [rad/s].
        level: ``"torque"``.

    ``tracking_error_q99`` is the model error ``|q_ddot - (a0 + Minv tau)|`` [rad/s^2] (see the module);
    the metrics' ``intervention`` is ``integral |tau - tau_nom|^2 dt`` [N^2 m^2 s].

    """

    tau_peak_ratio: float = 0.0
    reference_error_q99: float = 0.0
    level: str = "torque"

    def as_dict(self) -> dict[str, Any]:
        """:meth:`RunResult.as_dict` with the torque level's figures."""
        return {**super().as_dict(), "level": self.level, "tau_peak_ratio": self.tau_peak_ratio,
                "reference_error_q99": self.reference_error_q99}


class TorqueSimulation(ArmSimulation):
    """One episode of an arm scene at the torque level (see the module docstring).

    Args:
        scene: The scene; its model is the filter's model of the arm.
        strategy: A registered strategy name.
        plant: The simulated arm's model (default: the scene's): give one with what the filter does not
            know (a payload, friction) to see the robust term at work. Its actuators are switched off.
        params: Resolved parameters (:func:`resolve_torque_params`); or ``alpha``, ``c``, ``b``, ``d_bar``.
        alpha_1: Inner gain of ``psi = h_dot + alpha_1 h`` [1/s]; default ``alpha``'s gain (linear alpha).
        kd: Gain of the torque nominal [1/s]; default designed from the scene
            (:func:`~isf_robot.arm.filter_design.designed_kd`). The fallback damps with :data:`FALLBACK_KD`.
        self_collision: Barriers for the arm's own non-adjacent link pairs (default True, whatever the
            scene's ``[robot] self_collision`` says; ``None``: the scene's). At the torque level a contact
            between two links of the arm is a force the filter's model has no term for, and ``d_bar`` does
            not cover it: with the scenes' ``self_collision = false`` the filter's torques pressed link7
            against link5 on panda_pole and panda_moving (model error 16.8 rad/s^2 against ``d_bar`` 0.53,
            ``h`` to -6.4 mm). The velocity level keeps the scene's setting: its low-level tracker, not the
            filter, sets the torques there.
        **kwargs: As :class:`~isf_robot.arm.sim.ArmSimulation` (``seed``, ``observers``, ``timing``, ...).

    """

    level = "torque"

    def __init__(self, scene: Scene, strategy: str = "isf", *, plant: mujoco.MjModel | None = None,
                 params: FilterParams | None = None, alpha: float | None = None, c: float | None = None,
                 b: float | None = None, d_bar: float | None = None, alpha_1: float | None = None,
                 kd: float | None = None, self_collision: bool | None = True, solver: QPSolver | None = None,
                 **kwargs: Any) -> None:
        check_plant(scene, plant)
        if params is None:
            params = resolve_torque_params(scene, alpha, c, b, d_bar, calibrate=False)
        if params.shoot:
            raise ConfigError("maneuvers by shooting (shoot) are not available at the torque level; give shoot = 0")
        if self_collision is not None and self_collision != scene.config.robot.self_collision:
            c = scene.config
            scene = dataclasses.replace(scene, config=dataclasses.replace(
                c, robot=dataclasses.replace(c.robot, self_collision=bool(self_collision))))
        self.filter_scene = scene
        self.tau_max = torque_limits(scene)
        alpha_1 = inner_gain(params.alpha) if alpha_1 is None else alpha_1
        if not (math.isfinite(alpha_1) and alpha_1 > 0):
            raise ConfigError(f"alpha_1 must be a positive number [1/s], got {alpha_1}")
        self.alpha_1, self.kd = float(alpha_1), float(designed_kd(scene.config) if kd is None else kd)
        self.terms: DynamicsTerms | None = None
        self._zero = np.zeros(scene.n_joints)
        super().__init__(dataclasses.replace(scene, model=torque_plant(scene.model if plant is None else plant)),
                         strategy, params=params, solver=solver, **kwargs)  # (builds this level's strategy last)
        self.dynamics = ArmDynamics(scene.model, scene.dof_adr, own_data=plant is not None)
        self.second_order = SecondOrderRows(self.coll, self.joints, scene.qpos_adr, self.alpha_1,
                                            self._clock if scene.config.moving else None, approaching=True)
        self.torque_nominal = TorqueNominal(self.nominal, scene.dof_adr, self.tau_max, self.control_period,
                                           self.kd)

    far_formula = "alpha_1 (cutoff - margin)"

    def far_value(self) -> float:
        """The least value of a ``psi`` row beyond the broad-phase cut-off [m/s].

        ``alpha_1 (cutoff - margin)``: ``J = 0`` there, so ``psi = alpha_1 h``.
        """
        return self.alpha_1 * super().far_value()

    def _make_tracker(self, tracker: Any) -> None:
        """No low-level tracker: this level puts its torques on the joints itself."""
        if tracker is not None:
            raise ConfigError("the torque level applies its torques itself: it takes no tracker (drop tracker=)")

    def _make_strategy(self, strategy: str, solver: QPSolver) -> Any:
        """The core's strategy on the ``psi`` rows, the torque limits as input bounds, the torque nominal's rollout."""
        spec, wiring = filter_options(self, rollout=lambda horizon: TorqueRollout(
            self.scene, self.nominal, self.coll, self.joints, self.control_period, self.setup.time_offset,
            horizon, self.kd, self.alpha_1, approaching=True))
        return make_strategy(strategy, spec, **wiring, solver=solver, u_min=-self.tau_max, u_max=self.tau_max,
                             on_infeasible="fallback", fallback=self._fallback, validate=False)

    def _clock(self, data: mujoco.MjData, t: float) -> np.ndarray:
        """Moving obstacles at run time ``t`` (their path's time ``t + time_offset``); their velocities."""
        s = self.filter_scene
        s.set_moving_obstacles(data, t + self.setup.time_offset)
        return s.mocap_velocities(t + self.setup.time_offset)[0]

    def _fallback(self, t: float, x: Any, lie: LieData, res: Any) -> np.ndarray:
        """No torque within the limits meets every condition: damp toward rest, gravity compensated."""
        assert self.terms is not None  # (set by the episode's sense phase before any strategy step)
        return computed_torque(self.terms, self._zero, self._zero, x.qvel[self.scene.dof_adr], FALLBACK_KD,
                               self.tau_max)

    def start_info(self, duration: float) -> dict[str, Any]:
        """The velocity level's start information, with the level, ``alpha_1`` and the torque limits."""
        return {**super().start_info(duration), "level": self.level, "alpha_1": self.alpha_1,
                "tau_max": self.tau_max.copy()}


class _TorqueEpisode(_Episode):
    """The phases of one torque-level run (see the module docstring)."""

    sim: TorqueSimulation

    def __init__(self, sim: TorqueSimulation, n_ctrl: int) -> None:
        super().__init__(sim, n_ctrl)
        sim.torque_nominal.reset()
        self.track_err[:] = 0.0
        self.ref_err = np.zeros(n_ctrl)
        self.tau_peak = 0.0
        self._t = 0.0
        self._last: tuple[int, np.ndarray, np.ndarray] | None = None  # (tick, q_dot, predicted q_ddot)
        self._tau = np.zeros(sim.tau_max.size)  # (act's torque)
        self._held = compiled(held_torque)  # (act's arithmetic in one call; reads ISF_ROBOT_JIT)
        self._model_error = compiled(model_error)  # (one call, not five numpy operations; reads ISF_ROBOT_JIT)
        self._qvel, self._dofs = self.data.qvel, sim.dynamics.dof  # (a view of the run's data: its joint velocities)

    def sense(self, k: int) -> None:
        """The velocity level's sense, then the model's terms (and the last period's model error)."""
        super().sense(k)
        sim = self.sim
        self._t = k * sim.control_period
        sim.terms = sim.dynamics.terms(self.data)
        self._account_model_error()

    def _account_model_error(self) -> None:
        """The last period's model error ``|(q_dot - q_dot_0) / T - (a0 + Minv tau)|`` [rad/s^2] (at the next tick)."""
        if self._last is not None:
            j, v0, pred = self._last
            self.track_err[j] = self._model_error(self._qvel, self._dofs, v0, pred, self.sim.control_period)

    def barriers(self) -> tuple[TickValues | None, LieData | None]:
        """The ``psi`` rows and the tick's safety accounting on the true geometry.

        A strategy without rows (the nominal) gets the accounting only: no ``psi``, so no difference of ``phi``.
        """
        if not self.uses_rows:
            return super().barriers()  # (the velocity level's accounting: the same pairs, no rows)
        sim = self.sim
        assert sim.terms is not None
        psi, tick = sim.second_order.tick(self.data, self._t, sim.terms, self.lin, coherence=self.coherence,
                                          witness=self.recording)
        lie, idx, row_list, h_min, _, jmin, wit = tick
        values = TickValues(idx, lie.h, wit) if self.recording else None
        self.true_min = self.monitor.tick_min(min(h_min, self._h_far_min), row_list, idx)
        self.min_joint = min(self.min_joint, jmin)
        return values, psi

    def nominal(self, t: float) -> np.ndarray:
        """The nominal torque at the tick."""
        assert self.sim.terms is not None
        return self.sim.torque_nominal(t, self.data, self.sim.terms)

    def act(self, k: int, u: np.ndarray) -> None:
        """Hold the torque ``u`` over the control period: S physics steps, each checked for safety."""
        sim, data, model, dofs, terms = self.sim, self.data, self.model, self._dof_sel, self.sim.terms
        assert terms is not None
        tau, n = self._tau, self._tau.size  # (the QP's answer is within the limits up to its tolerance: clipped)
        v, pred = np.empty(n), np.empty(n)  # (fresh: kept for the next tick's model error)
        peak, self.ref_err[k] = self._held(u, sim.tau_max, tau, self._qvel, self._dofs, sim.torque_nominal.v_ref,
                                           terms.a0, terms.minv, v, pred)
        if not math.isfinite(peak):
            raise NonFiniteError(f"torque command at t = {k * sim.control_period:g} s is not finite: {u}")
        self.tau_peak = max(self.tau_peak, float(peak))
        self._last = (k, v, pred)
        data.qfrc_applied[dofs] = tau
        mujoco.mj_step2(model, data)
        bound, base = (self.true_min if self.recording else -math.inf), k * self.S
        for s in range(1, self.S):
            if self.moving:
                self._place(base + s)
            mujoco.mj_step1(model, data)
            h2 = self.monitor.substep(data, bound)
            if h2 < self.true_min:
                self.true_min = h2
                bound = h2 if self.recording else bound
            mujoco.mj_step2(model, data)

    def finish(self, wall: float, timings: dict[str, float]) -> RunResult:
        """The velocity level's summary with the torque level's figures."""
        self._account_model_error()
        res = super().finish(wall, timings)
        fields = {f.name: getattr(res, f.name) for f in dataclasses.fields(RunResult)}
        return TorqueRunResult(**fields, tau_peak_ratio=self.tau_peak,
                               reference_error_q99=float(np.quantile(self.ref_err, 0.99)))


TorqueSimulation.episode = _TorqueEpisode  # type: ignore[misc]


def held_torque(u: np.ndarray, tau_max: np.ndarray, tau: np.ndarray, qvel: np.ndarray, dof: np.ndarray,
                v_ref: np.ndarray, a0: np.ndarray, minv: np.ndarray, v: np.ndarray,
                pred: np.ndarray) -> tuple[float, float]:
    """The act phase's arithmetic on the command ``u``: ``(peak, |q_dot - v_ref|)``; ``tau``, ``v``, ``pred`` filled.

    ``peak``: :func:`~isf_robot.arm.torque_nominal.torque_peak` of ``u``; ``tau``: ``u`` clipped to the limits
    (:func:`~isf_robot.arm.torque_nominal.torque_clip`), the torque held; ``v = qvel[dof]``, the joint velocities at
    the tick; ``pred``: the model's acceleration under ``tau``
    (:func:`~isf_robot.arm.dynamics_law.model_acceleration`). A plain function that
    :func:`~isf_robot.core.jit.compiled` compiles (one call instead of a dozen numpy operations).
    """
    peak = torque_peak(u, tau_max)
    tau[:] = torque_clip(u, tau_max)
    v[:] = qvel[dof]
    e = v - v_ref
    pred[:] = model_acceleration(a0, minv, tau)
    return peak, np.sqrt(e.dot(e))


def run_torque_episode(scene: Scene, strategy: str = "isf", duration: float | None = None, seed: int | None = 0, *,
                       alpha: float | None = None, c: float | None = None, b: float | None = None,
                       d_bar: float | None = None, plant: mujoco.MjModel | None = None,
                       **kwargs: Any) -> RunResult:
    """Resolve the torque level's parameters (calibrating ``d_bar`` if needed), then run one episode."""
    params = kwargs.pop("params", None) or resolve_torque_params(scene, alpha, c, b, d_bar, plant=plant,
                                                                 kd=kwargs.get("kd"))
    return TorqueSimulation(scene, strategy, seed=seed, params=params, plant=plant, **kwargs).run(duration)
