"""Raw message payloads of one topic as one shared buffer, and the gather the bulk decoders use."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

IntArray = npt.NDArray[np.int64]


@dataclass
class Batch:
    """Raw message payloads of one topic sharing one buffer.

    ``offsets``/``lengths`` (bytes) locate each payload in ``buf``; ``log_ns`` is the log time (ns).
    """

    buf: bytes
    offsets: IntArray
    lengths: IntArray
    log_ns: IntArray

    def __len__(self) -> int:
        return len(self.offsets)

    def payload(self, i: int) -> memoryview:
        """The ``i``-th payload (no copy)."""
        o = int(self.offsets[i])
        return memoryview(self.buf)[o : o + int(self.lengths[i])]

    @staticmethod
    def from_payloads(payloads: list[bytes], log_ns: list[int]) -> Batch:
        """One batch from separate payloads (joined into one buffer)."""
        lengths = np.fromiter((len(p) for p in payloads), dtype=np.int64, count=len(payloads))
        offsets = np.zeros(len(payloads), dtype=np.int64)
        if len(payloads) > 1:
            np.cumsum(lengths[:-1], out=offsets[1:])
        return Batch(b"".join(payloads), offsets, lengths, np.asarray(log_ns, dtype=np.int64).reshape(-1))


def gather_bytes(arr: npt.NDArray[np.uint8], offsets: IntArray, nbytes: int) -> npt.NDArray[np.uint8]:
    """(n, nbytes) bytes starting at each offset of ``arr`` (one memcpy per row, through a void view)."""
    n = len(offsets)
    if n == 0 or nbytes == 0:
        return np.zeros((n, nbytes), dtype=np.uint8)
    windows = np.ndarray((len(arr) - nbytes + 1,), dtype=np.dtype((np.void, nbytes)), buffer=arr, strides=(1,))
    rows: npt.NDArray[np.uint8] = windows[offsets].view(np.uint8).reshape(n, nbytes)
    return rows
