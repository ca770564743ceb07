"""The satellite's formulas compiled where numba is present: one plain function, compiled or not.

A formula of the run (the tabulated field, the truth flow, the band's trigger values and their rate
bounds, the contact envelope, the maneuver trigger) is written once, as a plain module-level function
over floats and arrays. :func:`compiled` returns ``numba.njit(cache=True, nogil=True)`` of it when numba
imports and ``ISF_ROBOT_JIT`` is not ``0`` (read when the module defining the formula is imported), else
the function itself; :func:`inlined` registers a small helper so that compiled code can call it while
Python keeps the plain function (for numpy arrays as well as floats). The Python path (the classes,
scipy's integrator) and the compiled arcs (:mod:`satellite.orbit.arc_kernel`) call the same functions.

The core's formulas (:func:`isf_robot.core.jit.formula`: the robust condition's slack, ``Xi_tau``) are
compiled into the arcs from the core's own source. A compiled kernel's disk cache is keyed on every
source file of this package and of :mod:`isf_robot.core` (:func:`isf_robot.core.jit.stamp_sources`), so
an edit of any formula it calls compiles it afresh instead of loading a stale kernel.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import isf_robot.core
from isf_robot.core.jit import jit_enabled, register_formulas, stamp_sources, watch_compiles

__all__ = ["compiled", "kernel", "inlined", "plain"]

F = TypeVar("F", bound=Callable[..., Any])


def _numba() -> Any:
    if not jit_enabled():
        return None
    try:
        import numba  # (deferred: numba loads only when a formula is compiled)
    except ImportError:  # pragma: no cover (numba is a dependency)
        return None
    watch_compiles()  # (a command's one-line notice when a kernel is compiled: isf_robot.core.jit)
    register_formulas()  # (the core's formulas imported so far: the satellite's kernels call some)
    return numba


@functools.cache
def _source_folders() -> tuple[str, ...]:
    """Every folder of this package's source, then the core's (the same in every process; found once)."""
    here = Path(__file__).resolve().parent
    folders = sorted(str(p) for p in here.rglob("*") if p.is_dir() and p.name != "__pycache__")
    return (str(here), *folders, os.path.dirname(os.path.abspath(isf_robot.core.__file__)))


def compiled(fn: F) -> F:
    """``fn`` compiled by numba (cached on disk), or ``fn`` itself without numba or with ``ISF_ROBOT_JIT=0``."""
    return fn if _numba() is None else kernel(fn)


def kernel(fn: F) -> F:
    """``numba.njit(cache=True, nogil=True)`` of ``fn``, its cache keyed on the sources it may call.

    For the modules that exist only compiled (the arcs: :mod:`satellite.orbit.arc_kernel`); they are
    imported only when numba is used.
    """
    import numba

    register_formulas()
    got = numba.njit(cache=True, nogil=True)(fn)
    stamp_sources(got, _source_folders())
    return got  # type: ignore[no-any-return]


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
