"""Arms sharing a workspace: a run of a scene with several arms, filtered centrally or per arm.

A scene with ``[[arm]]`` tables is one robot for the single-arm loop (:class:`~isf_robot.arm.ArmSimulation`):
its joints are every arm's joints, its collision pairs the arm-obstacle pairs and the inter-arm pairs
(geoms of two different arms: both bodies move, so each row holds both arms' Jacobians, as a
self-collision row does; :mod:`isf_robot.arm.pairs`). What this module adds:

* :class:`~isf_robot.arm.team_nominal.TeamReaching` (the default nominal): each arm's
  :class:`~isf_robot.arm.nominal.ReachingController` through its own goals, the commands stacked.
* :class:`MultiArmSimulation`: the loop with a *coordination*: ``central`` (one filter over every arm's
  joints, :class:`~isf_robot.core.team.CentralFilter`) or ``decentral`` (one filter per arm with its
  share of each inter-arm row, :class:`~isf_robot.core.team.SharedFilter`; the share and the safety
  argument are in :mod:`isf_robot.core.team`). Both build their filters with the core's
  :func:`~isf_robot.core.strategies.make_strategy`, so ``cbf`` and ``isf`` (and ``nominal``) work either way.
* Per-arm figures (:meth:`MultiArmSimulation.arm_results`): duty cycle, switches, off periods,
  intervention, goals, coordination steps and events, and the run's smallest clearance and
  penetrating contacts by kind (arm-arm, arm-obstacle, self).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from isf_robot.core import ConfigError, LieData, QPSolver, UnknownNameError
from isf_robot.core.shares import SharedRows
from isf_robot.core.strategies import make_strategy
from isf_robot.core.team import CentralFilter, SharedFilter

from .arms import geom_arms
from .episode import episode_setup
from .nominal import NominalController
from .params import filter_options
from .records import RunResult
from .scene import Scene
from .sim import ArmSimulation, _brake
from .step_columns import TickValues
from .team_columns import TeamStepColumns
from .team_nominal import TeamReaching

__all__ = ["COORDINATIONS", "TeamReaching", "MultiArmSimulation", "ArmRunResult", "run_team"]

CLEARANCE_KINDS = ("arm-arm", "arm-obstacle", "self")
"""The kinds of pairs a team run reports by: between two arms, an arm and an obstacle, an arm's own links."""

COORDINATIONS = {
    "central": "one filter over every arm's joints (inter-arm rows solved together)",
    "decentral": "one filter per arm; each takes an equal share of every inter-arm row",
}
"""How the arms of a scene are filtered: name -> one line for ``--help``."""

OFF_HOLD_S = 0.1
"""An intermittent team filter switches off only after its off condition has held this long [s] (the trigger's
``off_hold``, :class:`~isf_robot.core.triggers.OnOffTrigger`), unless the parameters say otherwise."""


class _ArmRollout:
    """Arm ``i``'s view of the team's rollout: each point's rows as :func:`~isf_robot.core.shares.agent_lie` makes them.

    The arms share one rollout per control step (the first arm to ask runs it), and one :class:`SharedRows`
    (``shared_rows``; its own when not given): each point's rows are looked at once for all arms. The compiled
    rollout's stacked points are split for every arm and point in one call (:meth:`SharedRows.split_points`): each
    arm gets stacked points, which its predictor reads in one pass; other points are split point by point.
    """

    def __init__(self, rollout: Any, cache: dict[str, Any], blocks: tuple[slice, ...], i: int,
                 shared_rows: SharedRows | None = None) -> None:
        self.rollout, self.cache, self.blocks, self.i = rollout, cache, blocks, i
        self.shared_rows = SharedRows(blocks) if shared_rows is None else shared_rows

    def __call__(self, t: float, x: Any) -> list[tuple[float, LieData, np.ndarray]]:
        cache = self.cache
        if cache.get("t") != t or cache.get("x") is not x:  # (x: the episode's data; a new run, new data)
            points = self.rollout(t, x)
            cache.update(t=t, x=x, points=points, split=None, agents=self.shared_rows.split_points(points))
        agents = cache["agents"]
        if agents is not None:  # (the compiled rollout's stacked points: every arm's, split in one call)
            return agents[self.i]
        split = cache["split"]
        if split is None:  # (every arm's rows of every point, in one pass per point: the first arm to ask)
            points = cache["points"] = list(cache["points"])
            split = cache["split"] = [self.shared_rows(lie).split(lie) for _, lie, _ in points]
        b, i = self.blocks[self.i], self.i
        return [(s, subs[i], np.asarray(u)[b]) for (s, _, u), subs in zip(cache["points"], split)]


