"""The team filters' accounting: per-agent intervention, shared rows kept per set of names, coordination."""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core import LieData
from isf_robot.core.exceptions import NonFiniteError
from isf_robot.core.jit import compiled
from isf_robot.core.shares import (
    SharedRows,
    agent_lie,
    gather_rows,
    involved,
    row_agents,
    row_plan,
)
from isf_robot.core.step import FilterStep
from isf_robot.core.team import AgentTally, BlockIntervention, Coordination, SharedFilter, least_of, team_least

BLOCKS = (slice(0, 2), slice(2, 5))


@pytest.mark.parametrize("chunk", [1, 3, 1024])
def test_block_intervention_is_each_agents_sum_of_squares_times_dt(chunk: int) -> None:
    rng = np.random.default_rng(0)
    acc = BlockIntervention(BLOCKS, chunk=chunk)
    want = np.zeros(2)
    for k in range(10):
        u_nom = rng.normal(size=5)
        dt = 0.001 * (1 + k % 3)  # (steps of different length)
        if k % 4 == 0:  # the filter passes the nominal through: nothing added
            acc.add(u_nom, u_nom, dt)
            continue
        u = u_nom + rng.normal(size=5)
        acc.add(u, u_nom, dt)
        d = u - u_nom
        want += dt * np.array([np.sum(d[:2] ** 2), np.sum(d[2:] ** 2)])
    np.testing.assert_allclose(acc.result(), want, rtol=1e-13)
    np.testing.assert_allclose(acc.result(), want, rtol=1e-13)  # (reading twice adds nothing)
    acc.reset()
    np.testing.assert_array_equal(acc.result(), [0.0, 0.0])


def _lie(lg: np.ndarray, names: tuple[str, ...]) -> LieData:
    k = lg.shape[0]
    return LieData._of(np.ones(k), np.zeros(k), lg, np.linalg.norm(lg, axis=1), names)


def test_shared_rows_match_row_agents_and_are_kept_per_names() -> None:
    rng = np.random.default_rng(1)
    lg = rng.normal(size=(3, 5))
    lg[0, 2:] = 0.0  # row 0: agent 0 only
    lg[1, :2] = 0.0  # row 1: agent 1 only; row 2: both
    shared = SharedRows(BLOCKS)
    names = ("a|x", "b|y", "a|b")
    inv = shared(_lie(lg, names))
    np.testing.assert_array_equal(inv.inv, row_agents(lg, BLOCKS))
    np.testing.assert_array_equal(inv.shared, [False, False, True])
    rows, share, sh, names_1 = inv.parts[1]
    assert names_1 == ("b|y", "a|b")
    np.testing.assert_array_equal(rows, [1, 2])
    np.testing.assert_array_equal(share, [1.0, 0.5])
    np.testing.assert_array_equal(sh, [False, True])
    # the same names at another state: the same answer without looking again
    again = shared(_lie(rng.normal(size=(3, 5)), tuple(list(names))))  # (an equal names tuple, another object)
    assert again is inv  # (so an agent's names tuple, parts[i][3], is the same object again: the hand-over's key)
    # other names, or rows without names: looked at
    other = shared(_lie(lg[::-1].copy(), ("a|b", "b|y", "a|x")))
    np.testing.assert_array_equal(other.shared, [True, False, False])
    nameless = shared(_lie(lg[[2]], ()))
    np.testing.assert_array_equal(nameless.shared, [True])
    assert shared(_lie(lg[[0]], ())) is not nameless


