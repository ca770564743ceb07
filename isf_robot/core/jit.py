"""Whether the compiled kernels run, and a one-line notice on stderr when they are compiled.

The kernels (the arm's step, the filters' few-row step, the satellite's arcs) are numba functions
cached on disk (``cache=True``): the first run on a machine compiles them (some 30-45 s of CPU for a
velocity-level arm run; the torque level, several arms and the satellite compile theirs on their first run),
later runs load them. ``ISF_ROBOT_JIT=0`` runs the plain numpy paths instead (the same
formulas; see the kernels' modules for the tolerance they agree to). ``ISF_ROBOT_JIT=cached`` uses a
kernel handed out by :func:`compiled` only where numba's cache already holds it for this machine and runs
the rest as written: it compiles nothing (``isf-robot demo`` runs so, whatever the commands before it
happened to compile, and with ``0`` where the cache holds none; the satellite's kernels, made by
:mod:`satellite.compiled`, compile as usual). The cache is numba's, per argument types: a kernel held for some
types still compiles, on its first call, for types no earlier run gave it (rare: the arm's paths call each kernel
with the same types).

The command-line tools call :func:`announce_compiles` once: the first kernel that a command (or any
of its worker processes) actually compiles, rather than loads from the cache, prints one line on
stderr, so a slow first run says why. Library users see nothing unless they call it too.
"""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Sequence
from types import ModuleType
from typing import Any, TextIO

__all__ = ["JIT_ENV", "CACHED_ONLY", "NOTICE_ENV", "COMPILE_NOTICE", "jit_enabled", "announce_compiles",
           "watch_compiles", "end_notice", "compiled_here", "formula", "compiled", "direct", "register_formulas",
           "stamp_sources"]

JIT_ENV = "ISF_ROBOT_JIT"
"""Environment variable: ``0`` (or ``false``, ``no``, ``off``) turns the compiled kernels off; ``cached`` uses
only those numba's cache holds (:func:`compiled`)."""

CACHED_ONLY = "cached"
"""The :data:`JIT_ENV` value that uses a kernel only where numba's cache holds it, compiling nothing."""

NOTICE_ENV = "ISF_ROBOT_COMPILE_NOTICE"
"""Environment variable naming the marker file of a command's compile notice (set by :func:`announce_compiles`)."""

COMPILE_NOTICE = ("compiling the fast kernels for this machine, once (about 30-45 s; later runs load "
                  "them from numba's cache; ISF_ROBOT_JIT=0 runs without them)")
"""The notice (after the program's name)."""

_PACKAGES = ("isf_robot.", "satellite.")
_STATE: dict[str, Any] = {}


def jit_enabled() -> bool:
    """Whether the compiled kernels may be used (``ISF_ROBOT_JIT`` is not ``0``/``false``/``no``/``off``).

    Whether numba is importable is each kernel module's own question (it falls back to numpy).
    """
    return os.environ.get(JIT_ENV, "1").strip().lower() not in ("0", "false", "no", "off")


def announce_compiles(prog: str, stream: TextIO | None = None) -> str:
    """Make the first kernel compile of this command print one line on ``stream`` (stderr).

    Sets :data:`NOTICE_ENV` to a fresh marker path, which worker processes inherit: whichever process
    compiles first creates the marker and prints; the others stay quiet. Returns the marker path
    (remove it when the command ends: :func:`end_notice`).
    """
    marker = os.path.join(tempfile.gettempdir(), f"{prog}-compile-notice-{os.getpid()}")
    os.environ[NOTICE_ENV] = marker
    _STATE["stream"] = stream
    watch_compiles()
    return marker


def end_notice(marker: str) -> None:
    """Remove a command's marker (see :func:`announce_compiles`)."""
    try:
        os.unlink(marker)
    except OSError:
        pass


def watch_compiles() -> None:
    """Listen for numba compiles of this package's kernels (once per process; only when a notice is asked for).

    Called by the kernel modules before their first use; a no-op without :data:`NOTICE_ENV` or numba.
    """
    if "listener" in _STATE or not os.environ.get(NOTICE_ENV):
        return
    try:
        from numba.core import event
    except ImportError:
        return

    class _FirstCompile(event.Listener):  # type: ignore[misc]
        def on_start(self, ev: Any) -> None:
            if _STATE.get("printed"):
                return
            func = getattr(ev.data.get("dispatcher"), "py_func", None)
            if not str(getattr(func, "__module__", "")).startswith(_PACKAGES):
                return
            _STATE["printed"] = True
            marker = os.environ.get(NOTICE_ENV)
            if not marker:
                return
            try:
                os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            except OSError:  # another process of this command printed it
                return
            out = _STATE.get("stream") or sys.stderr
            prog = os.path.basename(marker).split("-compile-notice-")[0] or "isf-robot"
            print(f"{prog}: {COMPILE_NOTICE}", file=out, flush=True)

        def on_end(self, ev: Any) -> None:
            pass

    listener = _FirstCompile()
    event.register("numba:compile", listener)
    _STATE["listener"] = listener


