"""Content ids of recordings for cache keys, without reading an unchanged file again.

A recording's content id (``tasks.ingest.api.recording_id_of``) is the SHA-256 of all its bytes: every run of an
archive would read the whole archive again just to find that nothing changed (a 1.5 GB recording is seconds of
IO and hashing). Instead the id is remembered under the file's identity and state: device, inode, size,
modification and status-change times in nanoseconds (every file of a rosbag2 folder). Writing a file changes its
mtime and ctime, and replacing it changes its inode; even a tool that restores the mtime afterwards (``cp -p``,
``rsync -t``, ``touch -d``) changes the ctime, which no user call can set back. So a remembered id is only used
for the very same bytes. A file changed less than ``SETTLE_S`` before it was read may still be being written
(the same clock tick may hold two writes): its id is computed but not remembered.

The ids live in ``<store>/prefect-results/content-ids.sqlite``, read once per process (one query for the whole
archive), each new id written as it is found.
"""

from __future__ import annotations

import contextlib
import hashlib
import sqlite3
import threading
import time
from pathlib import Path

from flows.caching import results_dir
from tasks.ingest.api import recording_id_of

MEMO_FILENAME = "content-ids.sqlite"
"""The remembered ids of a store, under its ``prefect-results`` folder."""

SETTLE_S = 2.0
"""A file modified or changed less than this many seconds before it is read may still be being written; its id
is not remembered."""

SQLITE_TIMEOUT_S = 30.0
"""Wait for another process's write lock on the memo, seconds."""

_LOCK = threading.Lock()
_LOADED: dict[Path, dict[str, str]] = {}
"""Per memo file, the ids read from it by this process (and those it added)."""


def state_key(source: Path) -> str | None:
    """Hex digest of the identity and state of ``source`` (a file, or every file under a folder), or None when a
    file of it changed less than ``SETTLE_S`` ago (or cannot be listed)."""
    source = Path(source)
    files = sorted(p for p in source.rglob("*") if p.is_file()) if source.is_dir() else [source]
    settled = time.time_ns() - int(SETTLE_S * 1e9)
    parts = []
    try:
        for f in files:
            st = f.stat()
            if st.st_mtime_ns > settled or st.st_ctime_ns > settled:
                return None
            rel = f.relative_to(source).as_posix() if f != source else ""
            parts.append(f"{rel}\0{st.st_dev}\0{st.st_ino}\0{st.st_size}\0{st.st_mtime_ns}\0{st.st_ctime_ns}")
    except OSError:
        return None
    return hashlib.sha256(f"{source.resolve()}\n".encode() + "\n".join(parts).encode()).hexdigest()


def _connect(memo: Path) -> sqlite3.Connection:
    memo.parent.mkdir(parents=True, exist_ok=True)
    db = sqlite3.connect(memo, timeout=SQLITE_TIMEOUT_S)
    db.execute("CREATE TABLE IF NOT EXISTS ids (state TEXT PRIMARY KEY, id TEXT NOT NULL)")
    return db


def _remembered(memo: Path) -> dict[str, str]:
    """The ids in ``memo``, read on first use in this process (callers hold ``_LOCK``)."""
    if memo not in _LOADED:
        db = _connect(memo)
        try:
            _LOADED[memo] = dict(db.execute("SELECT state, id FROM ids").fetchall())
        finally:
            db.close()
    return _LOADED[memo]


def _lookup(memo: Path, key: str | None) -> str | None:
    """The id remembered under state ``key`` in ``memo`` (None without one; an unreadable memo is passed over)."""
    if key is not None:
        with _LOCK, contextlib.suppress(sqlite3.Error, OSError):
            return _remembered(memo).get(key)
    return None


def remembered_id(store_root: str | Path, source: Path) -> str | None:
    """The content id remembered for ``source`` in its present state, None when there is none (nothing is hashed)."""
    return _lookup(results_dir(store_root) / MEMO_FILENAME, state_key(source))


def content_id(store_root: str | Path, source: Path) -> str:
    """``recording_id_of(source)``, remembered in the store under the file's state (see the module's doc). A memo
    that cannot be read or written (a read-only store, a damaged file) is passed over: the bytes are hashed."""
    memo = results_dir(store_root) / MEMO_FILENAME
    key = state_key(source)
    if (known := _lookup(memo, key)) is not None:
        return known
    recording_id = recording_id_of(source)
    if key is not None:
        with _LOCK, contextlib.suppress(sqlite3.Error, OSError):
            db = _connect(memo)
            try:
                with db:
                    db.execute("INSERT OR REPLACE INTO ids (state, id) VALUES (?, ?)", (key, recording_id))
            finally:
                db.close()
            _remembered(memo)[key] = recording_id
    return recording_id
