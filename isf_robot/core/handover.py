"""The intermittent filter's hand-over: no step in the command at its switches beyond what safety needs.

* After an off switch the command blends from the last filtered command to the nominal one with the
  weight :func:`blend_weight` (1 at the switch, 0 after ``blend`` seconds).
* While on, each promoted row ramps from the robust condition to the promoted one: its weight ``w``
  (:func:`~isf_robot.core.robust.promotion_level`) moves by at most ``dt / blend`` per step, up while
  the row is promoted (from 0 when it enters), down once it is not (dropped at 0), so neither a row
  entering nor one leaving the promotion set steps the command. Weights are kept per row key (its
  name, or its index when the names do not match the rows), so a row keeps its weight when the set of
  rows changes between steps.

:func:`promote_rows` is a plain function over numpy arrays, compiled as it is by
:func:`~isf_robot.core.jit.compiled` (alone, or within the on step's one call:
:func:`~isf_robot.core.closed_step.promoted_closed_step`); :class:`PromotionRamp` keeps its per-key state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .jit import formula

__all__ = ["blend_weight", "promote_rows", "PromotionRamp"]

_NONE_I = np.zeros(0, np.intp)
_NONE_F = np.zeros(0)


def blend_weight(t: float, t_switch: float | None, blend: float) -> float:
    """Weight of the pre-switch command ``1 - (t - t_switch) / blend`` in [0, 1] (0 without a blend)."""
    if blend <= 0.0 or t_switch is None:
        return 0.0
    return min(1.0, max(0.0, 1.0 - (t - t_switch) / blend))


@formula
def promote_rows(xi: np.ndarray, c: float, failing: np.ndarray, ramp_on: bool, ids: np.ndarray, W: np.ndarray,
                 inw: np.ndarray, rate: float, mask: np.ndarray, weights: np.ndarray) -> None:
    """The rows the on filter promotes (``mask``) and, with ``ramp_on``, their hand-over weights.

    ``mask = xi < c`` or ``failing`` (no entries: none). With ``ramp_on``: ``ids[i]`` is row ``i``'s
    key, ``W``/``inw`` each key's weight and whether it has one; a key is promoted now when its last
    row is; every other key with a weight moves down by ``rate`` (dropped at <= 0), a promoted one up
    by ``rate`` (at most 1; a new one starts at 0); then ``mask``/``weights`` are the rows whose key
    has a weight >= 0 (and that weight; 1 elsewhere).
    """
    mask[:] = xi < c
    if failing.shape[0]:
        mask[:] = mask | failing
    if not ramp_on:
        return
    nid = W.shape[0]
    cur = np.full(nid, -1, np.int8)  # per key: promoted now (its last row) 1, not 0, not a row now -1
    for i in range(xi.shape[0]):
        cur[ids[i]] = 1 if mask[i] else 0
    for q in range(nid):
        if cur[q] == 1:
            if inw[q]:
                W[q] = min(1.0, W[q] + rate)
            else:
                W[q] = 0.0
                inw[q] = True
        elif inw[q]:
            W[q] -= rate
            if W[q] <= 0.0:
                inw[q] = False
    for i in range(xi.shape[0]):
        q = ids[i]
        if inw[q] and W[q] >= 0.0:
            mask[i] = True
            weights[i] = W[q]
        else:
            mask[i] = False
            weights[i] = 1.0


class PromotionRamp:
    """The per-key hand-over weights and the pass that updates them (see the module docstring).

    Args:
        kernel: :func:`promote_rows`, compiled or not.

    """

    def __init__(self, kernel: Callable[..., Any]) -> None:
        self.kernel = kernel
        self.reset()

    def reset(self) -> None:
        """Forget every key and weight."""
        self._id_of: dict[Any, int] = {}  # key -> its index in the weight arrays
        self._w = np.zeros(32)
        self._inw = np.zeros(32, bool)  # whether the key has a weight
        self._names: Any = None  # the names tuple (and row count) _ids was made for
        self._k = -1
        self._ids = _NONE_I
        self._out: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # per row count: mask, weights

    def clear(self) -> None:
        """Drop every weight (the filter switched off)."""
        self._inw[:] = False

    def weights(self) -> dict[Any, float]:
        """The weights by key (for tests and inspection)."""
        return {key: float(self._w[i]) for key, i in self._id_of.items() if self._inw[i]}

    def _ids_of(self, names: tuple[str, ...], k: int) -> np.ndarray:
        """Each row's key index (made once per names object and row count)."""
        if names is not self._names or k != self._k:
            keys = names if len(names) == k else range(k)
            id_of = self._id_of
            ids = np.array([id_of.setdefault(key, len(id_of)) for key in keys], np.intp)
            if len(id_of) > self._w.shape[0]:  # (room for the new keys, the weights kept)
                size = 2 * len(id_of)
                self._w = np.concatenate((self._w, np.zeros(size - self._w.shape[0])))
                self._inw = np.concatenate((self._inw, np.zeros(size - self._inw.shape[0], bool)))
            self._names, self._k, self._ids = names, k, ids
        return self._ids

    def arrays(self, k: int, rate: float | None, names: tuple[str, ...]) -> tuple[np.ndarray, ...]:
        """:func:`promote_rows`' arrays for ``k`` rows: ``(ids, W, inw, mask, weights)`` (``rate`` ``None``: no ramp).

        ``ids`` and ``weights`` have no entries without the ramp; ``mask`` and ``weights`` are this object's own,
        rewritten by the next call: they serve one filter step.
        """
        out = self._out.get(k)
        if out is None:
            out = self._out[k] = (np.empty(k, bool), np.empty(k))
        if rate is None:
            return _NONE_I, self._w, self._inw, out[0], _NONE_F
        ids = self._ids_of(names, k)  # (first: new keys may replace the weight arrays)
        return ids, self._w, self._inw, out[0], out[1]

    def __call__(self, xi: np.ndarray, c: float, failing: np.ndarray, rate: float | None,
                 names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
        """``(promote, ramp weights)`` of one on step (no weights without the ramp: ``rate`` ``None``).

        The arrays of :meth:`arrays`, rewritten by the next call.
        """
        ids, W, inw, mask, weights = self.arrays(xi.shape[0], rate, names)
        self.kernel(xi, c, failing, rate is not None, ids, W, inw, 0.0 if rate is None else rate, mask, weights)
        return mask, weights