class _TeamEpisode(ArmSimulation.episode):  # type: ignore[name-defined,misc,valid-type]
    """The run's phases, plus the clearance by kind at each tick and penetrating contacts by kind."""

    def __init__(self, sim: MultiArmSimulation, n_ctrl: int) -> None:
        super().__init__(sim, n_ctrl)
        self.contacts = {kind: 0 for kind in CLEARANCE_KINDS}
        self._arm_of = sim.geom_arm
        self._obstacle = np.zeros(sim.scene.model.ngeom, dtype=bool)
        self._obstacle[sim.scene.obstacle_geom_ids] = True
        pairs = sim.coll.pairs
        a1, a2 = self._arm_of[pairs.geom1], self._arm_of[pairs.geom2]
        both = (a1 >= 0) & (a2 >= 0)
        self._pair_kind = np.where(both, np.where(a1 != a2, 0, 2), 1)  # (an index of CLEARANCE_KINDS per pair)
        self._pair_min = np.full(pairs.k, math.inf)  # (each pair's smallest barrier value at the ticks so far)
        sim.last_episode = self

    def sense(self, k: int) -> None:
        super().sense(k)
        data = self.data
        if not data.ncon or not (data.contact.dist < 0.0).any():  # (mj_step1 ran the collision detection)
            return
        for c in range(data.ncon):  # (the contacts that penetrate)
            con = data.contact[c]
            if con.dist >= 0.0:
                continue
            a1, a2 = self._arm_of[con.geom1], self._arm_of[con.geom2]
            if a1 >= 0 and a2 >= 0:
                self.contacts["self" if a1 == a2 else "arm-arm"] += 1
            elif (a1 >= 0 and self._obstacle[con.geom2]) or (a2 >= 0 and self._obstacle[con.geom1]):
                self.contacts["arm-obstacle"] += 1

    def block(self, capacity: int) -> TeamStepColumns:
        """An empty block of ``capacity`` steps with each arm's columns (:class:`TeamStepColumns`)."""
        sim = self.sim
        block = TeamStepColumns(capacity, len(sim.scene.qpos_adr), sim.names, sim.coll.pairs.k, self.model.nmocap,
                                sim.control_period, sim.arm_names, sim.coll.h_far, sim.nominal.goal_positions,
                                nbody=self.model.nbody)
        self.bind(block)
        block.bind_arms(self.data.site_xpos, [a.ee_site_id for a in sim.scene.arms],
                        [c.goal_positions for c in sim.nominal.arms])  # (a TeamReaching: __init__ refuses others)
        return block

    def write(self, block: Any, t: float, step: Any, values: TickValues) -> None:
        """The step's row, then each arm's mode, end effector and goal."""
        super().write(block, t, step, values)
        sim = self.sim
        block.write_arms(sim.strategy.agent_modes(), [c.goal_index for c in sim.nominal.arms])

    def barriers(self) -> tuple[Any, LieData | None]:
        values, lie = super().barriers()
        monitor = self.monitor
        if len(monitor.rows):  # (every strategy, the nominal's too: tick_h holds the pairs within the cut-off first)
            rows = monitor.rows_array()  # (each pair once)
            pm = self._pair_min
            pm[rows] = np.minimum(pm[rows], self.tick_h[:rows.size])
        return values, lie

    @property
    def kind_min(self) -> dict[str, float]:
        """Smallest barrier value at the control ticks so far, by kind of pair (:data:`CLEARANCE_KINDS`) [m]."""
        kinds = self._pair_kind
        return {kind: float(self._pair_min[kinds == i].min(initial=math.inf))
                for i, kind in enumerate(CLEARANCE_KINDS)}


