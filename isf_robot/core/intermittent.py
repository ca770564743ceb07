"""What the intermittent filter adds to its on/off trigger: designed off periods and a smooth hand-over.

Three optional parts of :class:`~isf_robot.core.filters.IntermittentSafetyFilter` (each off by
default, so a filter built without them behaves exactly as before):

* **A minimum off time by design** (:class:`FallRateBound`). An off period starts with every
  ``Xi_on >= c`` and ends when some ``Xi_on`` reaches 0, so if ``min_i Xi_on`` falls no faster
  than ``R`` while the filter is off, every off period lasts at least ``c / R`` -- the paper's
  MIET ``tau = c / (L_Xi (B + d_bar))`` (Proposition 1) with the product ``L_Xi (B + d_bar)``,
  the largest rate of change of ``Xi`` along the flow, replaced by ``R``. ``R`` is *measured*:
  the fall rate of ``min_i Xi_on`` between consecutive off-mode steps (the state then moves under
  the nominal command), a running maximum that forgets with time constant ``forget_s``. Asked
  for ``min_off`` seconds, the filter uses the off margin ``c_eff = clip(min_off R, c, c_max)``
  and reports the bound ``c_eff / R`` at every off switch beside the measured off periods. A
  measured rate is not a proof: the measured minimum off period is always reported too.
* **A predictive off trigger** (:class:`OffPredictor`). When the off condition holds, the filter
  asks a rollout callback for the nominal controller rolled forward on the reduced model
  ``q_dot = u_nom(q)`` over a horizon, computes ``Xi_on`` at the predicted points with its own
  ``alpha`` and ``d_bar`` (:func:`~isf_robot.core.robust.robust_slack`: the formula lives once), and
  turns off only if every predicted ``Xi_on > 0``. Rows predicted to fail are promoted while the
  filter stays on, steering toward states with a longer off time. The prediction only *delays*
  switching off at ``c``; with ``c_pred < c`` (the filter's option) it may also switch off *early*, at
  every ``Xi_on >= c_pred``, when the rollout predicts every ``Xi_on > 0`` over the horizon, so the
  promotion stops as soon as the nominal is predicted safe instead of pushing on to ``c``. Either way
  the on trigger is monitored exactly as before and the robust condition is enforced whenever it
  binds, so Theorem 1 is untouched (``c_pred > 0`` keeps the hysteresis; the off period's length now
  rests on the prediction, and the measured off periods are reported). The
  rollout runs at most once every ``every`` control steps (its cost per step is bounded).
* **A smooth hand-over** (:mod:`isf_robot.core.handover`). For ``blend`` seconds after an off switch the
  command moves linearly from the last filtered command to the nominal one, projected onto the
  robust barrier conditions (the standard filter's QP with the blended target), so the only step
  in the command is the one safety requires; for ``blend`` seconds after an on switch the
  promotion level ramps from the robust condition ``-alpha(h)`` to ``b`` (never below the robust
  condition).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from itertools import compress
from typing import Any

import numpy as np

from .class_k import ClassK, Linear
from .exceptions import ConfigError, NonFiniteError, ShapeError
from .jit import compiled
from .miet import miet_bound
from .robust import predict_pass, robust_slack
from .system import LieData
from .validation import check_nonnegative

__all__ = ["FallRateBound", "OffPredictor", "Prediction", "RolloutFn", "StackedPoints", "pass_prediction"]

_F64 = np.dtype(np.float64)
_new, _set = object.__new__, object.__setattr__

RolloutFn = Callable[[float, Any], Sequence[tuple[float, LieData, np.ndarray]]]
"""``rollout(t, x) -> [(s, lie, u_nom), ...]``: predicted barrier data and nominal command at times
``t + s`` (``0 < s <= horizon``) of the nominal controller rolled forward on the reduced model from
the state ``x`` the adapter passed to ``step_lie`` (``None`` if it passed none).

