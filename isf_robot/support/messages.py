"""The command-line tools' warnings as one line each, in the command's process and in its worker processes.

Python prints a warning as ``path:line: Category: message`` followed by the source line that raised
it. For a user of ``isf-robot`` or ``isf-satellite`` the project's own warnings
(:class:`~isf_robot.core.exceptions.IsfWarning`: an infeasible filter step and its fallback, a
calibration that did not settle, ...) read instead ``<prog>: warning: <message>``, one line on stderr.
:func:`one_line_warnings` sets this up for a command and names the program in :data:`WARN_ENV`, so the
worker processes it starts (:mod:`isf_robot.support.parallel`) print theirs the same way. Other
warnings keep Python's format. Library users see Python's format throughout.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Callable
from typing import Any, TextIO

from isf_robot.core.exceptions import IsfWarning

__all__ = ["WARN_ENV", "one_line_warnings"]

WARN_ENV = "ISF_ROBOT_WARNINGS_AS"
"""Environment variable: the program name a worker process prints its warnings under (set by the command)."""


def one_line_warnings(prog: str | None = None) -> Callable[[], None]:
    """Print :class:`IsfWarning` as ``<prog>: warning: <message>`` lines; returns the function that undoes it.

    ``prog``: the program's name (``isf-robot run``); ``None``: the name in :data:`WARN_ENV` (a worker
    process of a command), and nothing changes when it is not set.
    """
    prog = prog or os.environ.get(WARN_ENV)
    if not prog:
        return lambda: None
    before_env = os.environ.get(WARN_ENV)
    os.environ[WARN_ENV] = prog
    previous = warnings.showwarning

    def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
             file: TextIO | None = None, line: str | None = None) -> None:
        if isinstance(category, type) and issubclass(category, IsfWarning):
            out: Any = sys.stderr if file is None else file
            text = " ".join(str(message).split())  # (one line whatever the message holds)
            try:
                print(f"{prog}: warning: {text}", file=out, flush=True)
            except (OSError, ValueError):  # (a closed stderr: as Python's own printer, say nothing)
                pass
            return
        previous(message, category, filename, lineno, file, line)

    warnings.showwarning = show

    def undo() -> None:
        warnings.showwarning = previous
        if before_env is None:
            os.environ.pop(WARN_ENV, None)
        else:
            os.environ[WARN_ENV] = before_env

    return undo
