"""The ``isf-robot`` command line.

Subcommands live in modules that expose ``register(subparsers)``; each registers its
parsers with ``set_defaults(handler=fn)``. Handlers import heavy libraries (mujoco, rerun)
lazily so that ``--help`` is instant.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from collections.abc import Sequence

from . import __version__
from .core.exceptions import IsfError

__all__ = ["main", "build_parser"]

# Modules providing subcommands, in the order they appear in --help.
COMMAND_MODULES = (
    "isf_robot.arm.commands",
    "isf_robot.record.commands",
    "isf_robot.demo_core",
)


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every available subcommand."""
    parser = argparse.ArgumentParser(
        prog="isf-robot",
        description=(
            "Event-triggered intermittent safety filters (Ong & Ames): run MuJoCo arm scenes with "
            "no filter, the standard CBF filter or the intermittent filter, compare duty cycles, "
            "and replay Rerun logs."
        ),
    )
    parser.add_argument("--version", action="version", version=f"isf-robot {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            if importlib.util.find_spec(name) is None:
                continue
        except ModuleNotFoundError:  # the parent package is not there
            continue
        module = importlib.import_module(name)
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help()
        return 2
    try:
        return int(handler(args) or 0)
    except IsfError as exc:
        print(f"isf-robot {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("isf-robot: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # stdout was closed early (e.g. piped into `head`): not an error of ours
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