A rollout may also offer ``rollout.prediction(t, x, alpha, d_bar) -> Prediction | None``: what
:func:`predict` of ``rollout(t, x)`` gives, in one go (the arm's compiled rollout: its points and their
``Xi_on`` in one call), or ``None`` where it cannot (:class:`OffPredictor` then takes the points and
predicts)."""


class FallRateBound:
    """Measured bound ``R`` on how fast ``min_i Xi_on`` falls while the filter is off.

    Args:
        prior: Rate assumed before any measurement [units of Xi per s] (0: none).
        forget_s: Time constant [s] with which the running maximum decays (``inf``: a plain
            running maximum over the run).

    """

    def __init__(self, prior: float = 0.0, forget_s: float = 2.0) -> None:
        self.prior = check_nonnegative(prior, "prior fall rate")
        if not forget_s > 0:
            raise ConfigError(f"forget_s (fall-rate memory) must be > 0 [s] (inf: never forget), got {forget_s}")
        self.forget_s = float(forget_s)
        self.reset()

    def reset(self) -> None:
        """Forget every measurement."""
        self.rate = self.prior
        self._t: float | None = None
        self._xi = 0.0
        self.samples = 0

    def observe(self, t: float, xi_min: float, off: bool) -> None:
        """Record ``min_i Xi_on`` at time ``t``; ``off``: the filter was off since the previous sample.

        Only intervals spent off (the state moving under the nominal command) measure the rate.
        """
        finite = math.isfinite(xi_min)
        if off and finite and self._t is not None and t > self._t:
            dt = t - self._t
            fall = (self._xi - xi_min) / dt
            decayed = self.rate * math.exp(-dt / self.forget_s)
            self.rate = max(fall, decayed, 0.0)
            self.samples += 1
        self._t, self._xi = (t, xi_min) if finite else (None, 0.0)

    def margin(self, min_off: float, c_min: float, c_max: float) -> float:
        """Off margin ``clip(min_off R, c_min, c_max)`` that makes off periods last ``min_off`` at rate ``R``."""
        return min(c_max, max(c_min, min_off * self.rate))

    def bound_s(self, c: float) -> float:
        """Shortest off period the margin ``c`` guarantees at fall rate ``R`` [s] (``inf`` at ``R = 0``)."""
        return miet_bound(c, self.rate, 1.0) if self.rate > 0 else math.inf


@dataclass(frozen=True)
class Prediction:
    """The outcome of one rollout.

    Attributes:
        ok: Every predicted ``Xi_on`` is > 0 over the horizon.
        xi_min: Smallest predicted ``Xi_on`` (``inf`` without points).
        first_fail_s: Time from now of the first predicted point with some ``Xi_on <= 0``
            (``None`` when ok).
        failing: Names of the rows predicted to reach ``Xi_on <= 0``.
        points: Predicted points evaluated.

    """

    ok: bool
    xi_min: float
    first_fail_s: float | None
    failing: frozenset[str]
    points: int


class StackedPoints(Sequence[tuple[float, LieData, np.ndarray]]):
    """Predicted points whose rows sit in stacked arrays: a :data:`RolloutFn` result a compiled rollout can hand over.

    A sequence of ``(s, lie, u)`` like any rollout's list. Point ``j`` has ``rows[j]`` rows: its
    barrier data are ``h[j, :rows[j]]``, ``lf[j, :rows[j]]``, ``lg[j]`` (its first ``rows[j]`` rows)
    and ``grad_norm[j, :rows[j]]``, its command ``u[j]``, its time ``s[j]``. ``point(j)`` builds point
    ``j``'s :class:`LieData` (on first use; kept): it must hold exactly these numbers with the rows' names, which
    ``row_names(j, rows)`` gives alone for some rows (default: read from ``point(j).names``).
    :func:`predict` reads the arrays in one compiled pass and asks for the names only of the rows
    predicted to fail.

    Args:
        s: Times ahead [s], one per point.
        u: Commands, shape (n, m), float64.
        rows: Rows per point, shape (n,), int64, each at most K.
        h, lf, grad_norm: Shape (n, K), float64.
        lg: One array per point, shape (rows[j], m), float64; or one float64 array of shape (n, K, m)
            (point ``j``'s rows ``lg[j, :rows[j]]``: a compiled rollout's block, read as it is).
        point: ``point(j) -> LieData`` of point ``j``.
        row_names: ``row_names(j, rows) -> [name, ...]``: the names of those rows of point ``j``, each
            ``point(j).names[i]`` (``str(i)`` past the end of the names) (``None``: read from ``point(j)``).
        keys, key_names: Optional, together: an int64 array of shape (n, K) with ``key_names[keys[j, i]]``
            the name of row ``i`` of point ``j`` (for ``i < rows[j]``; the rest is not read). With
            them :func:`predict` finds the failing rows' names in one compiled pass (each name once)
            instead of asking ``row_names`` point by point; a key outside ``key_names`` is an error
            there.

    """

    __slots__ = ("s", "u", "rows", "h", "lf", "lg", "grad_norm", "_rows", "_point", "_row_names", "_items", "keys",
                 "key_names")

    def __init__(self, s: Sequence[float], u: np.ndarray, rows: np.ndarray, h: np.ndarray, lf: np.ndarray,
                 lg: Sequence[np.ndarray], grad_norm: np.ndarray, point: Callable[[int], LieData],
                 row_names: Callable[[int, list[int]], list[str]] | None = None, keys: np.ndarray | None = None,
                 key_names: Sequence[str] | None = None) -> None:
        n, shape, kl = len(s), h.shape, rows.tolist()
        if not (u.ndim == 2 and u.shape[0] == n and rows.shape == (n,) and h.ndim == 2 and shape[0] == n
                and lf.shape == shape and grad_norm.shape == shape and rows.dtype == np.int64 and u.dtype == _F64
                and h.dtype == _F64 and lf.dtype == _F64 and grad_norm.dtype == _F64 and len(lg) == n
                and (n == 0 or min(kl) >= 0 and max(kl) <= shape[1])
                and (keys is None) == (key_names is None)
                and (keys is None or type(keys) is np.ndarray and keys.shape == shape and keys.dtype == np.int64)):
            raise ShapeError(f"stacked points: s ({n},), u (n, m), rows (n,) int64 in [0, K], h/lf/grad_norm (n, K) "
                             f"float64, lg one per point, keys (n, K) int64 with key_names or neither; "
                             f"got u {u.shape}, "
                             f"rows {kl}, h {shape}, lf {lf.shape}, grad_norm {grad_norm.shape}, {len(lg)} lg, keys "
                             f"{None if keys is None else (np.shape(keys), getattr(keys, 'dtype', None))}")
        self.keys, self.key_names = keys, key_names
        self.s, self.u, self.rows, self.h, self.lf, self.lg, self.grad_norm = list(s), u, rows, h, lf, lg, grad_norm
        self._rows = kl
        self._point = point
        self._row_names = row_names
        self._items: list[tuple[float, LieData, np.ndarray] | None] = [None] * n

    @classmethod
    def _of(cls, s: Sequence[float], u: np.ndarray, rows: np.ndarray, kl: list[int], h: np.ndarray, lf: np.ndarray,
            lg: Sequence[np.ndarray], grad_norm: np.ndarray, point: Callable[[int], LieData],
            row_names: Callable[[int, list[int]], list[str]] | None, keys: np.ndarray | None,
            key_names: Sequence[str] | None) -> StackedPoints:
        """The points, unchecked (``kl``: ``rows.tolist()``): for a producer that lays them out as above itself.

        The compiled rollout of :mod:`isf_robot.arm.rollout` builds its arrays to this layout on
        every call (``tests/arm/test_predict_stacked_arm.py`` checks them against the checked constructor).
        """
        self = object.__new__(cls)
        self.s, self.u, self.rows, self.h, self.lf, self.lg, self.grad_norm = s, u, rows, h, lf, lg, grad_norm  # type: ignore[assignment]
        self._rows, self._point, self._row_names, self.keys, self.key_names = kl, point, row_names, keys, key_names
        self._items = [None] * len(s)
        return self

    def __len__(self) -> int:
        return len(self.s)

    def __getitem__(self, j: int) -> Any:  # (an int: the point; a slice: a list of points)
        if isinstance(j, slice):
            return [self[i] for i in range(*j.indices(len(self.s)))]
        item = self._items[j]
        if item is None:
            j = range(len(self.s))[j]  # (negative indices; out of range: IndexError)
            item = self._items[j] = (self.s[j], self._point(j), self.u[j])
        return item

    def __iter__(self) -> Iterator[tuple[float, LieData, np.ndarray]]:
        return (self[j] for j in range(len(self.s)))

    def row_names(self, j: int, rows: list[int]) -> list[str]:
        """The names of ``rows`` of point ``j`` (``str(i)`` for a row past the end of its names)."""
        if self._items[j] is None and self._row_names is not None:
            return self._row_names(j, rows)
        names = self[j][1].names
        nn = len(names)
        return [names[i] if i < nn else str(i) for i in rows]


def _lg_block(lg: Sequence[np.ndarray] | np.ndarray, shape: tuple[int, ...], m: int, kl: list[int]) -> np.ndarray:
    """The points' ``Lg h`` as one float64 (n, K, m) array (``lg`` itself when it is one)."""
    if type(lg) is np.ndarray and lg.dtype == _F64 and lg.shape == (*shape, m):
        return lg
    block = np.zeros((*shape, m))
    for j, a in enumerate(lg):
        block[j, :kl[j]] = np.asarray(a, dtype=float)[:kl[j]]
    return block


