"""The ``pbd`` command line (``../shared/DESCRIPTOR.md``, "Command line").

Each command lives in ``tasks/commands/<name>.py`` with ``add_arguments(parser)`` and ``run(args) -> int``.
Those modules import nothing heavy at the top, so start-up stays light: ``pbd ingest`` never imports
Prefect, open3d or pybullet. A ``PbdError``, or a file-system or memory fault no stage caught, becomes one line on
stderr and exit 2; any other exception is a bug, reported as one line and exit 1 (``PBD_DEBUG=1`` re-raises it).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from types import ModuleType

from tasks.errors import PbdError

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


def quiet_pybullet_import() -> None:
    """Import pybullet with the process's stderr (file descriptor 2) sent to /dev/null meanwhile, so its build-time
    banner does not join a command's one-line error output."""
    if "pybullet" in sys.modules:
        return
    sys.stderr.flush()
    saved = os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        importlib.import_module("pybullet")
    finally:
        os.close(null)
        os.dup2(saved, 2)
        os.close(saved)


def _module(name: str) -> ModuleType:
    return importlib.import_module(f"tasks.commands.{name}")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every sub-command."""
    parser = argparse.ArgumentParser(prog="pbd", description="Robot task descriptors from recorded demonstrations.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, help_text in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument("--store", metavar="DIR", default=None, help="artefact store (default $PBD_STORE or data/store)")
        _module(name).add_arguments(p)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pbd`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command in PYBULLET_COMMANDS:
        quiet_pybullet_import()
    try:
        code: int = _module(args.command).run(args)
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
