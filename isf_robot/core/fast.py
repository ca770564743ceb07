"""The filter step's compiled kernel (needs ``numba``, a dependency; without it the numpy paths run).

Why: the robust slack ``Xi_on`` of every row (:func:`~isf_robot.core.triggers.xi_on`), its sum
(the finiteness check), its minimum and where it is, and the screening count, are about ten
numpy calls and list passes on a robot's 10-30 rows; their call overhead, not the arithmetic,
was a third of the standard filter's step. :func:`xi_kernel` does them in one compiled pass.

Same answers: the kernel makes the product ``Lg h u_nom`` in :func:`isf_robot.core.sums.matvec`'s
written order (as :func:`~isf_robot.core.triggers.xi_on` does: the same on every machine, where
BLAS's order is not) and then exactly the elementwise operations of
:func:`~isf_robot.core.triggers.xi_on` in its order, ``((lf + lg u) - |dh/dx| d_bar) + alpha(h)``,
each an IEEE operation that numpy and the compiled loop round alike (numba does not contract
them into fused multiply-adds without ``fastmath``); the sum runs in Python's order, and the
minimum and the first index of it are those of ``min``/``argmin``. ``tests/core/test_fast.py``
checks it bit for bit against the numpy path.

Without numba, or with ``ISF_ROBOT_JIT=0`` in the environment, :func:`xi_kernel` returns ``None``
and the filters use numpy. The first use compiles the kernel (about a second; cached in
``__pycache__`` for later processes).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from .class_k import ClassK, Linear
from .jit import jit_enabled
from .system import LieData

__all__ = ["xi_kernel", "few_kernels", "step_kernels", "StepKernels", "screen_array", "xi_pass", "NO_SCREEN"]

_STATE: dict[str, Any] = {}
_F64 = np.dtype(np.float64)
NO_SCREEN = np.zeros(0)  # the kernel's "no screening"
_NO_SCREEN = NO_SCREEN
_NO_AV = np.zeros(0)  # the kernel's "alpha is linear: gain h"
_NO_ROWS = np.zeros(0, np.intp)  # the kernel's "no screening: no rows to write"


def _off() -> bool:
    return not jit_enabled()


def _build() -> Callable[..., Any] | None:
    if _off():
        return None
    try:
        from ._xi_jit import xi_plain, xi_screen
    except ImportError:
        return None
    _STATE["plain"] = xi_plain
    return xi_screen


def few_kernels() -> tuple[Callable[..., Any], Callable[..., Any]] | None:
    """``(few_candidate, few_confirm)`` of :mod:`isf_robot.core._few_jit`, or ``None`` (no numba; ``ISF_ROBOT_JIT=0``).

    Read when a :class:`~isf_robot.core.qp_solver.QPSolver` is built.
    """
    key = os.environ.get("ISF_ROBOT_JIT", "1")
    if _STATE.get("few_key") != key:
        kernels = None
        if not _off():
            try:
                from ._few_jit import few_candidate, few_confirm
                kernels = (few_candidate, few_confirm)
            except ImportError:
                pass
        _STATE["few_key"], _STATE["few"] = key, kernels
    return _STATE["few"]


class StepKernels(NamedTuple):
    """The screened few-row step's kernels (:mod:`isf_robot.core._step_jit`)."""

    select: Callable[..., Any]
    few_step: Callable[..., Any]
    hold: Callable[..., Any]
    on_rows: Callable[..., Any]
    one_step: Callable[..., Any]


def step_kernels() -> StepKernels | None:
    """The kernels of :mod:`isf_robot.core._step_jit`, or ``None`` (no numba, or ``ISF_ROBOT_JIT=0``).

    Read when a filter is built.
    """
    key = os.environ.get("ISF_ROBOT_JIT", "1")
    if _STATE.get("step_key") != key:
        kernels = None
        if not _off():
            try:
                from ._step_jit import few_step, on_rows, one_step, screened_hold, select_rows
                kernels = StepKernels(select_rows, few_step, screened_hold, on_rows, one_step)
            except ImportError:
                pass
        _STATE["step_key"], _STATE["step"] = key, kernels
    return _STATE["step"]


