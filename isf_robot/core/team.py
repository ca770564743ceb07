"""Several agents (arms) under one set of barriers: one filter for all, or one per agent with shares.

The input is the agents' inputs stacked, ``u = (u_1, ..., u_a)``; agent ``i`` owns the columns
``blocks[i]`` of every row's ``Lg h``. A row *involves* agent ``i`` when its ``Lg h`` has a non-zero
entry in agent ``i``'s columns (:mod:`isf_robot.core.shares`): an obstacle or joint-limit row involves one
agent, a row between two agents' bodies (two arms' links) involves both.

**Centralised** (:class:`CentralFilter`): one strategy over the stacked input, the rows as they are; it
only adds per-agent accounting.

**Decentralised** (:class:`SharedFilter`): one strategy per agent, built by the caller with the core's
:func:`~isf_robot.core.strategies.make_strategy` (no new filter). A row involving the agents ``S``
gives agent ``i`` in ``S`` the share ``s_i = 1 / |S|`` of its condition. The robust barrier condition
of the row (paper eq. barr_cond with ``Lf h(x, u) = lf + sum_j lg_j u_j``),

    sum_j lg_j u_j  >=  -alpha(h) - lf + |dh/dx| d_bar,                        (team)

is split into one condition per agent,

    lg_i u_i  >=  s_i (-alpha(h) - lf + |dh/dx| d_bar),                        (share i)

which is the ordinary robust condition of the row ``(h, lf, lg_i / s_i, |dh/dx|)`` (divide by
``s_i > 0``): :func:`~.shares.agent_lie` builds it, and agent ``i``'s filter treats it like any other row (its
trigger's ``Xi_on``, promotion ``>= b``, screening). Agent ``j``'s motion enters agent ``i``'s row only
through the state (h and its gradient at the current configuration, which every agent senses), never
through agent ``j``'s command.

*Promotion* (both ways, intermittent strategies). Rows shared by several agents are never
promoted (``promotable`` of :meth:`~isf_robot.core.filters.IntermittentSafetyFilter.step_lie`): they keep
the robust condition (their share of it) while the filter is on; the agents' own rows (obstacles, joint
limits, self pairs) are promoted as for one arm. Promoting a shared row asks the pair to open at rate
``b`` from the moment the filter is on: two arms on crossing paths may then never come closer, while
passing each other needs them to, so the filter stayed on with the arms held apart until their goals
timed out (panda_pair, RESULTS.md). ``promote_shared=True`` restores the promotion. This does not weaken
the robust condition, which holds on every row at every on step. (The arm layer builds a team's intermittent
filters with an off hold, the trigger's ``off_hold``, :class:`~isf_robot.core.triggers.OnOffTrigger`: a
shared row's ``Xi_on`` can flip sign between control steps where the closest points of two links jump
between features. These classes add no hold of their own.)

*Safety argument.* The shares of a row sum to 1. If every agent's command meets its share, adding the
(share i) conditions over ``i`` in ``S`` gives (team): the pair's robust condition holds, so the barrier
is kept by the same argument as for one filter, up to the robust terms (the tracking-error bound
``d_bar`` on every joint, and the sample-and-hold between control steps, as for one arm). The same holds
for a promoted row (``>= b``). What the split gives up is optimality: an agent meets its share even when
the other agent alone could have satisfied the row; the centralised filter would let one agent do all
the work. An agent whose QP has no solution brakes (``u_i = 0``; the adapter's fallback, counted, as for
one filter): braking meets the agent's share of every row whose bound is <= 0 (a row that holds without
input) and of no other, so a fallback is reported, never hidden.

**Coordination** (:class:`Coordination`): an agent *needs the other agents* at a step when its filter
(centrally: the one filter) is on and a row it shares with another agent is in play: that row's ``Xi_on``
under the nominal is below the margin in force (the intermittent filter's ``c``, or 0 for the standard
filter, where the nominal would break the row's condition). At such steps a centralised implementation
must solve the agents' commands together; counting them (steps, and rising edges as events) says how
often the team needs to communicate.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from .exceptions import ConfigError
from .jit import compiled, direct, formula
from .metrics import DutyCycleMetrics, MetricsAccumulator
from .shares import SharedRows, block_matrix
from .step import FilterStep
from .strategies import Strategy
from .switches import SwitchCounter
from .system import LieData

__all__ = ["Coordination", "AgentTally", "AgentResult", "BlockIntervention", "CentralFilter", "SharedFilter",
           "least_of", "team_least"]


@dataclass(frozen=True)
class AgentResult:
    """One agent's figures over a run.

    Attributes:
        name: The agent's name.
        metrics: Its filter's duty cycle, switches, off periods and intervention (its own input).
        coordination_steps: Control steps at which it needed the others (see the module docstring).
        coordination_events: Rising edges of that (stretches of needing them).
        coordination_s: Time [s] it needed them.

    """

    name: str
    metrics: DutyCycleMetrics
    coordination_steps: int
    coordination_events: int
    coordination_s: float

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready)."""
        return asdict(self)


