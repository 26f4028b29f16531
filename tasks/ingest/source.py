"""Byte ranges of a recording file, read on demand: memory holds one record (or one window), never the file."""

from __future__ import annotations

import os
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

WINDOW_BYTES = 64 * 1024
"""Bytes read at once for small records (schemas, channels, index records, a few markers between camera
frames): one read serves the records that follow, and a scattered read costs little more than its record."""


class FileSource:
    """A recording file opened for ranged reads; ``largest_read`` is the largest range read at once (bytes)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._fh: BinaryIO = self.path.open("rb")
        self.size = os.fstat(self._fh.fileno()).st_size
        self._base = 0
        self._window = b""
        self.largest_read = 0

    def read(self, pos: int, n: int) -> bytes:
        """Up to ``n`` bytes from ``pos`` (fewer at the end of the file)."""
        n = max(0, min(n, self.size - pos))
        if self._base <= pos and pos + n <= self._base + len(self._window):
            o = pos - self._base
            return self._window[o : o + n]
        self._fh.seek(pos)
        if n >= WINDOW_BYTES:
            self.largest_read = max(self.largest_read, n)
            return self._fh.read(n)
        self._window = self._fh.read(WINDOW_BYTES)
        self._base = pos
        return self._window[:n]

    def close(self) -> None:
        """Close the file."""
        self._window = b""
        self._fh.close()

    def __enter__(self) -> FileSource:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
