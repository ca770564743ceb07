"""The one error path of both command lines (``isf-robot`` and ``isf-satellite``).

Every subcommand handler runs through :func:`run_handler`:

* an :class:`~isf_robot.core.IsfError` (bad input, infeasible set-up, unreadable recording) or an
  :class:`OSError` (missing file, permission, full disk) prints **one line** on stderr,
  ``<prog> <command>: error: <message>`` (multi-line messages, e.g. MuJoCo's XML parser's, are
  joined), and exits with status 2, the status argparse uses for bad arguments;
* Ctrl-C (:class:`KeyboardInterrupt`) prints ``<prog> <command>: interrupted`` and exits 130;
  SIGTERM is turned into :class:`~isf_robot.support.parallel.Terminated` while a handler runs, so
  the same clean-up happens (workers stopped, partial results printed) and the exit status is
  143. Handlers print what finished before re-raising
  (:class:`~isf_robot.support.parallel.Interrupted` carries it);
* a closed stdout (``... | head``) is not an error of ours: exit 0 quietly.

Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from isf_robot.core.exceptions import IsfError
from isf_robot.core.jit import announce_compiles, end_notice
from isf_robot.support.messages import one_line_warnings
from isf_robot.support.parallel import Interrupted, Terminated

__all__ = ["EXIT_USAGE", "EXIT_INTERRUPTED", "EXIT_TERMINATED", "run_handler", "parse_command", "one_line",
           "OneLineParser"]

EXIT_USAGE = 2
"""Exit status of a user error."""
EXIT_INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT), as shells report it."""
EXIT_TERMINATED = 143
"""Exit status after SIGTERM (128 + SIGTERM)."""

Handler = Callable[[argparse.Namespace], "int | None"]


def one_line(exc: BaseException) -> str:
    """The exception's message on one line (its type name when it has no message)."""
    return " ".join(str(exc).split()) or type(exc).__name__


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (``prog: error: ...; see prog --help``)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def _quiet_stdout() -> None:
    """Point stdout at the null device, so the interpreter's final flush cannot fail again."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())


def _quiet_stdout_if_broken() -> None:
    try:
        sys.stdout.flush()
    except OSError:
        _quiet_stdout()


def _deferred_record_errors() -> list[BaseException]:
    """Recording failures kept while the handler ran (only if the Rerun layer was loaded at all)."""
    errors = sys.modules.get("isf_robot.record.errors")
    return list(errors.take_deferred_errors()) if errors is not None else []


def _serve_until_interrupted() -> None:
    """A recording served to the web viewer (``--serve-web``) stays up after the results until Ctrl-C."""
    stream = sys.modules.get("isf_robot.record.stream")
    if stream is not None:
        stream.wait_while_serving()


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated()


def parse_command(
    prog: str, build: Callable[[], argparse.ArgumentParser], argv: Sequence[str] | None
) -> tuple[argparse.ArgumentParser, argparse.Namespace]:
    """Build the parser (importing the command modules) and parse ``argv``.

    Ctrl-C in this phase, before :func:`run_handler` has started, prints ``<prog>: interrupted``
    and exits 130 like everywhere else, instead of the interpreter's traceback.
    """
    try:
        parser = build()
        return parser, parser.parse_args(argv)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        raise SystemExit(EXIT_INTERRUPTED) from None


def run_handler(prog: str, handler: Handler, args: argparse.Namespace) -> int:
    """Run ``handler(args)`` and turn the errors above into messages and exit statuses."""
    where = f"{prog} {getattr(args, 'command', None) or ''}".rstrip()
    marker = announce_compiles(prog)  # (a first run that compiles the kernels says so, once)
    restore_warnings = one_line_warnings(where)  # (the project's warnings as "<where>: warning: ...", workers too)
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    _deferred_record_errors()  # none belongs to this command yet (an earlier in-process one kept them)
    try:
        code = int(handler(args) or 0)
        sys.stdout.flush()  # a full or closed stdout fails here, inside the error path
        failed = _deferred_record_errors()
        for exc in failed:  # recordings that could not be written, reported after the run's results
            print(f"{where}: error: {one_line(exc)}", file=sys.stderr)
        _serve_until_interrupted()
        return EXIT_USAGE if failed and code == 0 else code
    except KeyboardInterrupt as exc:
        terminated = isinstance(exc, Terminated) or (isinstance(exc, Interrupted) and exc.terminated)
        print(f"{where}: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
        return EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
    except BrokenPipeError:
        _quiet_stdout()
        return 0
    except (IsfError, OSError) as exc:
        print(f"{where}: error: {one_line(exc)}", file=sys.stderr)
        for other in _deferred_record_errors():  # a failed recording that is not this error itself
            if other is not exc:
                print(f"{where}: error: {one_line(other)}", file=sys.stderr)
        _quiet_stdout_if_broken()
        return EXIT_USAGE
    finally:
        _deferred_record_errors()  # an interrupted command's failed recordings are not reported later
        signal.signal(signal.SIGTERM, previous)
        restore_warnings()
        end_notice(marker)
