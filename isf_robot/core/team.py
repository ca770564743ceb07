"""Several agents (arms) under one set of barriers: one filter for all, or one per agent with shares.

The input is the agents' inputs stacked, ``u = (u_1, ..., u_a)``; agent ``i`` owns the columns
``blocks[i]`` of every row's ``Lg h``. A row *involves* agent ``i`` when its ``Lg h`` has a non-zero
entry in agent ``i``'s columns (:func:`row_agents`): an obstacle or joint-limit row involves one agent,
a row between two agents' bodies (two arms' links) involves both.

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
``s_i > 0``): :func:`agent_lie` builds it, and agent ``i``'s filter treats it like any other row (its
trigger's ``Xi_on``, promotion ``>= b``, screening). Agent ``j``'s motion enters agent ``i``'s row only
through the state (h and its gradient at the current configuration, which every agent senses), never
through agent ``j``'s command.

*Promotion and the off hold* (both ways, intermittent strategies). Rows shared by several agents are never
promoted (``promotable`` of :meth:`~isf_robot.core.filters.IntermittentSafetyFilter.step_lie`): they keep
the robust condition (their share of it) while the filter is on; the agents' own rows (obstacles, joint
limits, self pairs) are promoted as for one arm. Promoting a shared row asks the pair to open at rate
``b`` from the moment the filter is on: two arms on crossing paths may then never come closer, while
passing each other needs them to, so the filter stayed on with the arms held apart until their goals
timed out (panda_pair, RESULTS.md). ``promote_shared=True`` restores the promotion. The filter switches
off only when its off condition has held for ``off_hold`` seconds (:class:`OffHold`): a shared row's
``Xi_on`` can flip sign between control steps where the closest points of two links jump between
features. Neither change weakens the robust condition, which holds on every row at every on step.

*Safety argument.* The shares of a row sum to 1. If every agent's command meets its share, adding the
(share i) conditions over ``i`` in ``S`` gives (team): the pair's robust condition holds, so the barrier
is kept by the same argument as for one filter, up to the robust terms (the tracking-error bound
``d_bar`` on every joint, and the sample-and-hold between control steps, as for one arm). The same holds
for a promoted row (``>= b``). What the split gives up is optimality: an agent meets its share even when
the other agent alone could have satisfied the row; the centralised filter would let one agent do all
the work. An agent whose QP has no solution brakes (``u_i = 0``; the adapter's fallback, counted, as for
one filter): braking meets the agent's share of every row whose bound is <= 0 (a row that holds without
input) and of no other, so a fallback is reported, never hidden.

**Coordination** (:class:`AgentTally`): an agent *needs the other agents* at a step when its filter is
on and a row it shares with another agent is in play: that row's ``Xi_on`` under the nominal is below
the margin in force (the intermittent filter's ``c``, or 0 for the standard filter, where the nominal
would break the row's condition). At such steps a centralised implementation must solve the agents'
commands together; counting them (steps, and rising edges as events) says how often the team needs to
communicate.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .exceptions import ConfigError
from .metrics import DutyCycleMetrics, MetricsAccumulator
from .step import FilterStep
from .strategies import Strategy
from .switches import SwitchCounter
from .system import LieData

__all__ = ["block_matrix", "row_agents", "agent_lie", "AgentTally", "AgentResult", "OffHold", "CentralFilter",
           "SharedFilter"]


def block_matrix(blocks: Sequence[slice], m: int) -> np.ndarray:
    """``M[j, i] = 1`` when column j is agent i's, shape (m, a): ``|Lg h| M > 0`` is :func:`row_agents`."""
    M = np.zeros((m, len(blocks)))
    for i, b in enumerate(blocks):
        M[b, i] = 1.0
    return M


def row_agents(lg: np.ndarray, blocks: Sequence[slice] | np.ndarray) -> np.ndarray:
    """Which agents each row involves: ``out[r, i]`` when row r's ``Lg h`` is non-zero in agent i's columns.

    Args:
        lg: ``Lg h``, shape (k, m).
        blocks: Agent i's columns, slices covering ``0..m`` without overlap; or their :func:`block_matrix`
            (computed once by a caller that asks every step).

    Returns:
        Shape (k, a), bool.

    """
    M = blocks if isinstance(blocks, np.ndarray) else block_matrix(blocks, lg.shape[1])
    return np.abs(lg) @ M > 0.0


def agent_lie(lie: LieData, block: slice, rows: np.ndarray, share: np.ndarray) -> LieData:
    """Agent's rows: ``(h, lf, lg[:, block] / share, |dh/dx|)`` of the rows ``rows`` (see the module docstring).

    Args:
        lie: The team's rows.
        block: The agent's columns.
        rows: Indices of the rows that involve the agent, shape (k_i,).
        share: The agent's share of each of those rows, in (0, 1], shape (k_i,).

    """
    names = tuple(lie.names[r] for r in rows) if lie.names else ()
    return LieData._of(lie.h[rows], lie.lf[rows], lie.lg[rows, block] / share[:, None], lie.grad_norm[rows], names)


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


