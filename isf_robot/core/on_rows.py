"""The intermittent filter's on step before its QP, the compiled way: promoted rows, hand-over ramp, kept rows.

:class:`OnRows` keeps the hand-over ramp's weights per key (a row's name, or its index when the
names do not match the rows) in arrays, so that one kernel call
(:func:`~isf_robot.core._step_jit.on_rows`) makes what
:meth:`~isf_robot.core.filters.IntermittentSafetyFilter._row_ramp` and the row screening make in
Python and numpy: the same masks, weights and kept rows, bit for bit
(``tests/core/test_intermittent.py``, ``tests/core/test_fast_step.py``). Used when the filter
has the compiled kernels (:func:`~isf_robot.core.fast.step_kernels`); a filter keeps one of the
two ways for its whole life (the weights live in one of them).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["OnRows"]

_NONE_I = np.zeros(0, np.intp)
_NONE_F = np.zeros(0)


class OnRows:
    """The per-key ramp weights and the kernel that updates them (see the module docstring).

    Args:
        kernel: :func:`~isf_robot.core._step_jit.on_rows`.

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
        self._out: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # per row count: mask, weights, rows

    def clear(self) -> None:
        """Drop every weight (the filter switched off)."""
        self._inw[:] = False

    def weights(self) -> dict[Any, float]:
        """The weights by key (as ``_row_ramp``'s dict holds them; for tests and inspection)."""
        return {key: float(self._w[i]) for key, i in self._id_of.items() if self._inw[i]}

    def _ids_of(self, names: tuple[str, ...], k: int) -> np.ndarray:
        """Each row's key index (made once per names object and row count)."""
        if names is not self._names or k != self._k:
            keys = names if len(names) == k else range(k)
            id_of = self._id_of
            ids = np.fromiter((id_of.setdefault(key, len(id_of)) for key in keys), np.intp, k)
            if len(id_of) > self._w.shape[0]:  # (room for the new keys, the weights kept)
                size = 2 * len(id_of)
                self._w = np.concatenate((self._w, np.zeros(size - self._w.shape[0])))
                self._inw = np.concatenate((self._inw, np.zeros(size - self._inw.shape[0], bool)))
            self._names, self._k, self._ids = names, k, ids
        return self._ids

    def __call__(self, xi: np.ndarray, c: float, failing: np.ndarray, rate: float | None, names: tuple[str, ...],
                 screen: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """``(promote, ramp weights, kept rows)`` of one on step.

        The rows to promote (``xi < c`` or ``failing``, ramped), their weights (``None`` without the
        ramp: ``rate`` ``None``) and the rows kept by ``screen`` (``None``: no thresholds given).

        The three arrays are this object's own, rewritten by the next call: they serve one filter step.
        """
        k = xi.shape[0]
        ramp_on = rate is not None
        out = self._out.get(k)
        if out is None:
            out = self._out[k] = (np.empty(k, bool), np.empty(k), np.empty(k, np.intp))
        mask, weights, rows = out
        n = self.kernel(xi, c, failing, ramp_on, self._ids_of(names, k) if ramp_on else _NONE_I, self._w, self._inw,
                        rate if ramp_on else 0.0, screen, mask, weights if ramp_on else _NONE_F, rows)
        return mask, weights if ramp_on else None, None if n < 0 else rows[:n]