def compiled_here(modules: Sequence[Any]) -> tuple[int, int]:
    """How many kernels numba's cache holds for this machine: ``(held, kernels)``.

    ``modules``: modules (their module-level numba functions count) or compiled functions
    themselves (:func:`compiled`). A kernel is a cached numba function that is not inlined into its
    callers; it is held when its cache index (fresh for its source) has an entry for this machine's
    code generation. ``(0, 0)`` when that cannot be told (a numba without these internals).
    """
    held = total = 0
    try:
        from numba.core.registry import CPUDispatcher

        found = []
        for module in modules:
            if isinstance(module, ModuleType):
                found += [obj for obj in vars(module).values()
                          if isinstance(obj, CPUDispatcher) and obj.__module__ == module.__name__]
            elif isinstance(module, CPUDispatcher):
                found.append(module)
        for obj in found:
            if obj.targetoptions.get("inline", "never") != "never":
                continue
            index_file = getattr(getattr(obj, "_cache", None), "_cache_file", None)
            if index_file is None:
                continue
            here = obj.targetctx.codegen().magic_tuple()
            total += 1
            held += any(key[1] == here for key in index_file._load_index())
    except Exception:  # noqa: BLE001 - numba's internals moved: nothing can be said
        return 0, 0
    return held, total


def formula(fn: Any) -> Any:
    """Mark a plain function as callable from compiled code; returns ``fn`` itself, unchanged.

    Python callers run ``fn`` as written (on floats or on numpy arrays alike); a function compiled
    with :func:`compiled` that calls it compiles this same source into itself (numba's
    ``register_jitable``, applied when the first kernel is compiled: importing the core does not
    import numba).
    """
    _FORMULAS.append(fn)
    return fn


def compiled(fn: Any, sources: Sequence[str] = ()) -> Any:
    """``fn`` compiled by numba (cached on disk, made once per process), or ``fn`` itself.

    ``fn`` itself when ``ISF_ROBOT_JIT`` turns the kernels off or numba is missing, and under
    ``ISF_ROBOT_JIT=cached`` when numba's cache does not hold ``fn`` for this machine yet (the
    setting is read at each call: a filter reads it when it is built). ``fn`` must be a module-level
    function whose compiled callees are :func:`formula` functions of its own folder, or of the folders
    ``sources`` (numba's cache then follows edits of those files: :func:`stamp_sources`; the same
    ``sources`` at every call). Creating it compiles nothing: the first call with new argument types does.
    """
    env = _ENV.get(JIT_ENV)
    if env == _HANDED_ENV[0]:  # (the common case: no parsing of the setting)
        got = _HANDED.get(fn)
        if got is not None:
            return got
    else:
        _HANDED.clear()
        _HANDED_ENV[0] = env
    got = _HANDED[fn] = _hand_out(fn, (env or "").strip().lower() == CACHED_ONLY, sources)
    return got


def _hand_out(fn: Any, cached_only: bool, sources: Sequence[str]) -> Any:
    """:func:`compiled`'s answer for the current setting (the dispatcher is made once per process)."""
    if not jit_enabled():
        return fn
    got = _COMPILED.get(fn)
    if got is None:
        try:
            from numba import njit
        except ImportError:
            return fn
        watch_compiles()
        register_formulas()
        got = _COMPILED[fn] = njit(cache=True, nogil=True)(fn)
        stamp_sources(got, (os.path.dirname(fn.__code__.co_filename), *sources))
    if cached_only and compiled_here((got,))[0] == 0:
        return fn
    return got


def direct(kernel: Any, args: Sequence[Any]) -> Any:
    """``kernel``'s compiled code for the types of ``args``, called without numba's dispatch; else ``kernel``.

    A numba function looks at every argument of every call to pick the code compiled for their types
    (some 45 ns an argument: a microsecond for the arm's twenty-argument kernels, called every control
    step). The code it picks takes its arguments as they come: a call site whose arguments' types are
    fixed by construction (its own buffers and addresses, Python floats, ints and bools) can hold it and
    call it directly. The caller must pass every later call arrays of the same dtype, dimensions and layout
    as ``args`` (numba does not check an array's dtype there; a scalar is converted as numba converts it).
    Loads or compiles that code as a first call would. ``kernel`` itself when it is not a numba function
    (``ISF_ROBOT_JIT=0``, no numba, a stand-in) or numba lacks the interface.
    """
    typeof = getattr(kernel, "typeof_pyval", None)
    if typeof is None:
        return kernel
    try:
        return kernel.compile(tuple(typeof(a) for a in args))
    except Exception:  # noqa: BLE001 - numba's interface moved: the dispatching call serves
        return kernel


def stamp_sources(dispatcher: Any, folders: Sequence[str]) -> None:
    """Key a kernel's disk cache on every source file of ``folders``, not only the kernel's own file.

    numba checks only the file of the compiled function before it loads a cached kernel; the
    :func:`formula` functions compiled into it live in other files, and an edit of one of them must
    not load a stale kernel. ``folders`` must be the same in every process (the stamp is compared
    with the one stored beside the cache). (numba's cache internals; left as they are if they moved.)
    """
    try:
        stamp = tuple((os.path.join(os.path.basename(folder), f), os.stat(os.path.join(folder, f)).st_mtime,
                       os.stat(os.path.join(folder, f)).st_size)
                      for folder in folders for f in sorted(os.listdir(folder)) if f.endswith(".py"))
        cache_file = dispatcher._cache._cache_file
        if hasattr(cache_file, "_source_stamp"):
            cache_file._source_stamp = stamp
    except (AttributeError, OSError):
        pass


def register_formulas() -> None:
    """Make every :func:`formula` defined so far callable from compiled code (needs numba)."""
    from numba.extending import register_jitable

    while _FORMULAS:
        register_jitable(_FORMULAS.pop())


_COMPILED: dict[Any, Any] = {}  # (a function's numba dispatcher, made once per process)
_HANDED: dict[Any, Any] = {}  # (what compiled() hands out for a function under the setting below)
_HANDED_ENV: list[str | None] = ["?"]  # (the ISF_ROBOT_JIT value _HANDED was made under)
_ENV = os.environ
_FORMULAS: list[Any] = []