class AgentTally:
    """Per-agent accounting: its filter steps into a :class:`MetricsAccumulator`, and its coordination."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self.metrics = MetricsAccumulator()
        self.steps = self.events = 0
        self.time = 0.0
        self._was = False

    def add(self, step: FilterStep, shared: np.ndarray, dt: float) -> None:
        """Record the agent's step (``shared``: which of its rows involve another agent, shape like ``step.xi``)."""
        self.metrics.add_step(step, dt)
        margin = step.margin if step.margin is not None else 0.0
        need = bool(step.on) and bool(np.any(step.xi[shared] < margin))
        if need:
            self.steps += 1
            self.time += dt
            self.events += not self._was
        self._was = need

    def result(self) -> AgentResult:
        """The figures so far."""
        return AgentResult(self.name, self.metrics.result(), self.steps, self.events, self.time)


class OffHold:
    """Hold an intermittent filter on until its off condition has held for ``hold_s`` seconds.

    Between two arms the distance's gradient can turn where the closest points jump from one feature
    of a link to another: ``Xi_on`` of that row then flips sign from one control step to the next and
    the filter would switch off and on within milliseconds. The hold asks the off condition (every
    ``Xi_on`` at least the margin in force) to have held at every step of the last ``hold_s`` seconds
    before the filter may switch off; it only keeps the filter on (the robust condition enforced), never
    off, so it changes nothing in the safety argument. ``hold_s = 0``: no hold.
    """

    def __init__(self, hold_s: float) -> None:
        self.hold_s = float(hold_s)
        self.reset()

    def reset(self) -> None:
        """Forget the last failure of the off condition."""
        self._t_fail = -np.inf

    def __call__(self, t: float) -> bool:
        """Whether the filter must stay on at ``t`` (the off condition failed within ``hold_s``)."""
        return self.hold_s > 0.0 and t - self._t_fail < self.hold_s

    def record(self, step: FilterStep) -> None:
        """Note the step's outcome: an on step whose smallest ``Xi_on`` is below its margin."""
        if step.on and step.xi.size and float(step.xi.min()) < (step.margin or 0.0):
            self._t_fail = step.t


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
        off_hold: Seconds the off condition must hold before an intermittent strategy switches off.

    """

    def __init__(self, strategy: Strategy, blocks: Sequence[slice], names: Sequence[str], period: float, *,
                 promote_shared: bool = False, off_hold: float = 0.0) -> None:
        _check_blocks(blocks, names)
        self.inner, self.blocks, self.period = strategy, tuple(blocks), float(period)
        self.promote_shared = promote_shared
        self.hold = OffHold(off_hold if strategy.intermittent else 0.0)
        self.uses_rows, self.intermittent = strategy.uses_rows, strategy.intermittent
        self.tallies = [AgentTally(n) for n in names]
        self._M: np.ndarray | None = None
        self._last: FilterStep | None = None

    @property
    def on(self) -> bool:
        """The filter's mode."""
        return self.inner.on

    def reset(self, t0: float = 0.0) -> None:
        """Start again."""
        self.inner.reset(t0)
        self.hold.reset()
        self._last = None
        for tally in self.tallies:
            tally.reset()

    def step_lie(self, t: float, lie: LieData | None, u_nom: np.ndarray, x: Any = None, **kw: Any) -> FilterStep:
        """The strategy's step; each agent's share of it is recorded.

        An intermittent strategy promotes no shared row and is held on by :class:`OffHold` (module docstring).
        """
        if lie is None:
            step = self.inner.step_lie(t, lie, u_nom)  # type: ignore[arg-type]  # (no rows: NominalStrategy)
            shared = np.zeros(step.xi.shape, dtype=bool)
        else:
            if self._M is None or self._M.shape[0] != lie.m:
                self._M = block_matrix(self.blocks, lie.m)
            shared = row_agents(lie.lg, self._M).sum(axis=1) > 1
            if self.intermittent and not self.promote_shared:
                kw["promotable"] = ~shared
            if self.hold(t):
                kw["hold"] = True
            step = self.inner.step_lie(t, lie, u_nom, x, **kw)
            self.hold.record(step)
            if not step.on or lie.k != step.xi.shape[0]:  # (coordination counts only while on)
                shared = np.zeros(step.xi.shape, dtype=bool)
        for b, tally in zip(self.blocks, self.tallies):
            part = FilterStep._of(t, step.u[b], step.u_nom[b], step.on, step.h, step.xi, step.event, step.qp,
                                  margin=step.margin)
            tally.add(part, shared, self.period)
        self._last = step
        return step

    def agent_modes(self) -> list[tuple[bool, bool]]:
        """Each agent's ``(on, QP solved)`` at the last step (one filter: the same for every agent)."""
        st = self._last
        mode = (False, False) if st is None else (bool(st.on), st.qp is not None)
        return [mode] * len(self.tallies)

    def agent_results(self) -> list[AgentResult]:
        """Each agent's figures."""
        return [t.result() for t in self.tallies]


