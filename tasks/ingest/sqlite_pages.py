"""Rows of a damaged rosbag2 sqlite3 file, read from its b-tree leaf pages without sqlite (``--recover``).

A truncated or damaged file makes sqlite refuse the whole table (a lost interior page hides every leaf below
it), though most leaf pages are intact. Each table leaf page (type 13) is parsed as the file format says
(https://www.sqlite.org/fileformat2.html, "B-tree Pages", "Record Format"); a cell is a row of ``messages``
when its record is (NULL rowid alias, integer topic id, integer timestamp, blob) and the topic id is one the
topics table defines. Payloads that spill onto overflow pages are followed; a row whose chain is cut is lost.
"""

from __future__ import annotations

import shutil
import struct
from dataclasses import dataclass, field
from pathlib import Path

from tasks.ingest.selection import SMALL_PAYLOAD_BYTES, Keep
from tasks.ingest.source import FileSource

HEADER_PAGES_BYTES = 4 * 1024 * 1024
"""Bytes at the front of a damaged file given to sqlite to read its schema and topics tables: rosbag2 creates
them first, so their pages come before the messages."""
_LEAF_TABLE = 13
_INT_SIZES = {1: 1, 2: 2, 3: 3, 4: 4, 5: 6, 6: 8, 8: 0, 9: 0}
"""Bytes of each integer serial type of the record format (8 and 9 are the constants 0 and 1)."""


@dataclass
class MessageRows:
    """Rows of the messages table: counts per topic id, and the kept rows (ids, stamps ns, payloads)."""

    topic_ids: set[int]
    counts: dict[int, int] = field(default_factory=dict)
    rows: dict[int, tuple[list[int], list[int], list[bytes]]] = field(default_factory=dict)
    log_range: tuple[int, int] | None = None
    lost_estimate: int = 0
    """Rows estimated lost (pages the header counts that the file lacks, at the rows per page found)."""

    def count(self, tid: int, n: int, lo: int, hi: int) -> None:
        """``n`` rows of topic ``tid`` with timestamps in [lo, hi] ns."""
        self.counts[tid] = self.counts.get(tid, 0) + n
        self.log_range = (
            (lo, hi) if self.log_range is None else (min(self.log_range[0], lo), max(self.log_range[1], hi))
        )

    def add(self, rid: int, tid: int, stamp_ns: int, data: bytes) -> None:
        """A kept row."""
        ids, stamps, payloads = self.rows.setdefault(tid, ([], [], []))
        ids.append(rid)
        stamps.append(stamp_ns)
        payloads.append(data)

    @property
    def total(self) -> int:
        """Rows counted over all topics."""
        return sum(self.counts.values())


