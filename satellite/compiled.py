"""The satellite's formulas compiled where numba is present: one plain function, compiled or not.

A formula of the run (the tabulated field, the truth flow, the band's trigger values and their rate
bounds, the contact envelope, the maneuver trigger) is written once, as a plain module-level function
over floats and arrays. :func:`compiled` returns ``numba.njit(cache=True, nogil=True)`` of it when numba
imports and ``ISF_ROBOT_JIT`` is not ``0`` (read when the module defining the formula is imported), else
the function itself; :func:`inlined` registers a small helper so that compiled code can call it while
Python keeps the plain function (for numpy arrays as well as floats). The Python path (the classes,
scipy's integrator) and the compiled arcs (:mod:`satellite.orbit.arc_kernel`) call the same functions.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from isf_robot.core.jit import jit_enabled, watch_compiles

__all__ = ["compiled", "inlined", "plain"]

F = TypeVar("F", bound=Callable[..., Any])


def _numba() -> Any:
    if not jit_enabled():
        return None
    try:
        import numba  # (deferred: numba loads only when a formula is compiled)
    except ImportError:  # pragma: no cover (numba is a dependency)
        return None
    watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)
    return numba


def compiled(fn: F) -> F:
    """``fn`` compiled by numba (cached on disk), or ``fn`` itself without numba or with ``ISF_ROBOT_JIT=0``."""
    numba = _numba()
    return fn if numba is None else numba.njit(cache=True, nogil=True)(fn)  # type: ignore[no-any-return]


def inlined(fn: F) -> F:
    """``fn`` itself, made callable from compiled code (numba's ``register_jitable``) when numba is used."""
    numba = _numba()
    if numba is not None:
        from numba.extending import register_jitable

        register_jitable(fn)
    return fn


def plain(fn: Callable[..., Any]) -> Callable[..., Any]:
    """The Python function behind a :func:`compiled` one (for numpy arrays: no compile per array type)."""
    return getattr(fn, "py_func", fn)
