"""The arm loop's control steps in columns: what a block observer (the Rerun recorder) receives.

The loop writes each control step into row ``i`` of preallocated arrays (:meth:`StepColumns.write`
at the control tick, :meth:`StepColumns.end_row` once the step's physics steps are done), and hands
the whole block to observers that take blocks (:meth:`Observer.on_steps
<isf_robot.core.hooks.Observer.on_steps>`) when it is full, when the run ends and when it stops
early. No per-step object is built for them and nothing is transposed back into columns: a
recorder sends ``block.t[:n]``, ``block.q[:n]``, ... as they are. Observers that want one record
per step (a live viewer, a video) still get an :class:`~isf_robot.arm.records.ArmStepRecord`
at every step; :meth:`StepColumns.record` builds the same record from a row.

A row is the control tick's state (``t``: joint positions and velocities, every body's pose, the
end effector, mocap poses: what the filter's barrier values ``h`` were computed from), the command
applied from it, and the smallest true-geometry barrier value ``dist - margin`` (each pair's own margin)
over the step's physics steps.

Shapes: ``n`` arm joints, ``k`` barriers (the collision pairs first, then the joint-limit rows;
``k_c`` collision pairs), ``m`` mocap bodies, ``B`` the model's bodies, ``C`` the block's capacity.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from isf_robot.core.jit import compiled, direct

from .records import ArmStepRecord

__all__ = ["StepColumns", "TickValues"]

_F8 = np.dtype(np.float64)
_I8 = np.dtype(np.int64)
_S8 = (8,)  # (the strides of a 1-D contiguous array of 8-byte values; an empty one's are (0,))
_NO_POINTS = np.zeros((0, 2, 3))  # (the witness points passed when a row has none)
_ONE_F8, _ONE_I8 = np.zeros(1), np.zeros(1, np.int64)  # (the types the compiled write is made for: writable, C)
_ANY_POINTS = np.zeros((2, 3, 3))[:, :2]  # (witness points of any layout: a strided view, as near's are, so not C)


def _row_kernel() -> Any:
    """The compiled row write (``_columns_jit.write_row``), or ``None`` (no numba, or ``ISF_ROBOT_JIT=0``)."""
    from isf_robot.core.jit import jit_enabled

    if not jit_enabled():
        return None
    try:
        from . import _columns_jit
    except ImportError:
        return None
    kernel = compiled(_columns_jit.write_row)
    return None if kernel is _columns_jit.write_row else kernel


class TickValues(NamedTuple):
    """The barrier values of one control tick that a step's record keeps (made fresh at every tick).

    Attributes:
        rows: Indices of the collision pairs within the cut-off, ascending, shape (j,) int64.
        h: The tick's barrier values: those pairs' ``dist - margin``, then the joint limits', shape (j + k - k_c,).
        witness: The pairs' witness points, ``witness[:, 0]`` on the robot geom and ``witness[:, 1]`` on
            the other [m], shape (j, 2 or more, 3), or ``None``.

    """

    rows: np.ndarray
    h: np.ndarray
    witness: np.ndarray | None


class StepColumns:
    """A block of consecutive control steps, one row per step (capacity ``C``).

    The loop calls :meth:`bind` once per run, then :meth:`write` and :meth:`end_row` per step, and
    :meth:`seal` before handing the block on; after :meth:`seal` the attributes below hold the
    block's first ``len(block)`` rows.

    Attributes:
        t: Time at the start of each step [s], shape (C,).
        dt: Control period [s] (the same every step).
        q, qd: Joint positions [rad] and velocities [rad/s] at ``t``, shape (C, n).
        u, u_nom: Applied and nominal commands [rad/s], shape (C, n).
        body_pos, body_quat: Every body's pose at ``t`` ([m]; (w, x, y, z)), shape (C, B, 3) and (C, B, 4).
        on, qp_solved, fallback: Filter mode, QP solved, braking fallback applied, shape (C,) bool.
        xi_min: Smallest ``Xi_on`` the filter saw (inf for ``nominal``), shape (C,).
        true_min: Smallest barrier value ``dist - margin`` of the collision pairs on the true geometry [m] over the
            step's physics steps (each pair's own margin), shape (C,) (``inf`` in a row whose physics steps did
            not finish: the last row of a run stopped by an error or Ctrl-C).
        h: Every barrier value at ``t``, shape (C, k) (pairs beyond the cut-off: ``cutoff - margin``).
        h_min: Smallest barrier value of each row, shape (C,).
        ee_pos, goal_pos: End effector at ``t`` and goal pursued [m], shape (C, 3) (goal NaN without one).
        goal_index: Goal pursued, shape (C,) int.
        mocap_pos, mocap_quat: Mocap poses at ``t`` [m], (w, x, y, z), shape (C, m, 3) and (C, m, 4).
        pair_start: Where each row's near pairs start in :attr:`pairs` and :attr:`witness`, shape (C + 1,):
            row ``i``'s are ``pairs[pair_start[i]:pair_start[i + 1]]``.
        pairs: The collision pairs within the cut-off, row after row (each row's ascending), shape (A,) int64.
        witness: Their witness points, ``[:, 0]`` on the robot geom and ``[:, 1]`` on the other [m]
            (NaN where the loop kept none), shape (A, 2, 3).
        relaxed: The names of the barriers whose promotion was relaxed, by row (rows without any: absent).
        events: The switches, by row (rows without one: absent).
        names: Barrier names, length k.
        n_collision: ``k_c``.

    Cost: with numba, :meth:`write` writes the whole row at the tick in one compiled call
    (``_columns_jit.write_row``, called directly on a table of the addresses of the block's arrays and of the
    views of ``data`` made once by :meth:`bind`): the state and commands, the scalars, ``Xi_on``'s minimum, the
    tick's values scattered into ``h``, ``h``'s minimum, the goal, the near pairs and their witness points.
    Nothing of the step is kept, and :meth:`seal` has nothing left to do for such rows. Without numba, and for a
    row whose arrays are of other types (checked at each step), the NumPy way: the state and commands
    copied into their row in one ``np.concatenate`` (the columns ``q`` to ``u_nom`` are views of one array),
    the rest of the step kept as one tuple (its scalars, and the arrays the loop makes fresh at every step,
    ``Xi_on`` and the tick's values, by reference), which :meth:`seal` turns into the block's arrays with a
    few NumPy calls over the whole stretch of rows, every :attr:`SEAL_ROWS` rows: a kept view keeps alive
    the kernel's output block it points into, and a long run of them makes every phase of the loop slower.
    A step inside a control loop costs far more per NumPy call than the same call in a tight loop, so the
    per-step part makes as few as it can. The compiled write and :meth:`seal` fill the same arrays with the
    same values (``tests/arm/test_step_columns.py`` compares the two, rows of both kinds mixed).

    """

    SEAL_ROWS = 256
    """:meth:`write` seals the block every this many rows (the loop's arrays of a row are kept until then)."""

    def __init__(self, capacity: int, n: int, names: tuple[str, ...], n_collision: int, nmocap: int,
                 dt: float, h_far: np.ndarray | None = None, goals: np.ndarray | None = None,
                 nbody: int = 0) -> None:
        c, k = int(capacity), len(names)
        if c < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity, self.names, self.n_collision, self.dt = c, tuple(names), int(n_collision), float(dt)
        self.h_far = (np.full(self.n_collision, np.inf) if h_far is None
                      else np.asarray(h_far, dtype=float).reshape(self.n_collision))
        self.size = 0
        # A row's state and commands side by side in one array, copied in one call (:meth:`write`); the
        # columns are views of it.
        b, m = int(nbody), int(nmocap)
        self._n = int(n)
        widths = (n, n, 3, 3 * b, 4 * b, 3 * m, 4 * m, n, n)
        self._row_state = np.zeros((c, sum(widths)))
        ends = np.cumsum(widths).tolist()
        cols = [self._row_state[:, e - w: e] for w, e in zip(widths, ends)]
        self.q, self.qd, self.ee_pos = cols[0], cols[1], cols[2]
        self.body_pos, self.body_quat = cols[3].reshape(c, b, 3), cols[4].reshape(c, b, 4)
        self.mocap_pos, self.mocap_quat = cols[5].reshape(c, m, 3), cols[6].reshape(c, m, 4)
        self.u, self.u_nom = cols[7], cols[8]
        self.goal_pos = np.zeros((c, 3))
        self._goals = None if goals is None else np.asarray(goals, dtype=float).reshape(-1, 3).copy()
        self.t, self.on, self.qp_solved, self.fallback = np.zeros(c), *(np.zeros(c, dtype=bool) for _ in range(3))
        self.xi_min, self.true_min, self.h_min = np.zeros(c), np.full(c, math.inf), np.zeros(c)
        self.goal_index = np.zeros(c, dtype=np.int64)
        self.h = np.zeros((c, k))
        self.pair_start = np.zeros(c + 1, dtype=np.int64)
        per_row = max(1, min(self.n_collision, 8))  # (first guess of the near pairs per row: the buffers grow)
        # (each seal fills its rows' stretch of the flat buffers; nothing reads past it, so they start unfilled)
        self._pairs, self._witness = np.empty(c * per_row, dtype=np.int64), np.empty((c * per_row, 2, 3))
        self._rows: list[tuple[Any, ...]] = []  # (the rows not sealed yet: t, on, QP, fallback, goal, Xi_on, values)
        self.relaxed: dict[int, tuple[str, ...]] = {}
        self.events: dict[int, Any] = {}
        self.sealed = 0
        self._state: tuple[Any, ...] = ()
        self._copy: Any = None  # (the compiled row write: (kernel, sources, h_far, address table), made by bind)
        self._table: np.ndarray | None = None  # (its address table, ``_copy[3]``)
        self._call: Any = None  # (the kernel called directly, made at the first compiled write)
        self._used = 0  # (near pairs in the flat buffers, rows written by the compiled write: their end)

    def __len__(self) -> int:
        return self.size

    @property
    def pairs(self) -> np.ndarray:
        """The written rows' near pairs, row after row, shape (A,) (see :attr:`pair_start`)."""
        return self._pairs[: self.pair_start[self.sealed]]

    @property
    def witness(self) -> np.ndarray:
        """Their witness points, shape (A, 2, 3)."""
        return self._witness[: self.pair_start[self.sealed]]

    def __getstate__(self) -> dict:
        """A copy or a pickle writes the NumPy way: the compiled write's table holds this object's raw addresses."""
        state = dict(self.__dict__)
        state["_copy"], state["_table"], state["_call"] = None, None, None
        return state

    def bind(self, data: Any, qpos_adr: Any, dof_adr: Any, ee_pos: np.ndarray) -> None:
        """Where :meth:`write` reads the tick's state: views of ``data`` (MuJoCo's, valid while it lives).

        Args:
            data: The run's MuJoCo data.
            qpos_adr: Addresses of the arm's joints in ``qpos`` (a slice where they are consecutive: a view).
            dof_adr: Addresses of the arm's joints in ``qvel`` (likewise).
            ee_pos: The end effector's position as kept in ``data`` (a view such as
                ``data.site_xpos[site]``), shape (3,).

        """
        nbody = self.body_pos.shape[1]
        if nbody not in (0, data.xpos.shape[0]):
            raise ValueError(f"the block keeps {nbody} body poses; the data has {data.xpos.shape[0]} bodies")
        rest = (np.asarray(ee_pos).reshape(3),)  # (views: what the tick's state is read from, in the row's order)
        if nbody:
            rest += (data.xpos.reshape(-1), data.xquat.reshape(-1))
        if self.mocap_pos.shape[1]:
            rest += (data.mocap_pos.reshape(-1), data.mocap_quat.reshape(-1))
        if isinstance(qpos_adr, slice) and isinstance(dof_adr, slice):
            parts = (data.qpos[qpos_adr], data.qvel[dof_adr], *rest)
            width = sum(p.size for p in parts) + 2 * self._n
            if width != self._row_state.shape[1]:  # (checked before anything is bound: a failed bind changes nothing)
                raise ValueError(f"the bound state holds {width - 2 * self._n} values a step; the block keeps "
                                 f"{self._row_state.shape[1] - 2 * self._n} (joints, end effector, poses)")
            fast = None
            if all(p.dtype == np.float64 and p.ndim == 1 and p.flags.c_contiguous for p in parts):
                kernel = _row_kernel()  # (the views' types are fixed: their addresses in the table)
                if kernel is not None:
                    fast = (kernel, parts)
            self._state, self._copy, self._table, self._call = (parts, None), fast, None, None
            self._point()
        else:  # (the arm's joints scattered: picked at each step)
            self._state, self._copy, self._table = (rest, (data, qpos_adr, dof_adr)), None, None

    def _point(self) -> None:
        """The compiled write's address table, on the block's arrays as they are now (again after they grow)."""
        if self._copy is None:
            return
        from ._columns_jit import table

        goals, far = self._goals, np.ascontiguousarray(self.h_far, dtype=np.float64)
        self._table = table(
            self._copy[1], row_state=self._row_state, width=self._row_state.shape[1], t=self.t, on=self.on,
            qp_solved=self.qp_solved, fallback=self.fallback, goal_index=self.goal_index, xi_min=self.xi_min,
            h=self.h, k=self.h.shape[1], n_collision=self.n_collision, h_far=far, h_min=self.h_min,
            pair_start=self.pair_start, pairs=self._pairs, witness=self._witness, goal_pos=self.goal_pos,
            goals=goals if goals is not None else self.goal_pos, n_goals=0 if goals is None else len(goals),
            capacity=self.capacity)
        self._copy = (self._copy[0], self._copy[1], far, self._table)

    def clear(self) -> None:
        """Start the next block (the arrays are reused: observers must not keep views past ``on_steps``)."""
        self.size = self.sealed = self._used = 0
        self.true_min[:] = math.inf
        self._rows.clear()
        self.relaxed.clear()
        self.events.clear()

    def write(self, t: float, step: Any, values: TickValues, goal_index: int) -> None:
        """Write one control step into the next row, at the control tick (before its physics steps).

        Args:
            t: Time at the start of the step [s].
            step: The strategy's step (``u``, ``u_nom``, ``on``, ``xi``, ``qp``, ``fallback``,
                ``relaxed``, ``event``).
            values: The tick's barrier values: kept by reference until the next seal (like ``step.xi``), so
                they must be arrays made for this step, not a buffer the caller fills again.
            goal_index: Goal pursued (its position: the block's goal table, NaN without one).

        Raises:
            IndexError: The block is full.
            RuntimeError: :meth:`bind` was not called.

        """
        if self._table is not None and not self._rows and self._write_compiled(t, step, values, goal_index):
            return
        i = self.size
        if i >= self.capacity:
            raise IndexError(f"the block is full ({self.capacity} steps)")
        if not self._state:
            raise RuntimeError("StepColumns.write needs bind(data, qpos_adr, dof_adr, ee_pos) first")
        src, pick = self._state
        u, u_nom = step.u, step.u_nom
        if u.shape[0] != self._n or u_nom.shape[0] != self._n:  # (one copy checks only the total width)
            raise ValueError(f"commands of {u.shape[0]} and {u_nom.shape[0]} joints for a block of {self._n}")
        if pick is None:  # (the row's state and commands: one copy)
            np.concatenate((*src, u, u_nom), out=self._row_state[i])
        else:
            data, qpos_adr, dof_adr = pick
            np.concatenate((data.qpos[qpos_adr], data.qvel[dof_adr], *src, u, u_nom), out=self._row_state[i])
        self._rows.append((t, step.on, step.qp is not None, step.fallback, goal_index, step.xi, values))
        if step.relaxed:
            self.relaxed[i] = tuple(step.relaxed)
        if step.event is not None:
            self.events[i] = step.event
        self.size = i + 1
        if self.size - self.sealed >= self.SEAL_ROWS:
            self.seal()

    def _write_compiled(self, t: float, step: Any, values: TickValues, goal_index: int) -> bool:
        """The next row by the compiled write (``_columns_jit.write_row``), whole; ``False``: the NumPy way instead.

        Taken when every array has the types the compiled call was made for (checked here: the call is
        direct, without numba's own checks): 1-D float64 (int64 for the pairs) and contiguous, the witness points
        3-D float64 of any layout (one call for contiguous and strided ones alike, made when first needed). The
        write itself checks the rest and writes nothing when the row does not fit (a full block, commands of
        another width, values or witness points that do not match the near pairs, a pair that is not one of the
        block's): the NumPy way then says what is wrong. The call is made for writable arrays and takes read-only
        ones as they are (the write only reads them; numba would otherwise compile it again for each mix of
        read-only arguments). It is the loop's path at every step of a recorded run, so it checks as little as
        it can in Python: a dtype and the strides of each array.
        """
        rows, tick_h, wit = values
        u, u_nom, xi = step.u, step.u_nom, step.xi
        if not (u.dtype is _F8 and u_nom.dtype is _F8 and xi.dtype is _F8 and tick_h.dtype is _F8
                and rows.dtype is _I8 and (u.strides == _S8 or _flat(u)) and (u_nom.strides == _S8 or _flat(u_nom))
                and (xi.strides == _S8 or _flat(xi)) and (tick_h.strides == _S8 or _flat(tick_h))
                and (rows.strides == _S8 or _flat(rows))):
            return False
        if wit is None:
            has, wit = False, _NO_POINTS
        elif type(wit) is np.ndarray and wit.dtype is _F8 and wit.ndim == 3:
            has = True
        else:
            return False
        call = self._call
        if call is None:
            call = self._call = direct(self._copy[0], (
                self._table, 0, 0.0, False, False, False, 0, _ONE_F8, _ONE_F8, _ONE_F8, _ONE_I8, _ONE_F8,
                _ANY_POINTS, True))
        j = rows.shape[0]
        if self._used + j > self._pairs.shape[0]:
            self._room(self._used + j)
        i = self.size
        used = call(self._table, i, float(t), bool(step.on), step.qp is not None, bool(step.fallback),
                    int(goal_index), u, u_nom, xi, rows, tick_h, wit, has)
        if used < 0:  # (a row the compiled write does not take: the NumPy way says what is wrong)
            return False
        self._used = used
        if step.relaxed:
            self.relaxed[i] = tuple(step.relaxed)
        if step.event is not None:
            self.events[i] = step.event
        self.size = self.sealed = i + 1
        return True

    def _room(self, pairs: int) -> None:
        """Room for at least ``pairs`` near pairs (and their witness points) in the flat buffers."""
        if pairs > len(self._pairs):
            size = max(pairs, 2 * len(self._pairs))
            used = int(self.pair_start[self.sealed])
            pairs, witness = np.empty(size, dtype=np.int64), np.empty((size, 2, 3))
            pairs[:used], witness[:used] = self._pairs[:used], self._witness[:used]
            self._pairs, self._witness = pairs, witness
            self._point()

    def end_row(self, true_min: float) -> bool:
        """The smallest true-geometry barrier value [m] over the physics steps of the row just written.

        Returns:
            Whether every row is now written (the loop then seals the block, hands it on and clears it).

        """
        i = self.size
        if i == 0:
            raise IndexError("end_row follows write: the block has no row yet")
        self.true_min[i - 1] = true_min
        return i >= self.capacity

    def seal(self) -> None:
        """Fill the block's arrays from the rows written since the last :meth:`seal` (or :meth:`clear`).

        A handful of NumPy calls over the whole stretch of rows (one concatenation per kind of
        per-row array), not one per row. :meth:`write` seals every :attr:`SEAL_ROWS` rows, so the
        step's own arrays (views into the kernels' output blocks) are let go soon.
        """
        a, b = self.sealed, self.size
        if b <= a:
            return
        n = b - a
        t, on, qp, fallback, goal, xi, values = zip(*self._rows)
        self.t[a:b], self.on[a:b], self.qp_solved[a:b] = t, on, qp
        self.fallback[a:b], self.goal_index[a:b] = fallback, goal
        rows, tick_h, witness = zip(*values)
        counts = np.fromiter(map(len, rows), dtype=np.int64, count=n)
        p0 = int(self.pair_start[a])
        self.pair_start[a + 1: b + 1] = p0 + np.cumsum(counts)
        p1 = int(self.pair_start[b])
        self._room(p1)
        self.xi_min[a:b] = _row_minima(xi, n)
        nc = self.n_collision
        h = self.h[a:b]
        h[:, :nc] = self.h_far
        nj = h.shape[1] - nc  # (each tick's values: its near pairs', then every joint row's)
        flat = np.concatenate(tick_h)
        start = np.cumsum(counts + nj) - (counts + nj)  # (where each row's values start in ``flat``)
        if p1 > p0:  # (every row's near pairs in one scatter)
            pairs = self._pairs[p0:p1] = np.concatenate(rows)
            h[np.repeat(np.arange(n), counts), pairs] = flat[np.repeat(start - (np.cumsum(counts) - counts), counts)
                                                              + np.arange(p1 - p0)]
            try:
                cat = np.concatenate(witness)
            except (TypeError, ValueError):  # (rows without witness points, None, or of other widths: row by row)
                cat = None
            if cat is not None:
                if cat.shape[0] != p1 - p0:
                    raise ValueError(f"witness points of {cat.shape[0]} pairs for {p1 - p0} near pairs")
                self._witness[p0:p1] = cat[:, :2]
            else:
                for r, w in enumerate(witness):
                    lo, hi = int(self.pair_start[a + r]), int(self.pair_start[a + r + 1])
                    if w is not None and len(w) != hi - lo:
                        raise ValueError(f"row {a + r}: witness points of {len(w)} pairs for {hi - lo} near pairs")
                    self._witness[lo:hi] = math.nan if w is None else w[:, :2]
        if nj:
            h[:, nc:] = flat[(start + counts)[:, None] + np.arange(nj)]
        goals, gi = self._goals, self.goal_index[a:b]
        ok = (gi >= 0) & (gi < (0 if goals is None else len(goals)))
        if goals is not None and ok.all():
            np.take(goals, gi, axis=0, out=self.goal_pos[a:b])
        else:
            self.goal_pos[a:b] = math.nan
            if goals is not None and ok.any():
                self.goal_pos[a:b][ok] = goals[gi[ok]]
        self.h_min[a:b] = h.min(axis=1) if h.shape[1] else math.inf
        self.sealed = b
        self._used = p1
        self._rows.clear()  # (only now: a seal that fails keeps its rows)

    def closest(self, i: int, m: int = 3) -> np.ndarray:
        """Indices of the (up to) ``m`` collision pairs with the smallest ``h`` at (sealed) row ``i``, closest first."""
        return np.argsort(self.h[i, :self.n_collision])[:m]

    def record(self, i: int) -> ArmStepRecord:
        """Row ``i`` as a step record (copies: the record owns its arrays)."""
        if not 0 <= i < self.size:
            raise IndexError(f"row {i} of a block of {self.size} step(s)")
        self.seal()
        names = self.names
        near = slice(int(self.pair_start[i]), int(self.pair_start[i + 1]))
        return ArmStepRecord(
            t=float(self.t[i]), dt=self.dt, q=self.q[i].copy(), qd=self.qd[i].copy(), u=self.u[i].copy(),
            u_nom=self.u_nom[i].copy(), on=bool(self.on[i]), h_min=float(self.h_min[i]),
            xi_min=float(self.xi_min[i]), true_min=float(self.true_min[i]), qp_solved=bool(self.qp_solved[i]),
            h=self.h[i].copy(), names=names, closest=tuple(names[j] for j in self.closest(i).tolist()),
            witness=self._witness[near].copy(), witness_names=tuple(names[j] for j in self._pairs[near].tolist()),
            mocap_pos=self.mocap_pos[i].copy(), mocap_quat=self.mocap_quat[i].copy(),
            ee_pos=self.ee_pos[i].copy(), goal_index=int(self.goal_index[i]), goal_pos=self.goal_pos[i].copy(),
            event=self.events.get(i), fallback=bool(self.fallback[i]), relaxed=self.relaxed.get(i, ()),
        )


def _flat(a: np.ndarray) -> bool:
    """Whether ``a`` is 1-D and contiguous (the full check, for arrays whose strides are not ``(8,)``: empty ones)."""
    return a.ndim == 1 and a.flags.c_contiguous


def _row_minima(arrays: tuple[np.ndarray, ...], n: int) -> np.ndarray:
    """Each array's smallest value (``inf`` for an empty one), shape (n,)."""
    sizes = np.fromiter(map(len, arrays), dtype=np.int64, count=n)
    mins = np.full(n, math.inf)
    if sizes.any():
        nz = np.flatnonzero(sizes)
        mins[nz] = np.minimum.reduceat(np.concatenate(arrays), (np.cumsum(sizes) - sizes)[nz])
    return mins