class Coordination:
    """Control steps at which each agent needed the others (module docstring): counts, rising edges, time."""

    def __init__(self, agents: int = 1) -> None:
        self.agents = int(agents)
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        a = self.agents
        self.steps, self.events = np.zeros(a, dtype=np.int64), np.zeros(a, dtype=np.int64)
        self.time = np.zeros(a)
        self._was = np.zeros(a, dtype=bool)
        self._any = False  # (whether any agent needed the others at the last step)

    @staticmethod
    def needs(step: FilterStep, shared: np.ndarray, involves: np.ndarray | None = None) -> np.ndarray:
        """Which agents need the others at ``step``: its filter is on and one of their shared rows is below the margin.

        Args:
            step: The filter's step (``on``, ``xi``, ``margin``: ``None`` counts as 0).
            shared: Which rows involve several agents, bool like ``step.xi``.
            involves: The rows' agents (:func:`~.shares.row_agents`, shape (k, a)); ``None``: one agent, whose
                rows these are.

        Returns:
            Shape (a,) bool (a = 1 without ``involves``).

        """
        a = 1 if involves is None else involves.shape[1]
        if not step.on or not shared.any():
            return _nobody(a)
        hot = shared & (step.xi < (step.margin if step.margin is not None else 0.0))
        if involves is None:
            return _SOMEONE if hot.any() else _nobody(1)
        return (involves & hot[:, None]).any(axis=0)

    def add(self, need: np.ndarray, dt: float) -> None:
        """Count a step of ``dt`` seconds for the agents in ``need`` (bool, shape (a,))."""
        if need is _SOMEONE:  # (one agent, needing the others: scalar updates)
            self.steps[0] += 1
            self.time[0] += dt
            if not self._any:
                self.events[0] += 1
            self._was[0] = self._any = True
        elif need is not _NOBODY.get(need.shape[0]) and need.any():
            self.steps += need
            self.time[need] += dt
            self.events += need & ~self._was
            self._was = need.copy()
            self._any = True
        elif self._any:
            self._was[:] = False
            self._any = False

    def of(self, i: int) -> tuple[int, int, float]:
        """Agent ``i``'s ``(steps, events, seconds)``."""
        return int(self.steps[i]), int(self.events[i]), float(self.time[i])


_NOBODY: dict[int, np.ndarray] = {}
_SOMEONE = np.ones(1, dtype=bool)
_SOMEONE.flags.writeable = False


def _nobody(a: int) -> np.ndarray:
    """A read-only "no agent" answer of :meth:`Coordination.needs` (one per size: most steps need nobody)."""
    got = _NOBODY.get(a)
    if got is None:
        got = _NOBODY[a] = np.zeros(a, dtype=bool)
        got.flags.writeable = False
    return got


@formula
def least_of(xi: np.ndarray, rows: np.ndarray, ends: np.ndarray, values: np.ndarray) -> None:
    """``xi[r] = minimum(xi[r], v)`` over every agent's rows ``r`` and their ``Xi_on`` ``v``, agent after agent.

    Each row's least ``Xi_on`` over the agents that have it (:attr:`.shares._Involved.order`: every agent's rows, agent
    after agent, each agent's ascending, and where each agent's end; ``values`` their ``Xi_on`` in that order).
    NaN as ``np.minimum`` treats it. One call in array operations per agent (compiled where the kernels run).
    """
    r0 = 0
    for a in range(ends.shape[0]):
        r1 = ends[a]
        idx = rows[r0:r1]
        xi[idx] = np.minimum(xi[idx], values[r0:r1])
        r0 = r1