_NO_AV = np.zeros((0, 0))
_NO_KEYS = np.zeros((0, 0), np.int64)
_NO_NAMES: frozenset[str] = frozenset()


def _predict_stacked(points: StackedPoints, alpha: ClassK, d_bar: float, kernel: Callable[..., Any]) -> Prediction:
    """:func:`predict` of stacked points in one pass of ``kernel`` (:func:`~.robust.predict_pass`, compiled or not)."""
    h, k, kl, u = points.h, points.rows, points._rows, points.u
    m = u.shape[1]
    lg = _lg_block(points.lg, h.shape, m, kl)
    if type(alpha) is Linear:  # (alpha(h) = gain h, made in the pass)
        av = _NO_AV
        gain = alpha.gain
    else:
        av = np.zeros(h.shape)
        gain = 0.0
        for j, kj in enumerate(kl):
            av[j, :kj] = alpha.vector(h[j, :kj])  # (the point's h: the same array as its lie.h)
    xi = np.empty(h.shape)
    fails = np.empty(h.shape, np.int64)
    nfail = np.empty(len(kl), np.int64)
    keys, names = points.keys, points.key_names
    nk = 0 if names is None else len(names)
    out = np.empty(fails.size if keys is not None else 0, np.int64)
    run = kernel if m > 0 else predict_pass
    c = np.ascontiguousarray  # (strided points, as a team's split hands them over, are copied: numba compiles the
    # pass for one layout, not again for each mix of layouts)
    bad, xi_lo, found = run(c(points.lf), c(lg), c(u), c(points.grad_norm), float(d_bar), c(h), gain, av, k,
                            xi, fails, nfail, _NO_KEYS if keys is None else keys, np.zeros(nk, np.bool_), out)
    return pass_prediction(points.s, k, xi, fails, bad, xi_lo, nfail, found, out, names, points)


