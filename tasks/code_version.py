"""Explicit code versions for cache keys: a hash of the source files of the modules a stage runs."""

from __future__ import annotations

import hashlib
import importlib.util
from functools import cache
from pathlib import Path


@cache
def code_version(*packages: str) -> str:
    """First 12 hex digits of SHA-256 over the sources of ``packages`` (modules or package folders).

    Prefect's ``TASK_SOURCE`` hashes only a task's body; this covers every helper module the stage calls.
    """
    digest = hashlib.sha256()
    for name in sorted(packages):
        spec = importlib.util.find_spec(name)
        if spec is None or spec.origin is None:
            msg = f"code_version: no module {name}"
            raise ValueError(msg)
        origin = Path(spec.origin)
        files = sorted(origin.parent.rglob("*.py")) if origin.name == "__init__.py" else [origin]
        for path in files:
            digest.update(str(path.relative_to(origin.parent.parent)).encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:12]
