"""Importing pybullet without the build-time banner it prints on stderr (C level), which would join a command's
one-line error output or a worker process's log."""

from __future__ import annotations

import importlib
import os
import sys


def quiet_import(name: str = "pybullet") -> None:
    """Import ``name`` with the process's stderr (file descriptor 2) sent to /dev/null meanwhile."""
    if name in sys.modules:
        return
    sys.stderr.flush()
    saved = os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        importlib.import_module(name)
    finally:
        os.close(null)
        os.dup2(saved, 2)
        os.close(saved)
