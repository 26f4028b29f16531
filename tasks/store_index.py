"""``descriptors/<name>/index.json``: its rows, reading and replacing it, and adopting a version file it misses.

The index lists versions 1..N in order; it is the only file of the store that is replaced (atomically). A version
file the index does not list is what a writer killed between the two steps of ``Store.put_descriptor`` leaves;
``adoptable`` decides whether the next writer lists it.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from schemas.descriptor import Descriptor
from schemas.limits import MAX_DESCRIPTOR_BYTES
from tasks.atomic import write_bytes_atomic
from tasks.errors import PbdError, StoreError


@dataclass(frozen=True)
class VersionEntry:
    """One row of ``descriptors/<name>/index.json``."""

    version: int
    id: str
    created: str
    recording: str | None
    parameters: dict[str, Any]
    code_version: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready row."""
        return {
            "version": self.version,
            "id": self.id,
            "created": self.created,
            "recording": self.recording,
            "parameters": self.parameters,
            "code_version": self.code_version,
        }


def read_index(path: Path) -> list[VersionEntry]:
    """The rows of an ``index.json``; ``StoreError`` when it is not a list of version rows."""
    try:
        rows = json.loads(path.read_bytes())
        entries = [VersionEntry(**row) for row in rows]
    except (OSError, ValueError, TypeError, RecursionError) as err:
        msg = f"corrupt index ({type(err).__name__}); the next write under this name rebuilds it"
        raise StoreError(path, msg) from err
    if [e.version for e in entries] != list(range(1, len(entries) + 1)):
        msg = "corrupt index (versions not 1..N in order); the next write under this name rebuilds it"
        raise StoreError(path, msg)
    return entries


def lists(index: Path, version: int) -> bool:
    """True when ``index`` is readable and lists ``version``."""
    try:
        return any(e.version == version for e in read_index(index))
    except StoreError:
        return False


def write_index(path: Path, entries: list[VersionEntry]) -> None:
    """Replace ``index.json`` atomically (the only file the store rewrites)."""
    text = json.dumps([e.to_dict() for e in entries], indent=2) + "\n"
    write_bytes_atomic(path, text.encode(), overwrite=True, step="descriptor.index")


def adoptable(path: Path, name: str, number: int, entries: list[VersionEntry]) -> VersionEntry | None:
    """The index row for a version file the index does not list, or None when it cannot be adopted: not the
    next number, unreadable, invalid, of another name, or the same content as the version before it."""
    if number != (entries[-1].version + 1 if entries else 1):
        return None
    try:
        desc = Descriptor.from_bytes(path.read_bytes()[: MAX_DESCRIPTOR_BYTES + 1], source=str(path))
        created = dt.datetime.fromtimestamp(path.stat().st_mtime, dt.UTC).isoformat(timespec="seconds")
    except (OSError, PbdError):
        return None
    if desc.name != name or (entries and entries[-1].id == desc.id):
        return None
    return VersionEntry(number, desc.id, created, desc.recording_id, desc.parameters, desc.code_version)
