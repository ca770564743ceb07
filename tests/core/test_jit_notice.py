"""The one-line notice of a command whose run compiles the kernels (isf_robot.core.jit)."""

from __future__ import annotations

import io
import os
import subprocess
import sys

import pytest

from isf_robot.core import jit

numba = pytest.importorskip("numba")


def _fresh_function(module: str, name: str):  # type: ignore[no-untyped-def]
    """A new numba function whose ``__module__`` is ``module`` (never cached: each call compiles)."""
    scope = {"__name__": module}
    exec(f"def {name}(x):\n    return x + 1.0\n", scope)  # noqa: S102 - a probe function for the listener
    return numba.njit(scope[name])


@pytest.fixture
def notice(tmp_path, monkeypatch):  # type: ignore[no-untyped-def]
    marker = tmp_path / "isf-robot-compile-notice-1"
    monkeypatch.setenv(jit.NOTICE_ENV, str(marker))
    out = io.StringIO()
    monkeypatch.setattr(jit, "_STATE", {"stream": out})
    jit.watch_compiles()
    yield marker, out
    from numba.core import event

    event.unregister("numba:compile", jit._STATE["listener"])


def test_the_first_compile_of_a_package_kernel_prints_one_line(notice) -> None:  # type: ignore[no-untyped-def]
    marker, out = notice
    _fresh_function("someone_else.module", "f")(1.0)  # not ours: quiet
    assert out.getvalue() == "" and not marker.exists()
    _fresh_function("isf_robot.probe", "g")(1.0)
    _fresh_function("satellite.probe", "h")(1.0)  # a second compile: still one line
    lines = out.getvalue().splitlines()
    assert lines == [f"isf-robot: {jit.COMPILE_NOTICE}"]
    assert marker.exists()


def test_another_process_of_the_command_stays_quiet(notice) -> None:  # type: ignore[no-untyped-def]
    marker, out = notice
    marker.touch()  # a worker of the same command printed it already
    _fresh_function("isf_robot.probe", "k")(1.0)
    assert out.getvalue() == ""


def test_no_notice_unless_asked(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.delenv(jit.NOTICE_ENV, raising=False)
    monkeypatch.setattr(jit, "_STATE", {})
    jit.watch_compiles()
    assert "listener" not in jit._STATE


@pytest.mark.parametrize("value, on", [("1", True), ("0", False), ("off", False), (" False ", False), ("yes", True)])
def test_jit_switch(monkeypatch, value: str, on: bool) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv(jit.JIT_ENV, value)
    assert jit.jit_enabled() is on


def test_a_cold_cache_says_so_once_and_a_warm_one_says_nothing(tmp_path) -> None:  # type: ignore[no-untyped-def]
    tmp = tmp_path / "tmp"  # (the command's own temporary folder: where its marker lives while it runs)
    tmp.mkdir()
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "ISF_ROBOT_JIT": "1", "TMPDIR": str(tmp)}
    env.pop(jit.NOTICE_ENV, None)
    cmd = [sys.executable, "-m", "isf_robot.cli", "core-demo"]
    first = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr
    assert first.stderr.count(jit.COMPILE_NOTICE) == 1
    second = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert second.returncode == 0, second.stderr
    assert jit.COMPILE_NOTICE not in second.stderr
    assert not list(tmp.glob("*compile-notice*"))  # (each command removed its marker when it ended)