@pytest.mark.parametrize("jit", ["1", "0"])
def test_split_gives_each_agent_its_rows_its_columns_and_its_share(jit: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Every agent's rows in one pass (compiled or as written) equal the rows picked one agent at a time."""
    monkeypatch.setenv("ISF_ROBOT_JIT", jit)
    rng = np.random.default_rng(2)
    blocks = (slice(0, 2), slice(2, 5), slice(5, 7))
    lg = rng.normal(size=(9, 7))
    lg[rng.random(size=(9, 7)) < 0.4] = 0.0  # (rows of one agent, of two, of three)
    lg[0] = 0.0
    lg[0, 3] = 1.5  # (a row of agent 1 alone)
    lie = LieData._of(rng.normal(size=9), rng.normal(size=9), lg, np.linalg.norm(lg, axis=1) + 1.0,
                      tuple(f"r{i}" for i in range(9)))
    inv = SharedRows(blocks)(lie)
    subs = inv.split(lie)
    inv_rows = row_agents(lg, blocks)
    for a, (b, sub, (rows, share, _, names)) in enumerate(zip(blocks, subs, inv.parts)):
        np.testing.assert_array_equal(rows, np.flatnonzero(inv_rows[:, a]))
        want_share = 1.0 / inv_rows[rows].sum(axis=1)
        np.testing.assert_array_equal(share, want_share)
        np.testing.assert_array_equal(sub.h, lie.h[rows])
        np.testing.assert_array_equal(sub.lf, lie.lf[rows])
        np.testing.assert_array_equal(sub.grad_norm, lie.grad_norm[rows])
        np.testing.assert_array_equal(sub.lg, lg[rows][:, b] / want_share[:, None])
        assert sub.names == names == tuple(f"r{i}" for i in rows)
        one = agent_lie(lie, b, rows, share, names)  # (one agent's rows, the same pass)
        np.testing.assert_array_equal(one.lg, sub.lg)
        np.testing.assert_array_equal(agent_lie(lie, b, rows, np.ones(rows.size), names, scaled=False).lg,
                                      lg[rows][:, b])
    assert (compiled(gather_rows) is gather_rows) == (jit == "0")  # (numba is a dependency: compiled with "1")


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_row_with_non_finite_lg_is_refused_not_dropped(bad: float) -> None:
    """No agent may lose a row silently: the step's split refuses it, the points' split hands it to the agent."""
    lg = np.array([[bad, 0.0, 1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0, 0.0]])
    with pytest.raises(NonFiniteError, match=r"rows \[0\]"):
        row_agents(lg, BLOCKS)
    with pytest.raises(NonFiniteError):
        SharedRows(BLOCKS)(_lie(lg, ("a|b", "a|x")))
    out = np.zeros(2, dtype=bool)
    compiled(involved)(lg, 0, 2, out)  # (agent 0's columns: its prediction then refuses the row)
    np.testing.assert_array_equal(out, [True, True])
    compiled(involved)(lg, 2, 5, out)
    np.testing.assert_array_equal(out, [True, False])


@pytest.mark.parametrize("jit", ["1", "0"])
def test_least_of_takes_each_rows_least_xi_over_its_agents(jit: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("ISF_ROBOT_JIT", jit)
    rows = np.array([0, 2, 3, 1, 2, 4, 2, 3], dtype=np.intp)  # (three agents, each's rows ascending)
    ends = np.array([3, 6, 8], dtype=np.intp)
    values = np.array([0.5, 0.2, -1.0, 0.7, 0.1, np.nan, 0.3, -2.0])
    xi = np.full(5, np.inf)
    compiled(least_of)(xi, rows, ends, values)
    want = np.full(5, np.inf)
    for r, v in zip(rows, values):
        want[r] = np.minimum(want[r], v)
    np.testing.assert_array_equal(xi, want)
    np.testing.assert_array_equal(xi, [0.5, 0.7, 0.1, -2.0, np.nan])


def _step(t: float, on: bool, xi: list[float], margin: float | None) -> FilterStep:
    u = np.zeros(5)
    return FilterStep._of(t, u, u, on, np.ones(len(xi)), np.asarray(xi, dtype=float), margin=margin)


def test_coordination_counts_on_steps_with_a_shared_row_below_the_margin() -> None:
    c = Coordination()
    shared = np.array([False, True])
    dt = 0.002
    seq = [
        (False, [-1.0, -1.0]),  # off: never counted
        (True, [-1.0, 0.5]),  # on, but only the own row below the margin
        (True, [1.0, 0.05]),  # shared row below the margin 0.1: counted (an event)
        (True, [1.0, 0.0]),  # still: counted, no new event
        (True, [1.0, 0.2]),  # above: not counted
        (True, [1.0, -0.3]),  # again: counted, a second event
    ]
    for i, (on, xi) in enumerate(seq):
        c.add(Coordination.needs(_step(i * dt, on, xi, 0.1), shared), dt)
    steps, events, time = c.of(0)
    assert (steps, events) == (3, 2)
    assert time == pytest.approx(3 * dt)
    c.add(Coordination.needs(_step(1.0, True, [1.0, -1.0], None), np.zeros(2, dtype=bool)), dt)  # no shared row
    assert c.of(0)[0] == 3
    c.add(Coordination.needs(_step(1.1, True, [1.0, -0.01], None), shared), dt)  # no margin given: 0
    assert c.of(0)[:2] == (4, 3)
    c.reset()
    assert c.of(0) == (0, 0, 0.0)


def test_central_coordination_counts_an_agent_only_for_rows_it_shares() -> None:
    """Three agents, one filter: a row between agents 0 and 1 below the margin is not agent 2's need."""
    involves = np.array([[True, True, False],  # row 0: agents 0 and 1
                         [False, True, True],  # row 1: agents 1 and 2
                         [False, False, True]])  # row 2: agent 2 alone
    shared = involves.sum(axis=1) > 1
    c = Coordination(3)
    c.add(Coordination.needs(_step(0.0, True, [-0.1, 0.5, -1.0], 0.05), shared, involves), 0.002)
    assert [c.of(i)[0] for i in range(3)] == [1, 1, 0]  # (row 2 is below too, but agent 2 shares it with nobody)
    c.add(Coordination.needs(_step(0.002, True, [0.5, -0.1, 0.5], 0.05), shared, involves), 0.002)
    assert [c.of(i)[:2] for i in range(3)] == [(1, 1), (2, 1), (1, 1)]
    c.add(Coordination.needs(_step(0.004, False, [-0.5, -0.5, -0.5], 0.05), shared, involves), 0.002)  # off
    assert [c.of(i)[0] for i in range(3)] == [1, 2, 1]


def _plan(lg: np.ndarray, blocks: tuple[slice, ...]) -> tuple:
    """row_plan's outputs for ``lg`` (compiled or not, as ``ISF_ROBOT_JIT`` says)."""
    k, a = lg.shape[0], len(blocks)
    cols, col_ends, _ = SharedRows(blocks)._cols(lg.shape[1])
    out = (np.empty((a, k), bool), np.empty(k, np.int64), np.empty(a * k, np.intp), np.empty(a, np.intp),
           np.empty(a * k), np.empty(a * k, bool), np.empty(a, bool))
    n = compiled(row_plan)(lg, cols, col_ends, *out)
    return n, out


@pytest.mark.parametrize("jit", ["1", "0"])
@pytest.mark.parametrize("blocks", [(slice(0, 2), slice(2, 5), slice(5, 7)), (slice(0, 7, 2), slice(1, 7, 2))])
def test_row_plan_is_row_agents_and_each_agents_rows_shares_and_flags(jit: str, blocks, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The one pass of a new set of rows: row_agents' answer, and per agent its rows, shares and shared flags."""
    monkeypatch.setenv("ISF_ROBOT_JIT", jit)
    rng = np.random.default_rng(5)
    for _ in range(20):
        lg = rng.normal(size=(int(rng.integers(0, 12)), 7))
        lg[rng.random(size=lg.shape) < 0.5] = 0.0
        lg[rng.random(size=lg.shape[0]) < 0.2] = 0.0  # (rows of no agent)
        n, (by_agent, count, rows, ends, share, shared_of, flags) = _plan(lg, blocks)
        inv = row_agents(lg, blocks)
        np.testing.assert_array_equal(by_agent.T, inv)
        np.testing.assert_array_equal(count, inv.sum(axis=1))
        r0 = 0
        for a in range(len(blocks)):
            mine = np.flatnonzero(inv[:, a])
            np.testing.assert_array_equal(rows[r0:ends[a]], mine)
            np.testing.assert_array_equal(share[r0:ends[a]], 1.0 / inv[mine].sum(axis=1))
            np.testing.assert_array_equal(shared_of[r0:ends[a]], inv[mine].sum(axis=1) > 1)
            assert flags[a] == bool((inv[mine].sum(axis=1) > 1).any())
            r0 = ends[a]
        assert n == r0 == inv.sum()
    lg = rng.normal(size=(3, 7))
    for bad in (np.nan, np.inf):
        lg[1, 6] = bad
        assert _plan(lg, blocks)[0] == -1  # (refused: SharedRows then raises as row_agents does)
        with pytest.raises(NonFiniteError):
            SharedRows(blocks)(_lie(lg, ("a", "b", "c")))


def test_a_new_set_of_names_is_looked_at_again_not_taken_from_the_cache() -> None:
    """The cache is per set of names: other names (another set of near pairs) give that set's own answer."""
    shared = SharedRows(BLOCKS)
    lg = np.array([[1.0, 0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0, 0.0]])
    first = shared(_lie(lg, ("a|b", "a|x")))
    np.testing.assert_array_equal(first.shared, [True, False])
    lg2 = np.array([[1.0, 0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 2.0, 0.0], [0.0, 0.0, 0.0, 0.0, 3.0]])
    second = shared(_lie(lg2, ("a|y", "a|b", "b|z")))  # (another set: one more row, the shared row second)
    assert second is not first
    np.testing.assert_array_equal(second.inv, row_agents(lg2, BLOCKS))
    np.testing.assert_array_equal(second.shared, [False, True, False])
    np.testing.assert_array_equal(second.order[0], [0, 1, 1, 2])
    assert [p[3] for p in second.parts] == [("a|y", "a|b"), ("a|b", "b|z")]
    assert shared(_lie(lg, ("a|b", "a|x"))) is first  # (the first set again: kept)


def test_ranges_are_the_columns_of_each_agent_where_they_are_ranges() -> None:
    rows = SharedRows((slice(0, 2), slice(2, 5)))
    col0, col1, widths, starts, size = rows._ranges(5)
    np.testing.assert_array_equal(col0, [0, 2])
    np.testing.assert_array_equal(col1, [2, 5])
    assert (list(widths), list(starts), size) == ([2, 3], [0, 2], 5)
    cols, ends, w = rows._cols(5)
    np.testing.assert_array_equal(cols, np.arange(5))
    np.testing.assert_array_equal(ends, [2, 5])
    assert SharedRows((slice(0, 4, 2), slice(1, 4, 2)))._ranges(4) is None  # (every other column: no range)
    assert rows._ranges(6)[1].tolist() == [2, 5] and rows._cols(6)[1].tolist() == [2, 5]  # (another width: made again)


@pytest.mark.parametrize("jit", ["1", "0"])
def test_team_least_is_least_of_and_each_agents_coordination_need(jit: str, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """One call: least_of from inf, and per agent Coordination.needs of its step (on, a shared row below its margin)."""
    monkeypatch.setenv("ISF_ROBOT_JIT", jit)
    rng = np.random.default_rng(7)
    rows = np.array([0, 2, 3, 1, 2, 4, 2, 3], dtype=np.intp)
    ends = np.array([3, 6, 8], dtype=np.intp)
    for _ in range(50):
        values = rng.normal(size=8)
        values[rng.random(8) < 0.1] = np.nan
        shared_of = rng.random(8) < 0.5
        margins = rng.choice([0.0, 0.05, 0.5], size=3)
        on = rng.random(3) < 0.7
        xi, need = np.empty(6), np.empty(3, bool)
        compiled(team_least)(xi, rows, ends, values, shared_of, margins, on, need)
        want = np.full(6, np.inf)
        least_of(want, rows, ends, values)
        np.testing.assert_array_equal(xi, want)
        r0 = 0
        for a in range(3):
            step = _step(0.0, bool(on[a]), values[r0:ends[a]].tolist(), float(margins[a]))
            assert need[a] == bool(Coordination.needs(step, shared_of[r0:ends[a]])[0])
            r0 = ends[a]


def test_add_need_counts_as_add() -> None:
    """An agent's tally given its need counts the steps, events and time that add() counts from the step."""
    one, two = AgentTally("a"), AgentTally("a")
    shared = np.array([False, True])
    for i, (on, xi) in enumerate([(False, [-1.0, -1.0]), (True, [1.0, 0.05]), (True, [1.0, 0.0]), (True, [1.0, 0.5]),
                                  (True, [1.0, -0.3]), (False, [1.0, -0.3])]):
        st = _step(i * 0.002, on, xi, 0.1)
        one.add(st, shared, 0.002)
        two.add_need(st, bool(Coordination.needs(st, shared)[0]), 0.002)
    assert one.coordination.of(0) == two.coordination.of(0) == (3, 2, pytest.approx(0.006))
    assert one.result() == two.result()


class _Recorder:
    """A strategy that passes the nominal through and keeps each step's rows' names and keyword arguments."""

    uses_rows, on = True, False

    def __init__(self, intermittent: bool) -> None:
        self.intermittent = intermittent
        self.calls: list[tuple[tuple[str, ...], dict]] = []

    def reset(self, t0: float = 0.0) -> None:
        self.calls.clear()

    def step_lie(self, t, lie, u_nom, x=None, **kw):  # type: ignore[no-untyped-def]
        self.calls.append((lie.names, {k: np.array(v) if isinstance(v, np.ndarray) else v for k, v in kw.items()}))
        return FilterStep._of(t, u_nom, u_nom, False, lie.h, np.ones(lie.k), margin=0.05)


@pytest.mark.parametrize("promote_shared", [False, True])
def test_shared_filter_hands_each_agent_its_rows_screen_and_promotable_rows(promote_shared: bool) -> None:
    """What each agent's step is given: its rows' screen thresholds (read at every step: an array rewritten in place
    gives its new values) and, for an intermittent agent, its rows that are not shared; other keywords pass through."""
    a, b = _Recorder(True), _Recorder(False)
    team = SharedFilter([a, b], BLOCKS, ("a", "b"), 0.002, promote_shared=promote_shared)
    lg = np.array([[1.0, 0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0, 0.0]])  # (row 0 shared, row 1 agent a's)
    lg2 = np.array([[0.0, 0.0, 1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 2.0, 0.0], [1.0, 0.0, 0.0, 0.0, 0.0]])
    first, second = _lie(lg, ("a|b", "a|x")), _lie(lg2, ("b|y", "a|b", "a|z"))
    s1, s2, s3 = np.array([0.1, 0.2]), np.array([0.3, 0.4]), np.array([0.5, 0.6, 0.7])
    u = np.zeros(5)
    for t, lie, screen, kw in [(0.0, first, s1, {}), (0.002, first, s1, {}), (0.004, first, s2, {}),
                               (0.006, second, s3, {}), (0.008, second, None, {"extra": 1}), (0.01, first, s1, {})]:
        team.step_lie(t, lie, u, screen=screen, **kw)
    prom = {} if promote_shared else None
    want_a = [(("a|b", "a|x"), [0.1, 0.2], [False, True]), (("a|b", "a|x"), [0.1, 0.2], [False, True]),
              (("a|b", "a|x"), [0.3, 0.4], [False, True]), (("a|b", "a|z"), [0.6, 0.7], [False, True]),
              (("a|b", "a|z"), None, [False, True]), (("a|b", "a|x"), [0.1, 0.2], [False, True])]
    want_b = [(("a|b",), [0.1]), (("a|b",), [0.1]), (("a|b",), [0.3]), (("b|y", "a|b"), [0.5, 0.6]),
              (("b|y", "a|b"), None), (("a|b",), [0.1])]
    for (names, kw), (want_names, want_screen, want_prom) in zip(a.calls, want_a):
        assert names == want_names
        assert kw.get("extra", 1) == 1
        assert (kw.get("screen") is None if want_screen is None else kw["screen"].tolist() == want_screen)
        assert ("promotable" not in kw) if prom is not None else kw["promotable"].tolist() == want_prom
    for (names, kw), (want_names, want_screen) in zip(b.calls, want_b):
        assert names == want_names and "promotable" not in kw  # (not intermittent: no promotion to limit)
        assert (kw.get("screen") is None if want_screen is None else kw["screen"].tolist() == want_screen)
    assert len(a.calls) == len(b.calls) == 6 and "extra" in a.calls[4][1] and "extra" in b.calls[4][1]
    s1[:] = [0.8, 0.9]  # (the same array, rewritten in place)
    team.step_lie(0.012, first, u, screen=s1)
    assert a.calls[-1][1]["screen"].tolist() == [0.8, 0.9] and b.calls[-1][1]["screen"].tolist() == [0.8]
