"""The filter step's passes (:mod:`.robust`, :mod:`.screening`, :mod:`.handover`, :mod:`.closed_step`), compiled or not.

:class:`Passes` holds them compiled by numba where they run (:func:`~isf_robot.core.jit.compiled`) or as written;
:class:`DirectPasses` calls their compiled code without numba's per-call dispatch
(:func:`~isf_robot.core.jit.direct`) for the inputs :meth:`~isf_robot.core.filter_base._FilterBase._passes_for`
admits. :func:`core_kernels`: the core's compiled functions, for :func:`~isf_robot.core.jit.compiled_here`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

from . import projection, qp_check, robust, screening
from .closed_step import promoted_closed_step, screened_closed_step, xi_closed_step
from .handover import promote_rows
from .jit import compiled, direct, jit_enabled

__all__ = ["Passes", "DirectPasses", "core_kernels"]


class Passes(NamedTuple):
    """The step's passes: each a function of :mod:`.robust`, :mod:`.screening`, :mod:`.handover`, compiled or not."""

    xi_pass: Callable[..., Any]
    row_bounds: Callable[..., Any]
    screened_rows: Callable[..., Any]
    others_hold: Callable[..., Any]
    promote_rows: Callable[..., Any]
    xi_closed_step: Callable[..., Any]
    screened_closed_step: Callable[..., Any]
    promoted_closed_step: Callable[..., Any]

    @classmethod
    def build(cls, compile_them: bool = True) -> Passes:
        """The passes compiled (where ``ISF_ROBOT_JIT`` allows; ``compile_them=False``: as written)."""
        c = compiled if compile_them else (lambda f: f)
        return cls(c(robust.xi_pass), c(robust.row_bounds), c(screening.screened_rows), c(screening.others_hold),
                   c(promote_rows), c(xi_closed_step), c(screened_closed_step), c(promoted_closed_step))


class DirectPasses:
    """:class:`Passes`' compiled code called without numba's dispatch (:func:`~isf_robot.core.jit.direct`).

    Each pass is resolved at its first call, for that call's argument types; the filter hands these passes
    only inputs its ``_passes_for`` admits (:class:`~isf_robot.core.filter_base._FilterBase`: float64,
    C-contiguous, one dimension, ``Lg h`` two; a linear class-K function), so every later call passes arrays of
    the same types: those, the filter's own buffers and flags, and screening thresholds made C-contiguous
    float64 (its ``_screen_array``).
    """

    __slots__ = (*Passes._fields, "_of")

    def __init__(self, passes: Passes) -> None:
        self._of = passes

    def __reduce__(self) -> tuple[Any, ...]:  # (a copy resolves its passes again: compiled code does not pickle)
        return DirectPasses, (self._of,)

    def __getattr__(self, name: str) -> Any:  # (a pass not called yet: resolved at this call)
        if name.startswith("_"):  # (not a pass; also _of before __init__, as a copy is being made)
            raise AttributeError(name)
        kernel = getattr(self._of, name)

        def first(*args: Any) -> Any:
            code = direct(kernel, args)
            setattr(self, name, code)
            return code(*args)

        return first


def core_kernels() -> list[Any]:
    """The core's compiled functions (the filter step's passes, the closed forms, the prediction pass).

    For :func:`~isf_robot.core.jit.compiled_here`; empty when the kernels are off.
    """
    if not jit_enabled():
        return []
    return [*Passes.build(), compiled(projection.project_row), compiled(projection.project_few_within),
            compiled(projection.within_bounds), compiled(qp_check.answer_violation), compiled(robust.predict_pass)]