@dataclasses.dataclass(frozen=True)
class ArmRunResult:
    """A run of a scene with several arms: the team's result and each arm's figures.

    Attributes:
        run: The whole run (every joint; safety over every pair at every physics step).
        coordination: ``central`` or ``decentral``.
        arms: Per arm: name, duty cycle, switches, off periods, intervention (over its own joints), goals,
            coordination steps and events. Centrally filtered, the duty, switches and off periods are the one
            filter's (the same for every arm); per arm, they are the arm's own filter's.
        clearance: Smallest barrier value at the control ticks by kind (``arm-arm``, ``arm-obstacle``, ``self``:
            an arm's own link pairs) [m]; ``inf`` when no pair of that kind came within the cut-off.
        contacts: Penetrating MuJoCo contacts at the control ticks by kind (``arm-arm``, ``arm-obstacle``, ``self``).

    """

    run: RunResult
    coordination: str
    arms: tuple[dict[str, Any], ...]
    clearance: dict[str, float]
    contacts: dict[str, int]

    @property
    def violations(self) -> int:
        """Physics steps with a pair below its margin, plus penetrating contacts of any kind."""
        return int(self.run.collisions) + sum(self.contacts.values())

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready)."""
        return {"coordination": self.coordination, "arms": list(self.arms), "clearance": self.clearance,
                "contacts": self.contacts, "violations": self.violations, **self.run.as_dict()}


class MultiArmSimulation(ArmSimulation):
    """One episode of a scene with several arms, filtered centrally or per arm.

    Args:
        scene: A scene with ``[[arm]]`` tables.
        strategy: A registered strategy name (``nominal``, ``cbf``, ``isf``, ...).
        coordination: A name of :data:`COORDINATIONS`.
        seed: Episode seed (as :class:`ArmSimulation`; goals jittered per arm).
        nominal: Default :class:`TeamReaching` through the (seeded) goals.
        off_hold: Seconds an intermittent filter's off condition must hold before it switches off (the
            trigger's ``off_hold``; default the parameters' ``off_hold``, else :data:`OFF_HOLD_S`; 0: none).
        **kwargs: As :class:`ArmSimulation` (``params``, ``alpha``, ..., ``observers``, ``timing``).

    Raises:
        ConfigError: The scene has one arm.
        UnknownNameError: Unknown coordination or strategy (the message lists the valid ones).

    """

    episode = _TeamEpisode
    last_episode: _TeamEpisode
    """The state of the last run (its clearance and contacts by kind)."""

    def __init__(self, scene: Scene, strategy: str = "isf", *, coordination: str = "central",
                 seed: int | None = 0, nominal: NominalController | None = None, off_hold: float | None = None,
                 **kwargs: Any) -> None:
        if not scene.arms:
            raise ConfigError(f"scene {scene.name!r} has one arm: run it with ArmSimulation (a scene with "
                              "several arms gives them as [[arm]] tables)")
        if coordination not in COORDINATIONS:
            raise UnknownNameError("coordination", coordination, list(COORDINATIONS))
        if nominal is None:
            goals = episode_setup(scene, seed).goals if seed is not None else scene.goal_positions
            nominal = TeamReaching(scene, goals=goals)
        if not isinstance(nominal, TeamReaching):
            raise ConfigError(f"a scene with several arms runs a TeamReaching nominal (one per arm), got "
                              f"{type(nominal).__name__}")
        self.coordination = coordination
        self.blocks = tuple(a.joints for a in scene.arms)
        self.arm_names = tuple(a.name for a in scene.arms)
        self._off_hold = off_hold
        self._solver_given = kwargs.get("solver") is not None
        super().__init__(scene, strategy, seed=seed, nominal=nominal, **kwargs)
        self.geom_arm = geom_arms(scene.arms, np.arange(scene.model.ngeom))

    def _make_strategy(self, strategy: str, solver: QPSolver) -> CentralFilter | SharedFilter:
        """One filter over every arm's joints (central), or one per arm with its shares (decentral)."""
        if self.info.intermittent:  # (the hold the filters run with, recorded as run)
            hold = self._off_hold if self._off_hold is not None else self.params.off_hold
            self.params = self.params.replace(off_hold=OFF_HOLD_S if hold is None else hold)
        if self.coordination == "central":
            return CentralFilter(super()._make_strategy(strategy, solver), self.blocks, self.arm_names,
                                 self.control_period)
        spec, wiring = filter_options(self)
        cache: dict[str, Any] = {}
        rows = SharedRows(self.blocks)  # (the arms' rollouts': one for all)
        per_arm = []
        for i in range(len(self.blocks)):
            w = dict(wiring)
            if "rollout" in w:
                w["rollout"] = _ArmRollout(wiring["rollout"], cache, self.blocks, i, rows)
            arm_solver = solver if self._solver_given else QPSolver(few_rows=True)  # (a given one serves every arm)
            per_arm.append(make_strategy(strategy, spec, **w, solver=arm_solver, on_infeasible="fallback",
                                         fallback=_brake, validate=False))
        return SharedFilter(per_arm, self.blocks, self.arm_names, self.control_period)

    def start_info(self, duration: float) -> dict[str, Any]:
        """As :meth:`ArmSimulation.start_info`, plus the arms and the coordination.

        Also each arm's columns of the input (``arm_joints``, ``(start, stop)``) and each collision pair's arms
        (``pair_arms``, ``(arm of geom 1, arm of geom 2)``, -1 for a geom of no arm).
        """
        pairs = self.coll.pairs
        return {**super().start_info(duration), "coordination": self.coordination, "arms": list(self.arm_names),
                "arm_joints": [(b.start, b.stop) for b in self.blocks],
                "pair_arms": np.stack((self.geom_arm[pairs.geom1], self.geom_arm[pairs.geom2]), axis=1).tolist()}

    def run_team(self, duration: float | None = None) -> ArmRunResult:
        """Run (as :meth:`ArmSimulation.run`) and gather each arm's figures."""
        run = self.run(duration)
        ep = self.last_episode
        arms = []
        for res, nom in zip(self.strategy.agent_results(run.metrics), self.nominal.arms):  # type: ignore[attr-defined]
            d = res.as_dict()
            arms.append({"name": d.pop("name"), **d.pop("metrics"), **d,
                         "goals_reached": nom.goals_reached, "goals_missed": nom.goals_missed})
        return ArmRunResult(run, self.coordination, tuple(arms), dict(ep.kind_min), dict(ep.contacts))


def run_team(scene: Scene, strategy: str = "isf", coordination: str = "central", duration: float | None = None,
             seed: int | None = 0, **kwargs: Any) -> ArmRunResult:
    """One run of a scene with several arms (:class:`MultiArmSimulation`); keyword arguments go to it."""
    return MultiArmSimulation(scene, strategy, coordination=coordination, seed=seed, **kwargs).run_team(duration)
