"""The commands' warnings as one line each: in the command's process, in its workers, and not for library users."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

from isf_robot.core.exceptions import IsfWarning
from isf_robot.support.messages import WARN_ENV, one_line_warnings


def test_project_warnings_print_one_line_under_the_program_and_undo_restores(capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.delenv(WARN_ENV, raising=False)
    others: list[type] = []

    def python_format(message, category, *args, **kwargs):  # type: ignore[no-untyped-def]
        others.append(category)

    monkeypatch.setattr(warnings, "showwarning", python_format)
    undo = one_line_warnings("isf-robot run")
    try:
        assert os.environ[WARN_ENV] == "isf-robot run"  # (what a worker process reads)
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            warnings.warn("safety filter infeasible at t=0.5;\napplied the fallback", IsfWarning, stacklevel=1)
            warnings.warn("something else", UserWarning, stacklevel=1)
    finally:
        undo()
    err = capsys.readouterr().err.splitlines()
    assert err == ["isf-robot run: warning: safety filter infeasible at t=0.5; applied the fallback"]
    assert others == [UserWarning]  # (other warnings keep Python's printer)
    assert warnings.showwarning is python_format and WARN_ENV not in os.environ


def test_without_a_program_nothing_changes(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.delenv(WARN_ENV, raising=False)
    before = warnings.showwarning
    undo = one_line_warnings()
    assert warnings.showwarning is before
    undo()


def test_a_command_and_its_worker_processes_print_one_line_warnings() -> None:
    """`compare --jobs 2` at the torque level on panda_shelf: its workers' fallback warnings, one line each."""
    cmd = [sys.executable, "-m", "isf_robot.cli", "compare", "--scene", "panda_shelf", "--level", "torque",
           "--filters", "isf", "--episodes", "2", "--jobs", "2", "--duration", "1.0", "--d-bar", "0.63", "--quiet"]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env={**os.environ, WARN_ENV: ""})
    assert out.returncode == 0, out.stderr
    lines = [line for line in out.stderr.splitlines() if "compiling the fast kernels" not in line]
    warned = [line for line in lines if "warning" in line]
    assert warned and all(line.startswith("isf-robot compare: warning: safety filter infeasible") for line in warned)
    assert not any(".py:" in line or line.startswith("  ") for line in lines), lines  # (no path, no source line)
