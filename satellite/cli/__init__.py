"""Command line of the satellite study: ``isf-satellite COMMAND ...``.

Each subcommand lives in its own module ``satellite.cli.<name>`` exposing
``register(subparsers)``, which adds its parser and sets ``func`` (a callable taking the parsed
``argparse.Namespace`` and returning an exit code). To add a subcommand, write the module and
list it in :data:`SUBCOMMAND_MODULES`; modules that do not exist (yet) are skipped.

Errors go through the one error path of both command lines,
:func:`isf_robot.cli.errors.run_handler`: user errors (missing files, bad meshes, invalid
parameters) print one line to stderr and exit with status 2, Ctrl-C exits 130, no traceback.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
from collections.abc import Sequence

from isf_robot.cli.errors import EXIT_USAGE, OneLineParser, parse_command, run_handler

__all__ = ["SUBCOMMAND_MODULES", "EXIT_USAGE", "build_parser", "main"]

SUBCOMMAND_MODULES: tuple[str, ...] = (
    "satellite.cli.gravity",
    "satellite.cli.run",
    "satellite.cli.tau",
    "satellite.cli.study",
)
"""Modules providing subcommands, in ``--help`` order; missing ones are skipped."""

def build_parser() -> argparse.ArgumentParser:
    """Build the ``isf-satellite`` parser with every available subcommand registered."""
    parser = OneLineParser(
        prog="isf-satellite",
        description=(
            "Event-triggered safety of a satellite orbiting asteroid 25143 Itokawa: gravity "
            "model generation and orbit studies."
        ),
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMAND_MODULES:
        if importlib.util.find_spec(name) is None:
            continue
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line.

    Args:
        argv: Arguments without the program name; default ``sys.argv[1:]``.

    Returns:
        The exit status: 0 on success, 2 on a user error (one-line message on stderr).

    """
    _, args = parse_command("isf-satellite", build_parser, argv)
    return run_handler("isf-satellite", args.func, args)