class SharedFilter:
    """One strategy per agent, each with its share of the rows it shares (the decentralised filter).

    Args:
        strategies: Agent i's strategy (input: its own columns), e.g. from :func:`make_strategy`.
        blocks: Agent i's columns of the stacked input.
        names: Agent names.
        period: Control period [s].
        promote_shared: As :class:`CentralFilter`.
        off_hold: As :class:`CentralFilter` (each agent's filter its own hold).

    The team's step: the agents' commands stacked, ``on`` when any agent's filter is on (with its own
    switch events), ``xi`` per row the smallest of the agents' ``Xi_on`` of that row (rows that involve
    no agent: ``inf``), ``qp`` the first agent's QP result that exists.

    """

    def __init__(self, strategies: Sequence[Strategy], blocks: Sequence[slice], names: Sequence[str],
                 period: float, *, promote_shared: bool = False, off_hold: float = 0.0) -> None:
        _check_blocks(blocks, names)
        if len(strategies) != len(blocks):
            raise ConfigError(f"a shared filter needs one strategy per agent, got {len(strategies)} for {len(blocks)}")
        self.agents, self.blocks, self.period = tuple(strategies), tuple(blocks), float(period)
        self.uses_rows = any(s.uses_rows for s in strategies)
        self.intermittent = any(s.intermittent for s in strategies)
        self.promote_shared = promote_shared
        self.holds = [OffHold(off_hold if s.intermittent else 0.0) for s in strategies]
        self.tallies = [AgentTally(n) for n in names]
        self.last: list[FilterStep] = []
        self._switch = SwitchCounter()
        self._M: np.ndarray | None = None

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
        for hold in self.holds:
            hold.reset()

    def split(self, lie: LieData) -> list[tuple[np.ndarray, LieData, np.ndarray]]:
        """Each agent's ``(rows, its Lie data, which of those rows are shared)`` (:func:`agent_lie`)."""
        if self._M is None or self._M.shape[0] != lie.m:
            self._M = block_matrix(self.blocks, lie.m)
        inv = row_agents(lie.lg, self._M)
        count = inv.sum(axis=1)
        out = []
        for i, b in enumerate(self.blocks):
            rows = np.flatnonzero(inv[:, i])
            share = 1.0 / count[rows]
            out.append((rows, agent_lie(lie, b, rows, share), count[rows] > 1))
        return out

    def step_lie(self, t: float, lie: LieData | None, u_nom: np.ndarray, x: Any = None,
                 screen: np.ndarray | None = None, **kw: Any) -> FilterStep:
        """Every agent's filter on its share of the rows; the commands stacked."""
        u = np.array(u_nom, dtype=float)
        steps = []
        if lie is None:
            for s, b in zip(self.agents, self.blocks):
                steps.append(s.step_lie(t, None, u_nom[b]))  # type: ignore[arg-type]  # (NominalStrategy)
            xi = np.zeros(0)
            parts: list[tuple[np.ndarray, LieData, np.ndarray]] = []
        else:
            parts = self.split(lie)
            xi = np.full(lie.k, np.inf)
            for s, b, (rows, sub, shared), hold in zip(self.agents, self.blocks, parts, self.holds):
                extra = dict(kw)
                if screen is not None:
                    extra["screen"] = screen[rows]
                if s.intermittent and not self.promote_shared:
                    extra["promotable"] = ~shared
                if hold(t):
                    extra["hold"] = True
                st = s.step_lie(t, sub, u_nom[b], x, **extra)
                hold.record(st)
                xi[rows] = np.minimum(xi[rows], st.xi)
                steps.append(st)
        for i, (b, st) in enumerate(zip(self.blocks, steps)):
            u[b] = st.u
            self.tallies[i].add(st, parts[i][2] if parts else np.zeros(st.xi.shape, bool), self.period)
        self.last = steps
        on = any(st.on for st in steps)
        event = self._switch.update(t, on, float(np.min(xi)) if xi.size else np.inf)
        qp = next((st.qp for st in steps if st.qp is not None), None)
        return FilterStep._of(t, u, u_nom, on, lie.h if lie is not None else xi, xi, event, qp,
                              tuple(r for st in steps for r in st.relaxed), any(st.fallback for st in steps),
                              lie.names if lie is not None else (), any(st.resolved for st in steps))

    def agent_modes(self) -> list[tuple[bool, bool]]:
        """Each agent's ``(on, QP solved)`` at the last step (its own filter's)."""
        if not self.last:
            return [(False, False)] * len(self.tallies)
        return [(bool(st.on), st.qp is not None) for st in self.last]

    def agent_results(self) -> list[AgentResult]:
        """Each agent's figures."""
        return [t.result() for t in self.tallies]
