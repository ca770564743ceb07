"""``ISF_ROBOT_JIT=cached``: a kernel is used only where numba's disk cache holds it; nothing is compiled.

The demo after a run that compiled only some kernels: tests/arm/test_demo_first_run.py.
"""

from __future__ import annotations

import importlib.util
import sys

import pytest

from isf_robot.core import jit

numba = pytest.importorskip("numba")


def _module(tmp_path, name: str):  # type: ignore[no-untyped-def]
    """A fresh module file with one plain function ``f`` (numba caches beside it, in ``tmp_path``)."""
    path = tmp_path / f"{name}.py"
    path.write_text("def f(x):\n    return 2.0 * x + 1.0\n")
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_cached_mode_uses_a_kernel_only_once_the_cache_holds_it(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    mod = _module(tmp_path, "isf_cached_probe")
    monkeypatch.setenv(jit.JIT_ENV, jit.CACHED_ONLY)
    assert jit.compiled(mod.f) is mod.f  # (nothing in the cache: the function as written)
    assert jit.compiled_here((jit._COMPILED[mod.f],)) == (0, 1)

    monkeypatch.setenv(jit.JIT_ENV, "1")
    kernel = jit.compiled(mod.f)
    assert kernel is not mod.f and kernel.py_func is mod.f
    assert kernel(3.0) == mod.f(3.0) == 7.0  # (compiles, and writes numba's cache)
    assert jit.compiled_here((kernel,)) == (1, 1)

    monkeypatch.setenv(jit.JIT_ENV, " Cached ")  # (read at each call: the setting changed)
    assert jit.compiled(mod.f) is kernel
    monkeypatch.setenv(jit.JIT_ENV, "0")
    assert jit.compiled(mod.f) is mod.f


def test_cached_mode_goes_back_to_the_source_when_it_changes(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    mod = _module(tmp_path, "isf_cached_probe_2")
    monkeypatch.setenv(jit.JIT_ENV, "1")
    jit.compiled(mod.f)(1.0)
    (tmp_path / "other.py").write_text("X = 1\n")  # (a file of the kernel's folder changed: its cache is stale)
    jit._COMPILED.pop(mod.f)  # (a new process)
    monkeypatch.setenv(jit.JIT_ENV, jit.CACHED_ONLY)
    assert jit.compiled(mod.f) is mod.f