def patched_prefix(db: Path, out: Path, nbytes: int) -> None:
    """Copy the first whole pages of ``db`` (up to ``nbytes``) to ``out`` with the header's page count made to
    match, so sqlite reads what is there."""
    with db.open("rb") as fin, out.open("wb") as fout:
        head = bytearray(fin.read(100))
        page = _page_size(bytes(head))
        fin.seek(0)
        shutil.copyfileobj(fin, fout, nbytes)
    size = min(out.stat().st_size, nbytes) // page * page
    with out.open("r+b") as fh:
        fh.truncate(size)
        fh.seek(28)
        fh.write(struct.pack(">I", size // page))
        fh.seek(92)
        fh.write(bytes(head[24:28]))  # version-valid-for = change counter: the page count above is trusted


def _page_size(head: bytes) -> int:
    (raw,) = struct.unpack_from(">H", head, 16)
    return 65536 if raw == 1 else max(int(raw), 512)


def _varint(buf: bytes, pos: int) -> tuple[int, int]:
    """sqlite's big-endian varint at ``pos``: (value, position after it)."""
    value = 0
    for i in range(8):
        b = buf[pos + i]
        value = (value << 7) | (b & 0x7F)
        if b < 0x80:
            return value, pos + i + 1
    return (value << 8) | buf[pos + 8], pos + 9


def _int(buf: bytes, pos: int, serial: int) -> int:
    if serial == 8:
        return 0
    if serial == 9:
        return 1
    n = _INT_SIZES[serial]
    return int.from_bytes(buf[pos : pos + n], "big", signed=True)


@dataclass
class _Leaves:
    """What reading the cells of one file needs: the file, its page geometry and what to keep."""

    src: FileSource
    page: int
    usable: int
    topic_ids: set[int]
    keep: dict[int, Keep]
    first_small: set[int] = field(default_factory=set)


def scan_message_rows(db: Path, topic_ids: set[int], keep: dict[int, Keep]) -> MessageRows:
    """Every intact row of the messages table in the leaf pages of ``db``, payloads kept as ``keep`` says."""
    rows = MessageRows(topic_ids)
    seen: set[int] = set()
    kept: dict[int, tuple[int, int, bytes]] = {}
    with FileSource(db) as src:
        head = src.read(0, 100)
        page = _page_size(head)
        leaves = _Leaves(src, page, page - head[20], topic_ids, keep)
        pages = src.size // page
        for n in range(1, pages + 1):
            buf = src.read((n - 1) * page, page)
            hdr = 100 if n == 1 else 0
            if buf[hdr] != _LEAF_TABLE:
                continue
            (cells,) = struct.unpack_from(">H", buf, hdr + 3)
            for c in range(cells):
                try:
                    (off,) = struct.unpack_from(">H", buf, hdr + 8 + 2 * c)
                    row = _cell(leaves, buf, off)
                except (IndexError, struct.error, KeyError):
                    continue
                if row is None or row[0] in seen:
                    continue
                rid, tid, stamp, data = row
                seen.add(rid)
                rows.count(tid, 1, stamp, stamp)
                if data is not None:
                    kept[rid] = (tid, stamp, data)
        (declared,) = struct.unpack_from(">I", head, 28)
        if head[92:96] == head[24:28] and declared > pages and pages:
            rows.lost_estimate = round((declared - pages) * len(seen) / pages)
    for rid in sorted(kept):
        tid, stamp, data = kept[rid]
        rows.add(rid, tid, stamp, data)
    return rows


def _cell(leaves: _Leaves, buf: bytes, off: int) -> tuple[int, int, int, bytes | None] | None:
    """(rowid, topic id, timestamp, payload or None when not kept) of a messages row, None for other rows and
    rows whose payload is cut."""
    size, p = _varint(buf, off)
    rid, p = _varint(buf, p)
    usable = leaves.usable
    x = usable - 35
    if size <= x:
        local = size
    else:
        m = ((usable - 12) * 32 // 255) - 23
        k = m + ((size - m) % (usable - 4))
        local = k if k <= x else m
    payload = buf[p : p + local]
    hsize, q = _varint(payload, 0)
    serials: list[int] = []
    while q < hsize and len(serials) < 5:
        st, q = _varint(payload, q)
        serials.append(st)
    if len(serials) != 4 or serials[0] != 0 or serials[1] not in _INT_SIZES or serials[2] not in _INT_SIZES:
        return None
    if serials[3] < 12 or serials[3] % 2:
        return None
    pos = hsize
    tid = _int(payload, pos, serials[1])
    pos += _INT_SIZES[serials[1]]
    stamp = _int(payload, pos, serials[2])
    pos += _INT_SIZES[serials[2]]
    blob_len = (serials[3] - 12) // 2
    if tid not in leaves.topic_ids or pos + blob_len != size:
        return None
    k_ = leaves.keep.get(tid, Keep.ALL)
    small_ok = k_ is Keep.SMALL and (blob_len <= SMALL_PAYLOAD_BYTES or tid not in leaves.first_small)
    if k_ is Keep.NONE or (k_ is Keep.SMALL and not small_ok):
        return rid, tid, stamp, None
    whole = bytes(payload) if local == size else _overflow(leaves, buf, p + local, payload, size)
    if whole is None:
        return None
    if k_ is Keep.SMALL:
        leaves.first_small.add(tid)
    return rid, tid, stamp, whole[pos:]


def _overflow(leaves: _Leaves, buf: bytes, at: int, local: bytes, size: int) -> bytes | None:
    """The whole payload: the local part then the overflow chain (None when the chain leaves the file)."""
    src, page, usable = leaves.src, leaves.page, leaves.usable
    (nxt,) = struct.unpack_from(">I", buf, at)
    parts = [local]
    have = len(local)
    while have < size:
        if nxt == 0 or nxt * page > src.size:
            return None
        chunk = src.read((nxt - 1) * page, page)
        (nxt,) = struct.unpack_from(">I", chunk, 0)
        take = min(usable - 4, size - have)
        parts.append(chunk[4 : 4 + take])
        have += take
    return b"".join(parts)
