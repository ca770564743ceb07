"""The ``isf-robot`` command line: the top layer (``cli -> {arm, satellite, record} -> core``).

Subcommands live in modules of this package that expose ``register(subparsers)``; each
registers its parsers with ``set_defaults(handler=fn)``. Handlers import heavy libraries
(mujoco, rerun) lazily so that ``--help`` is instant. Every handler runs through
:func:`isf_robot.cli.errors.run_handler`, the one error path shared with ``isf-satellite``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from isf_robot import __version__

from .errors import EXIT_USAGE, OneLineParser, parse_command, run_handler

__all__ = ["main", "build_parser", "COMMAND_MODULES"]

# Modules providing subcommands, in the order they appear in --help.
COMMAND_MODULES = (
    "isf_robot.cli.arm",
    "isf_robot.cli.sweep",
    "isf_robot.cli.replay",
    "isf_robot.cli.core_demo",
    "isf_robot.cli.setup",
    "isf_robot.cli.render",
    "isf_robot.cli.plot",
)


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every subcommand."""
    parser = OneLineParser(
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
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    parser, args = parse_command("isf-robot", build_parser, argv)
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help()
        return EXIT_USAGE
    return run_handler("isf-robot", handler, args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
