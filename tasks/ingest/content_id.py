"""The recording's content id (``../shared/RECORDING.md``): the first 16 hex digits of the SHA-256 of its bytes.

Hashing every byte is the floor of an ingest's time on a camera-heavy recording, where the readers skip the
camera chunks unread. ``content_id_beside`` therefore hashes on a second thread while the caller reads and
decodes: ``hashlib`` and file reads release the GIL, so on two cores the ingest takes about the longer of the
two instead of their sum, and memory grows by one block.
"""

from __future__ import annotations

import errno
import hashlib
import stat
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tasks.errors import RecordingError

CONTENT_ID_HEX = 16
"""Hex digits of the SHA-256 kept as the content id (``../shared/RECORDING.md``)."""

HASH_BLOCK_BYTES = 1 << 20
"""Bytes read and hashed at once: large enough that the per-read system call cost vanishes beside SHA-256's
(about 1.4 GB/s per core with the CPU's SHA instructions), small enough to stay in the core's L2 cache."""


class _AbandonedError(Exception):
    """The caller no longer needs the id (its read failed first)."""


def check_source(source: Path) -> None:
    """A recording must be a regular file or a folder: anything else is named for what it is."""
    try:
        st = source.stat()
    except FileNotFoundError:
        what = "a dangling symbolic link" if source.is_symlink() else "no such file or folder"
        raise RecordingError(source, what) from None
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise RecordingError(source, "a symbolic link loop, not a recording") from err
        msg = f"cannot read it ({err.strerror})"
        raise RecordingError(source, msg) from err
    kinds = {stat.S_ISFIFO: "a FIFO (named pipe)", stat.S_ISSOCK: "a socket", stat.S_ISCHR: "a character device",
             stat.S_ISBLK: "a block device"}  # fmt: skip
    for test, what in kinds.items():
        if test(st.st_mode):
            msg = f"{what}, not a recording file or folder"
            raise RecordingError(source, msg)


def recording_id_of(source: Path, stop: threading.Event | None = None) -> str:
    """First 16 hex digits of the SHA-256 of the recording's bytes (a folder: its files in name order).

    ``stop``: when set, the hashing gives up between blocks (raises an internal ``_AbandonedError``)."""
    source = Path(source)
    check_source(source)
    h = hashlib.sha256()
    if source.is_dir():
        files = sorted((p for p in source.rglob("*") if p.is_file()), key=lambda p: p.relative_to(source).as_posix())
    else:
        files = [source]
    buf = bytearray(HASH_BLOCK_BYTES)
    view = memoryview(buf)
    for f in files:
        try:
            with f.open("rb", buffering=0) as fh:
                while n := fh.readinto(buf):
                    h.update(view[:n])
                    if stop is not None and stop.is_set():
                        raise _AbandonedError
        except OSError as err:
            msg = f"cannot read it ({err.strerror})"
            raise RecordingError(f, msg) from err
    return h.hexdigest()[:CONTENT_ID_HEX]


class PendingId:
    """The content id of ``source`` being hashed on a second thread (started at construction), or ``known``
    when the caller already has it (no thread, nothing read)."""

    def __init__(self, source: Path, known: str | None = None) -> None:
        self._stop = threading.Event()
        self._id = known or ""
        self._error: Exception | None = None
        self._thread: threading.Thread | None = None
        if known is None:
            self._thread = threading.Thread(target=self._run, args=(Path(source),), name="pbd-content-id", daemon=True)
            self._thread.start()

    def _run(self, source: Path) -> None:
        try:
            self._id = recording_id_of(source, self._stop)
        except Exception as err:  # handed to the caller by result()
            self._error = err

    def result(self) -> str:
        """Wait for the id; raises what the hashing raised (a ``RecordingError`` for an unreadable file)."""
        if self._thread is not None:
            self._thread.join()
        if self._error is not None:
            raise self._error
        return self._id

    def abandon(self) -> None:
        """Stop hashing at the next block and wait for the thread (the file is closed when this returns)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()


@contextmanager
def content_id_beside(source: Path, known: str | None = None) -> Iterator[PendingId]:
    """Hash ``source`` on a second thread for the duration of the block; ``.result()`` gives the id (``known``,
    unhashed, when given). Leaving the block early (an exception) abandons the hashing and waits for the thread,
    so no file stays open."""
    pending = PendingId(source, known)
    try:
        yield pending
    finally:
        pending.abandon()