def xi_kernel() -> Callable[..., Any] | None:
    """``xi_screen(lf, lgu, gn, d_bar, h, gain, av, screen, out) -> (sum, min, argmin, kept, first)``, or ``None``.

    See :mod:`isf_robot.core._xi_jit`. ``None``: numba is missing or ``ISF_ROBOT_JIT=0``.
    """
    key = os.environ.get("ISF_ROBOT_JIT", "1")
    if _STATE.get("key") != key:
        _STATE["key"], _STATE["kernel"] = key, _build()
    return _STATE["kernel"]


def screen_array(screen: float | np.ndarray | None, k: int) -> np.ndarray | None:
    """Screening thresholds as the kernel takes them: none, one for every row, or one per row of ``k``.

    ``None`` (a shape or type the kernel does not take): the caller uses numpy, which broadcasts
    or refuses it as before.
    """
    if screen is None:
        return _NO_SCREEN
    if type(screen) is np.ndarray:
        if screen.dtype == _F64 and screen.ndim == 1 and screen.shape[0] in (1, k):
            return screen
        return None
    try:
        return np.full(1, float(screen))
    except (TypeError, ValueError):
        return None


def xi_pass(kernel: Callable[..., Any], lie: LieData, u_nom: np.ndarray, alpha: ClassK, d_bar: float,
            sa: np.ndarray, rows: np.ndarray | None = None,
            ) -> tuple[np.ndarray, float, float, int, int, int, np.ndarray | None, np.ndarray] | None:
    """``Xi_on`` of every row in one compiled pass (the kernel of :func:`xi_kernel`), where it takes the inputs.

    Returns ``(xi, sum, min, argmin, kept, first, alpha(h), rows)`` (``alpha(h)`` ``None`` for a
    linear alpha: the kernel made ``gain h`` itself; ``kept``/``first``: the screening count of
    the thresholds ``sa`` from :func:`screen_array`, -1 with :data:`NO_SCREEN`; ``rows[:kept]``:
    those rows, ascending, with thresholds; written to ``rows`` when given, an intp array of at least
    as many rows, else to a new array), or ``None`` when
    the inputs are not float64 vectors of one length (the caller then uses
    :func:`~isf_robot.core.triggers.xi_on`, which broadcasts or refuses them as before). The
    caller checks the sum for finiteness.
    """
    h, lf, gn, lg, k = lie.h, lie.lf, lie.grad_norm, lie.lg, lie.h.shape
    gain = alpha.gain if type(alpha) is Linear and h.dtype == _F64 else 0.0  # (the kernel's gain h)
    av = _NO_AV if gain else alpha.vector(h)
    if not (lf.shape == k and gn.shape == k and lg.ndim == 2 and lg.shape[0] == k[0] and lf.dtype == _F64
            and gn.dtype == _F64 and lg.dtype == _F64 and u_nom.dtype == _F64 and u_nom.shape == lg.shape[1:]
            and (gain or av.shape == k and av.dtype == _F64)):
        return None
    xi = np.empty(k)
    if not sa.shape[0]:  # (no thresholds: the plain pass, built with the kernel)
        plain = _STATE.get("plain")
        if plain is not None:
            total, low, arg = plain(lf, lg, u_nom, gn, d_bar, h, gain, av, xi)
            return xi, total, low, arg, -1, -1, None if gain else av, _NO_ROWS
        rows = _NO_ROWS
    elif rows is None or rows.shape[0] < k[0]:
        rows = np.empty(k, np.intp)
    total, low, arg, kept, first = kernel(lf, lg, u_nom, gn, d_bar, h, gain, av, sa, xi, rows)
    return xi, total, low, arg, kept, first, None if gain else av, rows
