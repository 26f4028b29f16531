"""The ``pbd`` command line (``../shared/DESCRIPTOR.md``, "Command line").

Every command's arguments are in ``flows.cli_args`` (argparse only); its ``run(args) -> int`` is in
``flows.commands.<name>``, imported by name once the arguments parse, so start-up stays light: ``pbd ingest``
never imports Prefect, open3d or pybullet. A ``PbdError`` becomes one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from flows.cli_args import ARGUMENTS
from tasks.errors import PbdError
from tasks.quiet_import import quiet_import

COMMANDS: dict[str, str] = {
    "demo": "make the sample recordings, run the whole pipeline flow over them, print where results are",
    "synth": "record a simulated demonstration of a built-in scene",
    "ingest": "read recordings into the store's Parquet; print their ids",
    "learn": "segment, fit, plan the grasp and store a descriptor version",
    "transfer": "carry a descriptor to a similar object by registering the object models",
    "simulate": "execute a descriptor in pybullet and report success",
    "diff": "what changed between two descriptors",
    "archive": "run the reprocessing flow over every recording in a folder",
    "serve": "serve the Prefect deployments with their schedules",
}

PYBULLET_COMMANDS = frozenset({"demo", "synth", "learn", "transfer", "simulate", "archive", "serve"})
"""Commands that load pybullet, whose import prints its build time on stderr (C level); they import it quietly."""


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every sub-command."""
    parser = argparse.ArgumentParser(prog="pbd", description="Robot task descriptors from recorded demonstrations.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, help_text in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument("--store", metavar="DIR", default=None, help="artefact store (default $PBD_STORE or data/store)")
        ARGUMENTS[name](p)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pbd`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command in PYBULLET_COMMANDS:
        quiet_import("pybullet")
    try:
        command = importlib.import_module(f"flows.commands.{args.command}")
        code: int = command.run(args)
    except PbdError as err:
        print(f"pbd {args.command}: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"pbd {args.command}: interrupted", file=sys.stderr)
        return 130
    return code


if __name__ == "__main__":
    sys.exit(main())
