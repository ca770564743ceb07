"""The collision kernel's output blocks: handed out as if fresh, an allocation reused once nothing holds it.

The packed kernel (``_kernels_jit.near_packed_key``) writes a state's rows into a float64 block of its
context's layout (``h``, ``dh/dq``, ``|dh/dq|``, ``dh/dt``, witness points) and the near pairs' indices into an
int64 row; the narrow phase hands out views of them (:class:`~isf_robot.arm.rows.TickRows`, the rollout's
points). A block is as large as every live pair's rows (some 440 kB for four arms) while a state fills a few of
them, so a new allocation per control step costs more than the kernel's work on it.

:class:`BlockPool` keeps a few allocations of one layout and reuses one only when no view of it is alive
anywhere: each allocation's arrays are referenced by the pool alone (their reference counts back to what they
were when it was made), so a result kept past a step (a recorded step's ``h``, a caller's rows) keeps its
allocation out of use and is never overwritten. What a caller gets is as fresh as a new allocation's.
"""

from __future__ import annotations

import sys

import numpy as np

__all__ = ["BlockPool", "REUSE"]

_refs = sys.getrefcount


def _held(a: list) -> tuple[int, int, int]:
    """References to an allocation's float, int and gradient arrays (the pool's own included).

    The gradient view counts too: :meth:`BlockPool.take_all` hands it out as it is, and a caller that keeps only it
    holds the memory (its views' own base is the float array).
    """
    return _refs(a[0]), _refs(a[1]), _refs(a[2])


def _views_counted() -> bool:
    """Whether a view of an array shows in the array's reference count here (else nothing is reused)."""
    a = [np.empty(2), np.empty(1), np.empty(1)]
    before = _held(a)
    view = a[0][:1]
    counted = _held(a)[0] == before[0] + 1
    del view
    return counted and _held(a) == before


REUSE = _views_counted()
"""Whether :class:`BlockPool` reuses allocations (the interpreter counts references as CPython does)."""


class BlockPool:
    """Output blocks of one layout, ``count`` per allocation; at most :attr:`KEEP` allocations are kept for reuse.

    Args:
        size: Floats per block (the layout's, ``_kernels_jit.near_packed_key``).
        m: Rows of a block's gradient (its (m, n) view from float ``m`` on).
        n: Columns of that view (the model's joints).
        ints: Int64 entries per block (the live pairs; at least 1).
        count: Blocks per allocation.

    :meth:`take` hands out one block at a time (a control tick's), :meth:`take_all` a whole allocation (a
    rollout's points, one block each).

    """

    KEEP = 4
    """Allocations kept for reuse (a new one replaces the oldest kept when every kept one is held)."""

    def __init__(self, size: int, m: int, n: int, ints: int, count: int) -> None:
        self.size, self.m, self.n, self.ints, self.count = int(size), int(m), int(n), max(int(ints), 1), int(count)
        self._allocs: list[list] = []
        self._cur: list | None = None
        self._next = self.count
        self.made = 0
        """Allocations made so far (for tests and benchmarks: the rest of the hand-outs were reuses)."""

    def __getstate__(self) -> dict:
        """A copy or a pickle starts with no allocations.

        An allocation's gradient array is a view of its float block, which a copy would make a separate array (the
        kernel's writes would not reach it).
        """
        state = dict(self.__dict__)
        state["_allocs"], state["_cur"], state["_next"] = [], None, self.count
        return state

    def _alloc(self) -> list:
        """A free allocation: the oldest kept one nothing else holds, else a new one (in place of the oldest)."""
        for a in self._allocs if REUSE else ():
            if _held(a) == a[3]:
                return a
        count, m = self.count, self.m
        flat = np.empty((count, self.size))
        a = [flat, np.empty((count, self.ints), dtype=np.int64), flat[:, m: m + m * self.n].reshape(count, m, self.n),
             (0, 0)]
        del flat
        a[3] = _held(a)
        if len(self._allocs) >= self.KEEP:
            del self._allocs[0]
        self._allocs.append(a)
        self.made += 1
        return a

    def take(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The next block: ``(blk, rows, g)``, the float block (size,), its int64 row and its (m, n) gradient view."""
        i = self._next
        a = self._cur
        if i >= self.count or a is None:
            a = self._cur = self._alloc()
            i = 0
        self._next = i + 1
        return a[0][i], a[1][i], a[2][i]

    def take_all(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A whole allocation: ``(blk, g, rows)`` of shapes (count, size), (count, m, n) and (count, ints)."""
        a = self._alloc()
        if a is self._cur:  # (take's current allocation: it starts another at its next call)
            self._next = self.count
        return a[0], a[2], a[1]
