"""The one error path of both command lines (``isf-robot`` and ``isf-satellite``).

Every subcommand handler runs through :func:`run_handler`:

* an :class:`~isf_robot.core.IsfError` (bad input, infeasible set-up, unreadable recording) or an
  :class:`OSError` (missing file, permission, full disk) prints **one line** on stderr,
  ``<prog> <command>: error: <message>`` (multi-line messages, e.g. MuJoCo's XML parser's, are
  joined), and exits with status 2, the status argparse uses for bad arguments;
* Ctrl-C (:class:`KeyboardInterrupt`) prints ``<prog> <command>: interrupted`` and exits 130;
* a closed stdout (``... | head``) is not an error of ours: exit 0 quietly.

Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable

from isf_robot.core.exceptions import IsfError

__all__ = ["EXIT_USAGE", "EXIT_INTERRUPTED", "run_handler", "one_line"]

EXIT_USAGE = 2
"""Exit status of a user error."""
EXIT_INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT), as shells report it."""

Handler = Callable[[argparse.Namespace], "int | None"]


def one_line(exc: BaseException) -> str:
    """The exception's message on one line (its type name when it has no message)."""
    return " ".join(str(exc).split()) or type(exc).__name__


def run_handler(prog: str, handler: Handler, args: argparse.Namespace) -> int:
    """Run ``handler(args)`` and turn the errors above into messages and exit statuses."""
    where = f"{prog} {getattr(args, 'command', None) or ''}".rstrip()
    try:
        return int(handler(args) or 0)
    except KeyboardInterrupt:
        print(f"{where}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except (IsfError, OSError) as exc:
        print(f"{where}: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
