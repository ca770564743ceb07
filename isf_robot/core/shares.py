"""Which agents each row of a team's filter involves, and each agent's share of a row it shares.

The input is the agents' inputs stacked, ``u = (u_1, ..., u_a)``; agent ``i`` owns the columns
``blocks[i]`` of every row's ``Lg h``. A row *involves* agent ``i`` when its ``Lg h`` has a non-zero
entry in agent ``i``'s columns (:func:`row_agents`). Agent ``i``'s share of a row that involves the agents
``S`` is ``s_i = 1 / |S|``, and its row is ``(h, lf, lg_i / s_i, |dh/dx|)`` (:func:`agent_lie`): the
decentralised filter's split of the robust condition (:mod:`isf_robot.core.team`, whose docstring states
the safety argument). :class:`SharedRows` keeps the answer per set of row names.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from operator import itemgetter
from typing import Any

import numpy as np

from .exceptions import NonFiniteError
from .intermittent import StackedPoints
from .jit import compiled, formula
from .system import LieData

__all__ = ["block_matrix", "row_agents", "involved", "gather_rows", "row_plan", "split_points", "agent_lie",
           "SharedRows"]

_NO_I = np.zeros(0, np.intp)


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
    s = np.abs(lg) @ M
    if not np.isfinite(s).all():  # (a row nobody would get: its constraint would be dropped without a word)
        bad = np.flatnonzero(~np.isfinite(s).all(axis=1)).tolist()
        raise NonFiniteError(f"team rows: Lg h not finite in rows {bad}")
    return s > 0.0


@formula
def involved(lg, c0, c1, out):  # type: ignore[no-untyped-def]
    """Whether each row of ``lg`` (k, m) involves the agent of the columns ``c0:c1``, into ``out`` (k,), bool.

    :func:`row_agents`' test for one agent whose columns are a range: ``sum |Lg h| > 0`` over them (a sum of
    absolute values is positive exactly where one of them is). A row whose sum is not finite is the agent's too,
    so that its non-finite values reach the agent's prediction, which refuses them (:func:`row_agents` refuses
    them at once). Loops over the entries: it runs compiled (:func:`split_points`).
    """
    for r in range(lg.shape[0]):
        s = 0.0
        for c in range(c0, c1):
            s += abs(lg[r, c])
        out[r] = s > 0.0 or not s < math.inf


@formula
def gather_rows(h: np.ndarray, lf: np.ndarray, lg: np.ndarray, grad_norm: np.ndarray, rows: np.ndarray,
                ends: np.ndarray, cols: np.ndarray, col_ends: np.ndarray, share: np.ndarray, scaled: np.ndarray,
                out_h: np.ndarray, out_lf: np.ndarray, out_gn: np.ndarray, out_lg: np.ndarray) -> None:
    """Agents' rows ``(h, lf, lg[:, cols] / share, |dh/dx|)``, agent after agent (see the module docstring).

    Agent ``a``: the rows ``rows[ends[a - 1]:ends[a]]`` (``ends[-1]`` read as 0), its columns
    ``cols[col_ends[a - 1]:col_ends[a]]``, its share of each of those rows ``share[ends[a - 1]:ends[a]]``
    (divided by only where ``scaled[a]``: a share of 1 leaves the row as it is). Written to ``out_h``,
    ``out_lf``, ``out_gn`` (one entry per row of ``rows``) and ``out_lg`` (flat: each agent's rows by its
    columns, row by row, after the agents before it). One call for every agent, in array operations per agent
    (as fast as numpy runs it; compiled by numba where the kernels run, :class:`_Involved.split`). An agent's
    columns that are a range (a slice's, step 1) are taken in one indexing, others picked one by one.
    """
    out_h[:] = h[rows]
    out_lf[:] = lf[rows]
    out_gn[:] = grad_norm[rows]
    p = 0
    r0 = c0 = 0
    for a in range(ends.shape[0]):
        r1, c1 = ends[a], col_ends[a]
        step1 = c1 > c0
        for i in range(c0, c1):  # (a range: each column the one before plus 1)
            if cols[i] != cols[c0] + (i - c0):
                step1 = False
                break
        if step1:
            block = lg[rows[r0:r1], cols[c0]: cols[c1 - 1] + 1]
        else:
            block = lg[rows[r0:r1]][:, cols[c0:c1]]
        dst = out_lg[p: p + block.size].reshape(r1 - r0, c1 - c0)
        if scaled[a]:
            np.divide(block, share[r0:r1].reshape(r1 - r0, 1), dst)
        else:
            dst[:] = block
        p += block.size
        r0, c0 = r1, c1


@formula
def row_plan(lg: np.ndarray, cols: np.ndarray, col_ends: np.ndarray, by_agent: np.ndarray, count: np.ndarray,
             rows: np.ndarray, ends: np.ndarray, share: np.ndarray, shared_of: np.ndarray, flags: np.ndarray) -> int:
    """Which agents each row of ``lg`` (k, m) involves, and every agent's rows with their shares, in one pass.

    Agent ``a`` owns the columns ``cols[col_ends[a - 1]:col_ends[a]]`` (``col_ends[-1]`` read as 0). Its test is
    :func:`row_agents`': ``sum |Lg h| > 0`` over its columns, into ``by_agent[a]`` (``by_agent``: shape (a, k), bool;
    :func:`row_agents`' answer transposed). ``count`` (k,): how many agents each row involves. Then every agent's
    rows, agent after agent, each agent's ascending, into ``rows`` (and where each agent's end into ``ends``), its
    share of each ``1 / count`` into ``share``, whether each is shared (``count > 1``) into ``shared_of``, and
    whether any of its rows is shared into ``flags[a]``. Returns the number of those rows, or -1 where a sum is
    not finite (nothing else is then to be read: :func:`row_agents` refuses such rows). In array operations per
    agent (as numpy runs it; compiled where the kernels run: :class:`SharedRows`).
    """
    count[:] = 0
    e0 = 0
    for a in range(col_ends.shape[0]):
        e1 = col_ends[a]
        s = np.zeros(lg.shape[0])
        for c in range(e0, e1):  # (the sum column after column, as involved() takes it)
            s += np.abs(lg[:, cols[c]])
        if not np.isfinite(s).all():
            return -1
        mine = s > 0.0
        by_agent[a] = mine
        count += mine
        e0 = e1
    p = 0
    for a in range(col_ends.shape[0]):
        idx = np.flatnonzero(by_agent[a])
        n = idx.shape[0]
        c = count[idx]
        rows[p: p + n] = idx
        share[p: p + n] = 1.0 / c
        shared_of[p: p + n] = c > 1
        flags[a] = (c > 1).any()
        p += n
        ends[a] = p
    return p


def split_points(h, lf, lg, grad_norm, k, keys, col0, col1, lg_at, out_k, out_h, out_lf, out_gn, out_lg,
                 out_keys):  # type: ignore[no-untyped-def]
    """Every agent's rows of every stacked point, as :meth:`_Involved.split` makes them point by point.

    (A row whose ``Lg h`` is not finite: :func:`row_agents` refuses it there; here it goes to the agents
    (:func:`involved`), whose prediction refuses it.)

    Point ``j``'s rows are the first ``k[j]`` of ``h[j]``, ``lf[j]``, ``lg[j]`` (K, m), ``grad_norm[j]`` and
    ``keys[j]``; agent ``a`` owns the columns ``col0[a]:col1[a]`` (``w`` of them). Its rows of point ``j``: those
    that involve it (:func:`involved`), ascending, each divided by its share ``1 / (agents of the row)`` where any
    of them is shared: :func:`gather_rows` of every agent, once per point. Their count goes to ``out_k[a, j]``,
    their values to the first entries of ``out_h[a, j]``, ``out_lf[a, j]``, ``out_gn[a, j]`` and ``out_keys[a, j]``,
    their ``Lg h`` columns row after row to the flat ``out_lg`` from ``lg_at[a] + j K w`` (agent ``a``'s (n, K, w)
    block, ``K = out_h.shape[2]``). One call for every point (compiled where the kernels run:
    :meth:`SharedRows.split_points`).
    """
    na, big = col0.shape[0], out_h.shape[2]
    widths = col1 - col0
    cols = np.empty(widths.sum(), np.intp)
    col_ends = np.cumsum(widths).astype(np.intp)
    for a in range(na):
        cols[col_ends[a] - widths[a]: col_ends[a]] = np.arange(col0[a], col1[a])
    kmax = k.max() if k.shape[0] else 0
    inv = np.empty((na, kmax), np.bool_)
    count = np.empty(kmax)
    rows = np.empty(na * kmax, np.intp)
    share = np.empty(na * kmax)
    ends = np.empty(na, np.intp)
    scaled = np.empty(na, np.bool_)
    th, tlf, tgn = np.empty(na * kmax), np.empty(na * kmax), np.empty(na * kmax)
    tlg = np.empty(kmax * cols.shape[0])
    for j in range(h.shape[0]):
        kj = k[j]
        lgj = lg[j, :kj]
        for a in range(na):
            involved(lgj, col0[a], col1[a], inv[a, :kj])
        for r in range(kj):
            count[r] = inv[:, r].sum()
        p = 0
        for a in range(na):  # (agent after agent, each agent's rows ascending, as _Involved.split gathers them)
            scaled[a] = False
            for r in range(kj):
                if inv[a, r]:
                    rows[p], share[p] = r, 1.0 / count[r]
                    scaled[a] = scaled[a] or count[r] > 1.0
                    p += 1
            ends[a] = p
        gather_rows(h[j], lf[j], lgj, grad_norm[j], rows[:p], ends, cols, col_ends, share[:p], scaled, th[:p],
                    tlf[:p], tgn[:p], tlg)
        r0 = q = 0
        for a in range(na):
            ka, w = ends[a] - r0, widths[a]
            out_k[a, j] = ka
            out_h[a, j, :ka] = th[r0: r0 + ka]
            out_lf[a, j, :ka] = tlf[r0: r0 + ka]
            out_gn[a, j, :ka] = tgn[r0: r0 + ka]
            for i in range(ka):
                out_keys[a, j, i] = keys[j, rows[r0 + i]]
            at = lg_at[a] + j * big * w
            out_lg[at: at + ka * w] = tlg[q: q + ka * w]
            r0, q = r0 + ka, q + ka * w


def agent_lie(lie: LieData, block: slice, rows: np.ndarray, share: np.ndarray,
              names: tuple[str, ...] | None = None, scaled: bool = True) -> LieData:
    """Agent's rows: ``(h, lf, lg[:, block] / share, |dh/dx|)`` of the rows ``rows`` (see the module docstring).

    :func:`gather_rows` for one agent (:meth:`_Involved.split` makes every agent's in one call).

    Args:
        lie: The team's rows.
        block: The agent's columns.
        rows: Indices of the rows that involve the agent, shape (k_i,).
        share: The agent's share of each of those rows, in (0, 1], shape (k_i,).
        names: Those rows' names, if at hand (:attr:`_Involved.parts` keeps one tuple per set of names, so
            that what is kept per names object downstream, e.g. the hand-over's weights, is found again).
        scaled: Whether any share is below 1 (``False``: every share is 1, nothing to divide).

    """
    if names is None:
        names = tuple(lie.names[r] for r in rows) if lie.names else ()
    rows = np.asarray(rows, dtype=np.intp)
    cols = np.arange(lie.lg.shape[1], dtype=np.intp)[block]
    k, w = rows.shape[0], cols.shape[0]
    out = np.empty(k), np.empty(k), np.empty(k), np.empty(k * w)
    compiled(gather_rows)(lie.h, lie.lf, lie.lg, lie.grad_norm, rows, np.array([k], np.intp), cols,
                          np.array([w], np.intp), np.asarray(share, dtype=float), np.array([bool(scaled)]), *out)
    return LieData._of(out[0], out[1], out[3].reshape(k, w), out[2], names)


class SharedRows:
    """Which rows involve several agents (:func:`row_agents`), kept per set of row names.

    A row's agents follow from which bodies its pair joins, so rows with the same names (the tuple
    :class:`LieData` shares between ticks with the same near pairs) are looked at once. Rows without
    names are looked at every time. The names object of the last call is checked first (by identity: the
    names are not hashed while the near pairs stay the same).
    """

    LIMIT = 4096
    """Most sets of names kept (the cache is emptied when full)."""

    def __init__(self, blocks: Sequence[slice]) -> None:
        self.blocks = tuple(blocks)
        self._M: np.ndarray | None = None
        self._cache: dict[tuple[str, ...], _Involved] = {}
        self._pools: tuple[dict[tuple[str, ...], tuple[str, ...]], ...] = tuple({} for _ in self.blocks)
        a = len(self.blocks)
        self._last = _Involved(np.zeros((a, 0), bool).T, np.zeros(0, np.intp), np.zeros(0, bool),
                               (_NO_I, np.zeros(a, np.intp), np.zeros(0), np.zeros(0, bool), np.zeros(a, bool)))
        self._colmap: tuple[int, tuple[np.ndarray, np.ndarray, tuple[int, ...]], tuple | None] | None = None
        self._gather = compiled(gather_rows)  # (ISF_ROBOT_JIT is read here, when the rows' split is set up)
        self._split = compiled(split_points)
        self._plan = compiled(row_plan)

    def _cols(self, m: int) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
        """The agents' columns of ``m`` inputs, one after the other, their ends, and each agent's count."""
        got = self._colmap
        if got is None or got[0] != m:
            got = self._colmap = self._columns(m)
        return got[1]

    def _columns(self, m: int) -> tuple[int, tuple[np.ndarray, np.ndarray, tuple[int, ...]], tuple | None]:
        """``(m, (columns, ends, counts), ranges)``: :meth:`_cols`' answer, and :meth:`_ranges`' made from it."""
        every = np.arange(m, dtype=np.intp)
        each = [every[b] for b in self.blocks]
        widths = tuple(c.shape[0] for c in each)
        cols = np.concatenate(each) if each else _NO_I
        ends = np.cumsum(widths, dtype=np.intp)
        ranges = None
        if all(c.shape[0] == 0 or (np.diff(c) == 1).all() for c in each):  # (each agent's columns a range)
            col0 = np.array([int(c[0]) if c.shape[0] else 0 for c in each], np.int64)
            starts = (ends - np.asarray(widths, np.intp)).astype(np.int64)
            ranges = (col0, col0 + np.asarray(widths, np.int64), list(widths), starts, int(sum(widths)))
        return m, (cols, ends, widths), ranges

    def split_points(self, points: Any) -> list[StackedPoints] | None:
        """Every agent's rows of stacked points (:class:`~.intermittent.StackedPoints` with keys), or ``None``.

        Agent ``i``'s points: each point's rows as :meth:`_Involved.split` makes them (the rows that involve it,
        ascending, divided by its share), its columns of the commands, keys and key names as the points'; made for
        every point and agent in one compiled call (:func:`split_points`). ``None`` (split the points one by one)
        for other points, without keys, where an agent's columns are not a range, or where the call is not compiled
        (``ISF_ROBOT_JIT=0``, or ``cached`` before numba's cache holds it: its loops run slowly as written).
        """
        if not hasattr(self._split, "py_func"):  # (not compiled: its loops as written are slower than point by point)
            return None
        keys = points.keys if type(points) is StackedPoints else None
        lg = points.lg if keys is not None else None
        if type(lg) is not np.ndarray or lg.ndim != 3:
            return None
        plan = self._ranges(lg.shape[2])
        if plan is None:
            return None
        col0, col1, widths, starts, size = plan
        n, big = points.h.shape[0], max(points._rows, default=0)  # (an agent has at most its point's rows)
        lg_at = starts * (n * big)  # (agent a's (n, K, w) block of Lg h in the flat output)
        na = len(widths)
        out_k, out_keys = np.empty((na, n), np.int64), np.empty((na, n, big), np.int64)
        out_h, out_lf, out_gn, out_lg = np.empty((na, n, big)), np.empty((na, n, big)), np.empty((na, n, big)), \
            np.empty(n * big * size)
        self._split(points.h, points.lf, lg, points.grad_norm, points.rows, keys, col0, col1, lg_at, out_k, out_h,
                    out_lf, out_gn, out_lg, out_keys)
        s, u, names = points.s, points.u, points.key_names
        got = []
        for a, w in enumerate(widths):
            at = int(lg_at[a])
            ka, lga, ha, lfa, gna, kya = out_k[a], out_lg[at: at + n * big * w].reshape(n, big, w), out_h[a], \
                out_lf[a], out_gn[a], out_keys[a]
            got.append(StackedPoints._of(s, np.ascontiguousarray(u[:, int(col0[a]):int(col1[a])]), ka, ka.tolist(), ha,
                                         lfa, lga, gna, _point_of(ka, ha, lfa, lga, gna, kya, names), None, kya, names))
        return got

    def _ranges(self, m: int) -> tuple | None:
        """The agents' column ranges of ``m`` inputs, or ``None`` where a block is not a range.

        ``(first columns, ends, widths, the widths before each agent, sum of widths)``: the columns of
        :meth:`_cols` (kept per ``m`` with them).
        """
        got = self._colmap
        if got is None or got[0] != m:
            got = self._colmap = self._columns(m)
        return got[2]

    def __call__(self, lie: LieData) -> _Involved:
        """The agents of each row of ``lie`` (:class:`_Involved`)."""
        key = lie.names
        last = self._last
        if key is last.names and key and last.count.shape[0] == lie.k:
            return last  # (the same names object as the last call's: no hashing of the names)
        if key:
            hit = self._cache.get(key)
            if hit is not None and hit.count.shape[0] == lie.k:
                self._last = hit
                return hit
        lg = lie.lg
        k, a = lg.shape[0], len(self.blocks)
        cols = self._cols(lg.shape[1])
        by_agent, count = np.empty((a, k), np.bool_), np.empty(k, np.int64)
        rows, ends, share, shared_of, flags = np.empty(a * k, np.intp), np.empty(a, np.intp), np.empty(a * k), \
            np.empty(a * k, np.bool_), np.empty(a, np.bool_)
        n = self._plan(lg, cols[0], cols[1], by_agent, count, rows, ends, share, shared_of, flags)
        if n < 0:  # (a sum not finite: refused, as row_agents refuses it)
            if self._M is None or self._M.shape[0] != lie.m:
                self._M = block_matrix(self.blocks, lie.m)
            row_agents(lg, self._M)  # (raises, naming the rows)
            raise NonFiniteError("team rows: Lg h not finite")  # (a sum that overflows only in row_plan's order)
        out = _Involved(by_agent.T, count, count > 1, (rows[:n], ends, share[:n], shared_of[:n], flags), key,
                        self._pools, cols, self._gather)
        if key:
            if len(self._cache) >= self.LIMIT:
                self._cache.clear()
                for pool in self._pools:
                    pool.clear()
            self._cache[key] = out
        self._last = out
        return out


def _point_of(k: np.ndarray, h: np.ndarray, lf: np.ndarray, lg: np.ndarray, gn: np.ndarray, keys: np.ndarray,
              names: Any) -> Callable[[int], LieData]:
    """``point(j)``: an agent's split point ``j`` as :class:`LieData` (views; its rows' names from the keys)."""
    def point(j: int) -> LieData:
        kj = int(k[j])
        names_j = tuple([names[i] for i in keys[j, :kj].tolist()])
        return LieData._of(h[j, :kj], lf[j, :kj], lg[j, :kj], gn[j, :kj], names_j)

    return point


class _Involved:
    """The agents of a set of rows.

    ``inv``: :func:`row_agents`, shape (k, a); ``count``: how many agents each row involves, shape (k,);
    ``shared``: ``count > 1``; ``order``: :func:`row_plan`'s every agent's rows, agent after agent, where each
    agent's end, its share of each, which of them are shared, and which agents have a shared row;
    :attr:`parts` (made at the first use): per agent, ``(its rows, its share of each, which of them are shared,
    their names)``; :attr:`steps` (made with it): per agent, ``(which of its rows are not shared, whether any
    is)``. An agent's names tuple is the one an earlier set of rows gave it when the names are the same
    (``pools``, one dict per agent, kept by :class:`SharedRows`): what an agent's filter keeps per names object
    (its hand-over's keys) is found again when other agents' rows changed. ``cols``: the agents' columns one
    after the other, their ends and each agent's count; ``gather``: :func:`gather_rows`, compiled or not
    (:meth:`split`).
    """

    __slots__ = ("inv", "count", "shared", "names", "_order", "_pools", "_cols", "_gather", "_parts", "_steps",
                 "_plan")

    def __init__(self, inv: np.ndarray, count: np.ndarray, shared: np.ndarray,
                 order: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray], names: tuple[str, ...] = (),
                 pools: Sequence[dict[tuple[str, ...], tuple[str, ...]]] = (),
                 cols: tuple[np.ndarray, np.ndarray, tuple[int, ...]] | None = None,
                 gather: Callable[..., None] = gather_rows) -> None:
        self.inv, self.count, self.shared, self.names = inv, count, shared, names
        self._order, self._pools, self._cols, self._gather = order, pools, cols, gather
        self._parts: tuple[tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]], ...] | None = None
        self._steps: tuple[tuple[np.ndarray, bool], ...] = ()
        self._plan: tuple[Any, ...] = ()

    @property
    def parts(self) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]], ...]:
        """Per agent ``(rows, share, shared, names)`` (see the class docstring)."""
        if self._parts is None:
            self._make()
        return self._parts  # type: ignore[return-value]

    @property
    def steps(self) -> tuple[tuple[np.ndarray, bool], ...]:
        """Per agent ``(not shared, any shared)`` of its rows (see the class docstring)."""
        if self._parts is None:
            self._make()
        return self._steps

    @property
    def order(self) -> tuple[np.ndarray, np.ndarray]:
        """Every agent's rows (:attr:`parts`), agent after agent, in one array, and where each agent's end."""
        return self._order[0], self._order[1]

    def order_shared(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:attr:`order`, and which of those rows are shared (the agents' :attr:`parts` ``shared``, in turn)."""
        return self._order[0], self._order[1], self._order[3]

    def split(self, lie: LieData) -> list[LieData]:
        """Every agent's rows of ``lie`` (these rows' data), as :func:`agent_lie` makes them, in one pass.

        :func:`gather_rows` (compiled where the kernels run) into one fresh array per field; agent ``i``'s data
        are views of its part (C-contiguous, float64).
        """
        if self._parts is None:
            self._make()
        rows, ends, share, scaled, views, size = self._plan
        cols, col_ends, _ = self._cols  # type: ignore[misc]
        k = rows.shape[0]
        h, lf, gn, lg = np.empty(k), np.empty(k), np.empty(k), np.empty(size)
        self._gather(lie.h, lie.lf, lie.lg, lie.grad_norm, rows, ends, cols, col_ends, share, scaled, h, lf, gn, lg)
        return [LieData._of(h[r], lf[r], lg[p].reshape(shape), gn[r], names) for r, p, shape, names in views]

    def _make(self) -> None:
        """Make :attr:`parts`, :attr:`steps` and :meth:`split`'s plan from :attr:`order` (once per set of rows)."""
        parts, steps = [], []
        names, pools = self.names, self._pools
        every, ends, shares, shared_of, flags = self._order
        own_of = ~shared_of
        picked_all = every.tolist() if names else []
        flag_list = flags.tolist()
        r0 = 0
        for i, r1 in enumerate(ends.tolist()):
            its: tuple[str, ...] = ()
            if names:
                picked = picked_all[r0:r1]
                its = itemgetter(*picked)(names) if len(picked) > 1 else tuple(names[r] for r in picked)
                if i < len(pools):
                    its = pools[i].setdefault(its, its)
            parts.append((every[r0:r1], shares[r0:r1], shared_of[r0:r1], its))
            steps.append((own_of[r0:r1], flag_list[i]))
            r0 = r1
        self._parts, self._steps = tuple(parts), tuple(steps)
        if self._cols is None:  # (made without SharedRows: every agent's columns unknown; split is not offered)
            return
        widths = self._cols[2]
        views, r0, p0 = [], 0, 0
        for (rows, _, _, its), w in zip(parts, widths):
            r1 = r0 + rows.shape[0]
            p1 = p0 + rows.shape[0] * w
            views.append((slice(r0, r1), slice(p0, p1), (rows.shape[0], w), its))
            r0, p0 = r1, p1
        self._plan = (every, ends, shares, flags, tuple(views), p0)
