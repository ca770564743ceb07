"""The one-line notice of a command whose run compiles the kernels (isf_robot.core.jit).

A whole command with a cold and then a warm cache: tests/arm/test_demo_first_run.py (one compile for both).
"""

from __future__ import annotations

import io

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