def pass_prediction(s: Sequence[float], rows: np.ndarray, xi: np.ndarray, fails: np.ndarray, bad: int, xi_lo: float,
                    nfail: np.ndarray, found: int, out: np.ndarray, key_names: Sequence[str] | None,
                    points: StackedPoints | None = None) -> Prediction:
    """The :class:`Prediction` from the answer of :func:`~isf_robot.core.robust.predict_pass` over stacked points.

    ``s``: the points' times ahead; ``rows``, ``xi``, ``fails``, ``nfail``, ``out``: the pass's arrays, ``(bad, xi_lo,
    found)`` its answer. The failing rows' names: ``key_names`` of the keys in ``out[:found]`` or, without key
    names, ``points.row_names``. Raises :class:`NonFiniteError` at a point whose values are not finite.
    """
    if bad >= 0:
        raise NonFiniteError(f"predicted Xi_on not finite {s[bad]:.3g} s ahead: {xi[bad, :rows[bad]]}")
    nf = nfail.tolist()
    first = min(compress(s, nf), default=None)  # (the first time ahead with failing rows)
    failing = _NO_NAMES
    if first is not None:
        if key_names is not None:  # (the failing rows' keys, each once, from the pass)
            if found < 0:
                nk = len(key_names)
                raise ShapeError(f"stacked points: a failing row's key lies outside key_names (0..{nk - 1})")
            failing = frozenset([key_names[i] for i in out[:found].tolist()])
        elif points is not None:
            names: set[str] = set()
            for j, c in enumerate(nf):
                if c:
                    names.update(points.row_names(j, fails[j, :c].tolist()))
            failing = frozenset(names)
    pred = _new(Prediction)  # (a frozen dataclass's __dict__ set whole, without the field-by-field __init__)
    _set(pred, "__dict__", {"ok": first is None, "xi_min": float(xi_lo), "first_fail_s": first, "failing": failing,
                            "points": len(nf)})
    return pred


