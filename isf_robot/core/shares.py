"""Which agents each row of a team's filter involves, and each agent's share of a row it shares.

The input is the agents' inputs stacked, ``u = (u_1, ..., u_a)``; agent ``i`` owns the columns
``blocks[i]`` of every row's ``Lg h``. A row *involves* agent ``i`` when its ``Lg h`` has a non-zero
entry in agent ``i``'s columns (:func:`row_agents`). Agent ``i``'s share of a row that involves the agents
``S`` is ``s_i = 1 / |S|``, and its row is ``(h, lf, lg_i / s_i, |dh/dx|)`` (:func:`agent_lie`): the
decentralised filter's split of the robust condition (:mod:`isf_robot.core.team`, whose docstring states
the safety argument). :class:`SharedRows` keeps the answer per set of row names.
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import itemgetter

import numpy as np

from .system import LieData

__all__ = ["block_matrix", "row_agents", "agent_lie", "SharedRows"]


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


def agent_lie(lie: LieData, block: slice, rows: np.ndarray, share: np.ndarray,
              names: tuple[str, ...] | None = None, scaled: bool = True) -> LieData:
    """Agent's rows: ``(h, lf, lg[:, block] / share, |dh/dx|)`` of the rows ``rows`` (see the module docstring).

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
    lg = lie.lg[rows, block]
    if scaled:  # (a share of 1 leaves the row as it is: no division where no row is shared)
        lg = lg / share[:, None]
    return LieData._of(lie.h[rows], lie.lf[rows], lg, lie.grad_norm[rows], names)


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
        self._last = _Involved(np.zeros((0, len(self.blocks)), bool), np.zeros(0, np.intp), np.zeros(0, bool))

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
        if self._M is None or self._M.shape[0] != lie.m:
            self._M = block_matrix(self.blocks, lie.m)
        inv = row_agents(lie.lg, self._M)
        count = inv.sum(axis=1)
        out = _Involved(inv, count, count > 1, key, self._pools)
        if key:
            if len(self._cache) >= self.LIMIT:
                self._cache.clear()
                for pool in self._pools:
                    pool.clear()
            self._cache[key] = out
        self._last = out
        return out


class _Involved:
    """The agents of a set of rows.

    ``inv``: :func:`row_agents`, shape (k, a); ``count``: how many agents each row involves, shape (k,);
    ``shared``: ``count > 1``; :attr:`parts` (made at the first use): per agent, ``(its rows, its share of each,
    which of them are shared, their names)``; :attr:`steps` (made with it): per agent, ``(which of its rows
    are not shared, whether any is)``. An agent's names tuple is the one an earlier set of rows gave it when
    the names are the same (``pools``, one dict per agent, kept by :class:`SharedRows`): what an agent's filter
    keeps per names object (its hand-over's keys) is found again when other agents' rows changed.
    """

    __slots__ = ("inv", "count", "shared", "names", "_pools", "_parts", "_steps")

    def __init__(self, inv: np.ndarray, count: np.ndarray, shared: np.ndarray, names: tuple[str, ...] = (),
                 pools: Sequence[dict[tuple[str, ...], tuple[str, ...]]] = ()) -> None:
        self.inv, self.count, self.shared, self.names = inv, count, shared, names
        self._pools = pools
        self._parts: tuple[tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]], ...] | None = None
        self._steps: tuple[tuple[np.ndarray, bool], ...] = ()

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

    def _make(self) -> None:
        """Make :attr:`parts` and :attr:`steps` (once per set of rows; the few array operations per agent)."""
        parts, steps = [], []
        names = self.names
        by_agent = np.ascontiguousarray(self.inv.T)
        share, own = 1.0 / self.count, ~self.shared
        any_shared = (by_agent & self.shared).any(axis=1).tolist()
        for i in range(by_agent.shape[0]):
            rows = by_agent[i].nonzero()[0]
            its: tuple[str, ...] = ()
            if names:
                picked = rows.tolist()
                its = itemgetter(*picked)(names) if len(picked) > 1 else tuple(names[r] for r in picked)
                if i < len(self._pools):
                    its = self._pools[i].setdefault(its, its)
            parts.append((rows, share[rows], self.shared[rows], its))
            steps.append((own[rows], any_shared[i]))
        self._parts, self._steps = tuple(parts), tuple(steps)
