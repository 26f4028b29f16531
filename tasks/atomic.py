"""Atomic writes, the fault-injection hook of the store's write protocols, and file-system errors as one line.

Every store write goes through a temporary file or folder that is renamed (or hard-linked, which refuses to
replace) into place, so a reader or a killed writer never sees half a file. Each step of a protocol calls
``checkpoint(step, path)``; with ``$PBD_FAULT_STEP`` set to that step the process dies there
(``$PBD_FAULT_MODE=kill``, exit ``FAULT_KILL_EXIT`` without clean-up, as after ``kill -9``) or the step fails
with the ``OSError`` of that errno name (``$PBD_FAULT_MODE=ENOSPC``, the default, as on a full disk; ``EROFS``
for a read-only file system, ``EACCES`` for no permission). The hook is how the
fault-injection tests reach every step; it costs one environment look-up per step otherwise.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import tempfile
from collections.abc import Iterator
from pathlib import Path

from tasks.errors import StoreError

FAULT_STEP_ENV = "PBD_FAULT_STEP"
"""Environment variable naming the protocol step at which to fail (test hook)."""
FAULT_MODE_ENV = "PBD_FAULT_MODE"
"""``kill`` (die at the step) or an errno name such as ``ENOSPC`` (the default), ``EROFS``, ``EACCES`` (raise it)."""
FAULT_KILL_EXIT = 137
"""Exit status of a process killed by the hook: what a shell reports after ``kill -9``."""


def _modes() -> tuple[int, int]:
    """(file mode, folder mode) the process's umask allows (read once, at import, while one thread runs)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask, 0o777 & ~mask


FILE_MODE, DIR_MODE = _modes()
"""Permissions of the store's files and folders: what the umask allows (temporary files start as 0600 and
staging folders as 0700, which would make a shared store unreadable by the team)."""

WRITE_STEPS = ("file.written", "file.linked")
"""Steps of ``write_bytes_atomic`` for a file that is never replaced (prefix ``file`` unless the caller names it)."""


def checkpoint(step: str, path: Path) -> None:
    """A step of a write protocol has completed; the fault hook may kill the process or fail the step here."""
    if os.environ.get(FAULT_STEP_ENV) != step:
        return
    mode = os.environ.get(FAULT_MODE_ENV, "ENOSPC").upper()
    if mode == "KILL":
        os._exit(FAULT_KILL_EXIT)
    code = getattr(errno, mode, errno.ENOSPC)
    raise OSError(code, os.strerror(code), str(path))


def os_error_text(err: OSError) -> str:
    """The cause of an ``OSError`` in a few words (``No space left on device``), without repeating the path."""
    if not err.strerror:
        return type(err).__name__
    text = str(err.strerror)
    if "Detail: " in text:  # pyarrow: "Error writing bytes to file. Detail: [errno 28] No space left on device"
        text = re.sub(r"^\[errno \d+\] ", "", text.split("Detail: ", 1)[1])
    return text.strip()


@contextlib.contextmanager
def write_errors(path: Path, doing: str = "cannot write") -> Iterator[None]:
    """Turn an ``OSError`` (no space, read-only file system, no permission) into a one-line ``StoreError`` naming
    the file the system named, else ``path``, and the cause (after ``doing``, when given)."""
    try:
        yield
    except StoreError:
        raise
    except OSError as err:
        where = err.filename if isinstance(err.filename, str) and err.filename else path
        msg = f"{doing}: {os_error_text(err)}" if doing else os_error_text(err)
        raise StoreError(where, msg) from err


def fsync_dir(folder: Path) -> None:
    """Make a rename or link in ``folder`` durable (a no-op where folders cannot be opened)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def write_bytes_atomic(path: Path, data: bytes, *, overwrite: bool = False, step: str = "file") -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder, then link (or rename) it in place.

    Refuses to replace an existing file unless ``overwrite`` (only indexes are rewritten). A failure (no space,
    read-only, no permission) is a ``StoreError`` naming the path and leaves no temporary file behind. Steps
    ``<step>.written`` (temporary file complete) and ``<step>.linked`` (in place, temporary name not yet removed).
    """
    with write_errors(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            os.fchmod(fd, FILE_MODE)
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            checkpoint(f"{step}.written", path)
            if overwrite:
                Path(tmp).replace(path)
            else:
                try:
                    os.link(tmp, path)  # fails if path exists: no overwrite, even under a race
                except FileExistsError as err:
                    msg = "refusing to overwrite an existing artefact"
                    raise StoreError(path, msg) from err
            fsync_dir(path.parent)
            checkpoint(f"{step}.linked", path)
        finally:
            with contextlib.suppress(FileNotFoundError):
                Path(tmp).unlink()
