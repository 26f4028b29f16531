"""``pbd synth``: not built yet (issue 3)."""

from __future__ import annotations

import argparse

from tasks.errors import NotBuiltError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd synth`` (none until it is built)."""
    parser.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)


def run(args: argparse.Namespace) -> int:  # noqa: ARG001 - the stub ignores its arguments
    """Refuse cleanly: this command is not built yet."""
    raise NotBuiltError("synth", 3)