def team_least(xi: np.ndarray, rows: np.ndarray, ends: np.ndarray, values: np.ndarray, shared_of: np.ndarray,
               margins: np.ndarray, on: np.ndarray, need: np.ndarray) -> None:
    """Each row's least ``Xi_on`` over its agents, and which agents need the others, in one call.

    ``xi`` is set to ``inf`` (a row of no agent keeps it), then :func:`least_of`. ``need[a]``: agent ``a``'s filter
    is on (``on[a]``) and one of its shared rows (``shared_of``, in the order of ``values``) has ``Xi_on`` below its
    margin ``margins[a]``: :meth:`Coordination.needs` of the agent's step (a NaN is not below). In array operations
    per agent (compiled where the kernels run: :class:`SharedFilter`).
    """
    xi[:] = np.inf
    least_of(xi, rows, ends, values)
    r0 = 0
    for a in range(ends.shape[0]):
        r1 = ends[a]
        need[a] = on[a] and (shared_of[r0:r1] & (values[r0:r1] < margins[a])).any()
        r0 = r1


class AgentTally:
    """Per-agent accounting: its filter steps into a :class:`MetricsAccumulator`, and its :class:`Coordination`."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self.metrics = MetricsAccumulator()
        self.coordination = Coordination()

    def add(self, step: FilterStep, shared: np.ndarray, dt: float, shares: bool = True) -> None:
        """Record the agent's step (``shared``: which of its rows involve another agent, shape like ``step.xi``).

        ``shares=False`` says that none does (as ``shared.any()`` would; not asked again).
        """
        self.metrics.add_step(step, dt)
        coordination = self.coordination
        if shares and step.on:
            coordination.add(Coordination.needs(step, shared), dt)
        elif coordination._any:  # (off, or no shared row: nobody is needed; only the end of a stretch to record)
            coordination.add(_nobody(1), dt)

    def add_need(self, step: FilterStep, need: bool, dt: float) -> None:
        """As :meth:`add`, given whether the agent needs the others at ``step`` (:meth:`Coordination.needs`' answer)."""
        self.metrics.add_step(step, dt)
        coordination = self.coordination
        if need:
            coordination.add(_SOMEONE, dt)
        elif coordination._any:  # (only the end of a stretch to record)
            coordination.add(_nobody(1), dt)

    def result(self) -> AgentResult:
        """The figures so far."""
        return AgentResult(self.name, self.metrics.result(), *self.coordination.of(0))


class BlockIntervention:
    """Each agent's intervention ``sum_k |u_k - u_nom,k|^2 dt_k`` over its own columns of the stacked command.

    The differences are kept by reference and summed per agent every ``chunk`` steps (one product for
    all of them), so a step costs one subtraction and a list append.
    """

    def __init__(self, blocks: Sequence[slice], chunk: int = 1024) -> None:
        self.blocks, self.chunk = tuple(blocks), int(chunk)
        self._M = block_matrix(self.blocks, max(b.stop for b in self.blocks))
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self.sums = np.zeros(len(self.blocks))
        self._d: list[np.ndarray] = []
        self._dt: list[float] = []

    def add(self, u: np.ndarray, u_nom: np.ndarray, dt: float) -> None:
        """One step's commands (a command that is ``u_nom`` itself adds nothing)."""
        if u is u_nom:
            return
        self._d.append(u - u_nom)
        self._dt.append(dt)
        if len(self._d) >= self.chunk:
            self._sum()

    def _sum(self) -> None:
        if self._d:
            d = np.array(self._d)
            self.sums += (np.asarray(self._dt) @ (d * d)) @ self._M
            self._d.clear()
            self._dt.clear()

    def result(self) -> np.ndarray:
        """Per agent, the intervention so far, shape (a,)."""
        self._sum()
        return self.sums.copy()


def _check_blocks(blocks: Sequence[slice], names: Sequence[str]) -> None:
    if len(blocks) != len(names) or len(blocks) < 1:
        raise ConfigError(f"a team needs one name per block of columns, got {len(blocks)} blocks, {len(names)} names")


class CentralFilter:
    """One strategy over every agent's input (the centralised filter), with per-agent accounting.

    Args:
        strategy: The strategy over the stacked input.
        blocks: Agent i's columns.
        names: Agent names.
        period: Control period [s] (each step's duration in the tallies).
        promote_shared: Promote rows shared by several agents too (default: only the agents' own rows).

    """

    def __init__(self, strategy: Strategy, blocks: Sequence[slice], names: Sequence[str], period: float, *,
                 promote_shared: bool = False) -> None:
        _check_blocks(blocks, names)
        self.inner, self.blocks, self.period = strategy, tuple(blocks), float(period)
        self.names = tuple(names)
        self.promote_shared = promote_shared
        self.uses_rows, self.intermittent = strategy.uses_rows, strategy.intermittent
        self.shared_rows = SharedRows(self.blocks)
        self.intervention = BlockIntervention(self.blocks)
        self.coordination = Coordination(len(self.blocks))
        self._last: FilterStep | None = None
        self._nobody = _nobody(len(self.blocks))

    @property
    def on(self) -> bool:
        """The filter's mode."""
        return self.inner.on

    def reset(self, t0: float = 0.0) -> None:
        """Start again."""
        self.inner.reset(t0)
        self._last = None
        self.intervention.reset()
        self.coordination.reset()

    def step_lie(self, t: float, lie: LieData | None, u_nom: np.ndarray, x: Any = None, **kw: Any) -> FilterStep:
        """The strategy's step, accounted for every agent.

        An intermittent strategy promotes no shared row (module docstring).
        """
        if lie is None:
            step = self.inner.step_lie(t, lie, u_nom)  # type: ignore[arg-type]  # (no rows: NominalStrategy)
            need = self._nobody
        else:
            rows = self.shared_rows(lie)
            if self.intermittent and not self.promote_shared:
                kw["promotable"] = ~rows.shared
            step = self.inner.step_lie(t, lie, u_nom, x, **kw)
            need = Coordination.needs(step, rows.shared, rows.inv) if lie.k == step.xi.shape[0] else self._nobody
        self.intervention.add(step.u, step.u_nom, self.period)
        self.coordination.add(need, self.period)
        self._last = step
        return step

    def agent_modes(self) -> list[tuple[bool, bool]]:
        """Each agent's ``(on, QP solved)`` at the last step (one filter: the same for every agent)."""
        st = self._last
        mode = (False, False) if st is None else (bool(st.on), st.qp is not None)
        return [mode] * len(self.blocks)

    def agent_results(self, team: DutyCycleMetrics) -> list[AgentResult]:
        """Each agent's figures: the filter's duty cycle, switches and periods, its own intervention.

        Args:
            team: The filter's figures over the run, as the loop that ran it accounted its steps (the one
                filter's duty cycle, switches and periods are every agent's).

        """
        return [AgentResult(n, replace(team, intervention=float(v)), *self.coordination.of(i))
                for i, (n, v) in enumerate(zip(self.names, self.intervention.result()))]


class SharedFilter:
    """One strategy per agent, each with its share of the rows it shares (the decentralised filter).

    Args:
        strategies: Agent i's strategy (input: its own columns), e.g. from :func:`make_strategy`.
        blocks: Agent i's columns of the stacked input.
        names: Agent names.
        period: Control period [s].
        promote_shared: As :class:`CentralFilter`.

    The team's step: the agents' commands stacked, ``on`` when any agent's filter is on (with its own
    switch events), ``xi`` per row the smallest of the agents' ``Xi_on`` of that row (rows that involve
    no agent: ``inf``), ``qp`` the first agent's QP result that exists.

    """

    def __init__(self, strategies: Sequence[Strategy], blocks: Sequence[slice], names: Sequence[str],
                 period: float, *, promote_shared: bool = False) -> None:
        _check_blocks(blocks, names)
        if len(strategies) != len(blocks):
            raise ConfigError(f"a shared filter needs one strategy per agent, got {len(strategies)} for {len(blocks)}")
        self.agents, self.blocks, self.period = tuple(strategies), tuple(blocks), float(period)
        self.uses_rows = any(s.uses_rows for s in strategies)
        self.intermittent = any(s.intermittent for s in strategies)
        self.promote_shared = promote_shared
        self.tallies = [AgentTally(n) for n in names]
        self.last: list[FilterStep] = []
        self._switch = SwitchCounter()
        self.shared_rows = SharedRows(self.blocks)
        self._least = compiled(team_least)  # (ISF_ROBOT_JIT is read when the filter is built)
        self._least_code: Any = None  # (its code for the types of the first step's arguments: jit.direct)
        a = len(self.agents)  # (team_least's per-agent inputs and answer, rewritten at each step)
        self._margins, self._on, self._need = np.empty(a), np.empty(a, np.bool_), np.empty(a, np.bool_)

    @property
    def on(self) -> bool:
        """Whether any agent's filter is on."""
        return any(s.on for s in self.agents)

    def reset(self, t0: float = 0.0) -> None:
        """Start again."""
        for s, tally in zip(self.agents, self.tallies):
            s.reset(t0)
            tally.reset()
        self._switch.reset()

    def split(self, lie: LieData) -> list[tuple[np.ndarray, LieData, np.ndarray]]:
        """Each agent's ``(rows, its Lie data, which of those rows are shared)`` (:func:`~.shares.agent_lie`'s rows)."""
        inv = self.shared_rows(lie)
        return [(rows, sub, shared) for sub, (rows, _, shared, _) in zip(inv.split(lie), inv.parts)]

    def step_lie(self, t: float, lie: LieData | None, u_nom: np.ndarray, x: Any = None,
                 screen: np.ndarray | None = None, **kw: Any) -> FilterStep:
        """Every agent's filter on its share of the rows; the commands stacked."""
        steps = []
        period, tallies = self.period, self.tallies
        if lie is None:
            u = np.array(u_nom, dtype=float)
            for i, (s, b) in enumerate(zip(self.agents, self.blocks)):
                st = s.step_lie(t, None, u_nom[b])  # type: ignore[arg-type]  # (NominalStrategy)
                u[b] = st.u
                tallies[i].add(st, np.zeros(st.xi.shape, bool), period)
                steps.append(st)
            xi = np.zeros(0)
        else:
            inv = self.shared_rows(lie)
            subs = inv.split(lie)  # (every agent's rows first, in one pass: agent_lie's rows for each agent)
            keep, margins, on, need = not self.promote_shared, self._margins, self._on, self._need
            parts = zip(self.agents, self.blocks, subs, inv.parts, inv.steps)
            for i, (s, b, sub, (rows, _, _, _), (mine, _)) in enumerate(parts):
                extra = dict(kw) if kw else {}
                if screen is not None:
                    extra["screen"] = screen[rows]
                if keep and s.intermittent:
                    extra["promotable"] = mine
                st = s.step_lie(t, sub, u_nom[b], x, **extra)
                steps.append(st)
                margins[i] = 0.0 if st.margin is None else st.margin
                on[i] = st.on
            xi = np.empty(lie.k)
            rows, ends, shared_of = inv.order_shared()
            # (each row's least Xi_on, and which agents need the others: Coordination.needs of each agent's step)
            args = (xi, rows, ends, np.concatenate([st.xi for st in steps]), shared_of, margins, on, need)
            least = self._least_code  # (every argument's type is fixed by construction: float64 Xi_on checked)
            if least is None:
                least = self._least_code = direct(self._least, args)
            (least if args[3].dtype == np.float64 else self._least)(*args)
            u = np.array(u_nom, dtype=float)
            for b, st, tally, wants in zip(self.blocks, steps, tallies, need.tolist()):
                u[b] = st.u
                tally.add_need(st, wants, period)
        self.last = steps
        on = fallback = resolved = False
        qp = None
        relaxed: tuple[str, ...] = ()
        for st in steps:  # (one pass over the agents' steps)
            on = on or bool(st.on)
            if qp is None:
                qp = st.qp
            if st.relaxed:
                relaxed += tuple(st.relaxed)
            fallback = fallback or bool(st.fallback)
            resolved = resolved or bool(st.resolved)
        switch = self._switch
        event = None if on == switch.on else switch.update(t, on, float(np.min(xi)) if xi.size else np.inf)
        return FilterStep._of(t, u, u_nom, on, lie.h if lie is not None else xi, xi, event, qp, relaxed, fallback,
                              lie.names if lie is not None else (), resolved)

    def agent_modes(self) -> list[tuple[bool, bool]]:
        """Each agent's ``(on, QP solved)`` at the last step (its own filter's)."""
        if not self.last:
            return [(False, False)] * len(self.tallies)
        return [(bool(st.on), st.qp is not None) for st in self.last]

    def agent_results(self, team: DutyCycleMetrics) -> list[AgentResult]:
        """Each agent's figures, from its own filter's tally (``team``, the team's figures, is not needed)."""
        return [t.result() for t in self.tallies]