def predict(points: Sequence[tuple[float, LieData, np.ndarray]], alpha: ClassK, d_bar: float, *,
            kernel: Callable[..., Any] | None = None) -> Prediction:
    """Evaluate ``Xi_on`` at every predicted point; see :class:`Prediction`.

    Each point's ``Xi_on`` is :func:`~isf_robot.core.robust.robust_slack` under its command;
    :class:`StackedPoints` go in one pass over every point (compiled where the kernels run).
    ``kernel``: that pass, :func:`~isf_robot.core.robust.predict_pass` compiled or not (``None``: compiled where
    ``ISF_ROBOT_JIT`` allows, read now; a caller that predicts often takes it once, as :class:`OffPredictor` does).
    """
    if type(points) is StackedPoints:
        return _predict_stacked(points, alpha, d_bar, compiled(predict_pass) if kernel is None else kernel)
    xi_lo = math.inf
    first: float | None = None
    failing: set[str] = set()
    for s, lie, u in points:
        if lie.h.size == 0:
            continue
        xi = robust_slack(lie.lf, lie.lg @ np.asarray(u, dtype=float), lie.grad_norm, d_bar, alpha.vector(lie.h))
        xl = xi.tolist()
        if not math.isfinite(sum(xl)):
            raise NonFiniteError(f"predicted Xi_on not finite {s:.3g} s ahead: {xi}")
        lo = min(xl)
        xi_lo = min(xi_lo, lo)
        if lo <= 0.0:
            first = s if first is None else min(first, s)
            names, nn = lie.names, len(lie.names)
            failing.update([names[i] if i < nn else str(i) for i, v in enumerate(xl) if v <= 0.0])
    return Prediction(first is None, xi_lo, first, frozenset(failing), len(points))


class OffPredictor:
    """Gate of the off switch by a rollout, run at most once every ``every`` control steps.

    :meth:`check` is called at each step where the off condition holds; it runs the rollout on
    the first such step and then every ``every``-th step while the condition keeps holding,
    returning the last outcome in between (the rollout's own ``prediction`` where it offers one and
    answers, else :func:`predict` of its points: see :data:`RolloutFn`). :meth:`idle` (the condition does not
    hold, or the filter switched) restarts the count.

    Args:
        rollout: The rollout callback (:data:`RolloutFn`).
        every: Steps between rollouts, >= 1.

    """

    def __init__(self, rollout: RolloutFn, every: int = 5) -> None:
        if not callable(rollout):
            raise ConfigError("rollout must be callable rollout(t, x) -> [(s, lie, u_nom), ...]")
        if int(every) != every or int(every) < 1:
            raise ConfigError(f"predict_every must be a whole number of control steps >= 1, got {every}")
        self.rollout = rollout
        self.every = int(every)
        self._kernel = compiled(predict_pass)  # (ISF_ROBOT_JIT is read here, when the filter is built)
        fused = getattr(rollout, "prediction", None)
        self._fused = fused if callable(fused) else None  # (the rollout's own prediction: see RolloutFn)
        self.reset()

    def reset(self) -> None:
        """Forget the last prediction and the counts."""
        self.last: Prediction | None = None
        self._since = 0
        self.rollouts = 0

    def idle(self) -> None:
        """The off condition does not hold: the next :meth:`check` runs a rollout."""
        self.last = None
        self._since = 0

    def check(self, t: float, x: Any, alpha: ClassK, d_bar: float) -> tuple[Prediction, bool]:
        """The prediction for switching off at ``t`` from state ``x`` and whether a rollout ran for it."""
        if self.last is not None and self._since < self.every:
            self._since += 1
            return self.last, False
        pred = None if self._fused is None else self._fused(t, x, alpha, d_bar)
        self.last = predict(self.rollout(t, x), alpha, d_bar, kernel=self._kernel) if pred is None else pred
        self._since = 1
        self.rollouts += 1
        return self.last, True
