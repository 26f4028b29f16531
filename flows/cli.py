"""The ``pbd`` command line (``../shared/DESCRIPTOR.md``, "Command line").

Every command's arguments are in ``flows.cli_args`` (argparse only); its ``run(args) -> int`` is in
``flows.commands.<name>``, imported by name once the arguments parse, so start-up stays light: ``pbd ingest``
never imports Prefect, open3d or pybullet. A ``PbdError`` becomes one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys
from collections.abc import Sequence
from importlib import metadata

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
    "diff": "what changed between two descriptors (or a name's last two versions)",
    "ls": "list the stored descriptors, or the versions of one",
    "archive": "run the reprocessing flow over every recording in a folder",
    "serve": "serve the Prefect deployments with their schedules",
}

PYBULLET_COMMANDS = frozenset({"demo", "synth", "learn", "transfer", "simulate", "archive", "serve"})
"""Commands that load pybullet, whose import prints its build time on stderr (C level); they import it quietly."""


CONSOLE_LEVELS = {-1: "ERROR", 0: "WARNING", 1: "INFO"}
"""Level of Prefect's console log handler by verbosity (``-q`` -1, default 0, ``-v`` 1, ``-vv`` and more DEBUG):
the flow commands show their own table, so Prefect's INFO lines (every task run) only with ``-v``. The Prefect
API handler keeps INFO, so the UI shows a CLI run's logs whatever the verbosity."""


def version() -> str:
    """pbd's installed version (the package metadata), or ``unknown`` when it is not installed."""
    try:
        return metadata.version("pbd")
    except metadata.PackageNotFoundError:
        return "unknown"


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every sub-command."""
    parser = argparse.ArgumentParser(prog="pbd", description="Robot task descriptors from recorded demonstrations.")
    parser.add_argument("--version", action="version", version=f"pbd {version()}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        "--store", metavar="DIR", default=None, help="artefact store (default $PBD_STORE or data/store)"
    )
    loud = common.add_mutually_exclusive_group()
    loud.add_argument("-v", "--verbose", action="count", default=0, help="more log lines (-v Prefect INFO, -vv DEBUG)")
    loud.add_argument("-q", "--quiet", action="store_true", help="errors only on stderr")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, help_text in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text, parents=[common])
        ARGUMENTS[name](p)
    return parser


def set_log_levels(args: argparse.Namespace) -> None:
    """Prefect's console log level (and pbd's logger's) from ``-q``/``-v``, set before Prefect is imported;
    ``PREFECT_LOGGING_HANDLERS_CONSOLE_LEVEL`` in the environment wins when neither flag is given."""
    verbosity = -1 if args.quiet else args.verbose
    level = CONSOLE_LEVELS.get(verbosity, "DEBUG")
    if verbosity or "PREFECT_LOGGING_HANDLERS_CONSOLE_LEVEL" not in os.environ:
        os.environ["PREFECT_LOGGING_HANDLERS_CONSOLE_LEVEL"] = level
        os.environ["PREFECT_SERVER_LOGGING_LEVEL"] = "DEBUG" if verbosity > 1 else "WARNING"
    if verbosity > 1:
        os.environ["PREFECT_LOGGING_LEVEL"] = "DEBUG"
    logging.getLogger("pbd").setLevel(level)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pbd`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    set_log_levels(args)
    if args.command in PYBULLET_COMMANDS:
        quiet_import("pybullet")
    try:
        command = importlib.import_module(f"flows.commands.{args.command}")
        code: int = command.run(args)
    except PbdError as err:
        return _fail(args.command, str(err), 2)
    except OSError as err:  # an environment fault no stage turned into a PbdError: name the file and the cause
        where = f"{err.filename}: " if err.filename else ""
        return _fail(args.command, f"{where}{err.strerror or err}", 2)
    except MemoryError:
        return _fail(args.command, "out of memory (the input is larger than this machine can hold)", 2)
    except KeyboardInterrupt:
        print(f"pbd {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as err:  # a bug: one line for the user, the traceback with PBD_DEBUG=1
        if os.environ.get("PBD_DEBUG"):
            raise
        return _fail(args.command, f"internal error {type(err).__name__}: {err} (PBD_DEBUG=1 shows where)", 1)
    return code


MAX_ERROR_CHARS = 400
"""Longest error line printed: a whole path and a cause fit; a quoted input never floods the terminal."""


def _fail(command: str, message: str, code: int) -> int:
    """Print ``pbd COMMAND: message`` as one line of at most ``MAX_ERROR_CHARS`` and return ``code``."""
    line = " ".join(f"pbd {command}: {message}".split())
    if len(line) > MAX_ERROR_CHARS:
        line = line[: MAX_ERROR_CHARS - 3] + "..."
    print(line, file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
