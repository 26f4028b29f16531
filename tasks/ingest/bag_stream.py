"""A streaming ROS 1 bag (format 2.0) reader: records front to back, chunks decompressed once each.

Why not ``rosbags.rosbag1.Reader``: it visits messages in time order through the index and re-reads and
re-decompresses a chunk every time the merge switches chunks (about 100 us per message on a bag with
interleaved topics), and it cannot read a bag whose index (at the end) is cut off. This reader walks the
records in file order, so a truncated bag reports the byte where it ends, and ``recover=True`` keeps every
message before the damage (``rosbag reindex`` and ``rosbag fix`` in one: a recorder killed before it wrote the
index leaves such a bag). Topic and type names are normalised the way rosbags does (``pkg/Type`` ->
``pkg/msg/Type``; repeated slashes collapsed).
"""

from __future__ import annotations

import bz2
import struct
from dataclasses import dataclass, field
from pathlib import Path

import lz4.frame
import numpy as np
import numpy.typing as npt

from tasks.errors import RecordingError, TruncatedRecordingError
from tasks.ingest.batch import Batch
from tasks.ingest.selection import SMALL_PAYLOAD_BYTES, Keep, Want, keep_all
from tasks.ingest.source import WINDOW_BYTES as WINDOW
from tasks.ingest.source import FileSource

IntArray = npt.NDArray[np.int64]

OP_MSG_DATA, OP_BAG_HEADER, OP_INDEX_DATA, OP_CHUNK, OP_CHUNK_INFO, OP_CONNECTION = 0x02, 0x03, 0x04, 0x05, 0x06, 0x07
_U32 = struct.Struct("<I")
_INDEX_DATA_BYTES = 4 + 46 + 4
"""An IndexData record without its entries: header length, the fields op, ver, conn and count, data length;
each entry adds 12 bytes."""


def normalize_topic(name: str) -> str:
    """Topic name as rosbags reports it (leading slash kept, empty segments dropped)."""
    return f"{'/' * name.startswith('/')}{'/'.join(x for x in name.split('/') if x)}"


@dataclass
class BagConnection:
    """A ROS 1 connection: topic, type (``pkg/msg/Type``) and the message definition text."""

    id: int
    topic: str
    msgtype: str
    msgdef: str


@dataclass
class BagContent:
    """Connections and raw messages (per connection id) of a bag."""

    want: Want = keep_all
    connections: dict[int, BagConnection] = field(default_factory=dict)
    payloads: dict[int, list[bytes]] = field(default_factory=dict)
    stamps: dict[int, list[int]] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    """Messages per connection, kept or not."""
    log_lo: int | None = None
    log_hi: int | None = None
    index_pos: int = 0
    chunk_count: int = 0
    """Chunks the bag header announces (0: not written, as when the recorder was killed)."""
    chunks_read: int = 0
    messages_read: int = 0
    chunk_messages_read: int = 0
    chunk_bytes_read: int = 0
    rate_messages: int = 0
    rate_bytes: int = 0
    """Messages of the complete chunks read after the first (which also holds the connection definitions),
    and the file bytes they and their index records span: the bag's messages per byte, to estimate a loss."""
    data_resume: int = 0
    """Where the data after the last chunk read resumes: past that chunk's index records, as long as its
    messages say they are (a cut inside them loses no message)."""
    record_pos: int = 0
    """Where the top-level record being read starts (the damage offset when it is bad)."""
    damage: str | None = None
    """What was wrong where reading stopped (only with ``recover=True``)."""
    damage_offset: int | None = None
    lost_messages: int = 0
    """The messages lost (see ``_note_damage``)."""
    lost_estimated: bool = False
    """The loss is estimated from the bag header's index position (the end of the data): otherwise it is a
    lower bound (what was recorded after the damage cannot be counted)."""
    past_data: bool = False
    """The damage lies in the index after the last chunk: no message was lost."""
    _keep: dict[int, Keep] = field(default_factory=dict)
    _first_kept: set[int] = field(default_factory=set)

    def keep(self, conn_id: int) -> Keep:
        """What to keep of a connection's messages (an undefined connection: all, to report it)."""
        k = self._keep.get(conn_id)
        if k is None:
            c = self.connections.get(conn_id)
            if c is None:
                return Keep.ALL
            k = self._keep[conn_id] = self.want(c.topic, c.msgtype)
        return k

    def add_message(self, conn: int, stamp_ns: int, data: memoryview | bytes) -> None:
        """One message: counted, its payload kept as the selection says."""
        self.counts[conn] = self.counts.get(conn, 0) + 1
        self.messages_read += 1
        self.note_log(stamp_ns, stamp_ns)
        k = self.keep(conn)
        if k is Keep.NONE:
            return
        if k is Keep.SMALL:
            if conn in self._first_kept and len(data) > SMALL_PAYLOAD_BYTES:
                return
            self._first_kept.add(conn)
        self.payloads.setdefault(conn, []).append(bytes(data))
        self.stamps.setdefault(conn, []).append(stamp_ns)

    def note_log(self, lo: int, hi: int) -> None:
        """Widen the log time range to [lo, hi] (ns)."""
        self.log_lo = lo if self.log_lo is None else min(self.log_lo, lo)
        self.log_hi = hi if self.log_hi is None else max(self.log_hi, hi)

    def batch(self, conn_id: int) -> Batch | None:
        """The raw messages of one connection as a batch (None when it has none)."""
        p = self.payloads.get(conn_id)
        return Batch.from_payloads(p, self.stamps[conn_id]) if p else None


class _BadRecordError(Exception):
    """Internal: a malformed record."""


def _fields(buf: bytes | memoryview, start: int, end: int) -> dict[bytes, bytes]:
    out: dict[bytes, bytes] = {}
    i = start
    while i < end:
        if i + 4 > end:
            raise _BadRecordError("header field cut off")
        (n,) = _U32.unpack_from(buf, i)
        j = i + 4 + n
        if j > end:
            raise _BadRecordError("header field runs past its header")
        name, eq, value = bytes(buf[i + 4 : j]).partition(b"=")
        if not eq:
            raise _BadRecordError("header field without '='")
        out[name] = value
        i = j
    return out


def _normalize_type(name: str) -> str:
    parts = [p for p in name.split("/") if p]
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else "/".join(parts)


def _connection(hdr: dict[bytes, bytes], data: bytes | memoryview, start: int, end: int) -> BagConnection:
    conn_id = _U32.unpack(hdr[b"conn"])[0]
    topic = hdr[b"topic"].decode("utf-8", errors="replace")
    info = _fields(data, start, end)
    return BagConnection(
        conn_id,
        normalize_topic(topic),
        _normalize_type(info.get(b"type", b"").decode("utf-8", errors="replace")),
        info.get(b"message_definition", b"").decode("utf-8", errors="replace"),
    )


def _stamp(hdr: dict[bytes, bytes]) -> int:
    secs, nsecs = struct.unpack("<II", hdr[b"time"])
    return int(secs) * 1_000_000_000 + int(nsecs)


def _walk_chunk(buf: bytes, content: BagContent) -> int:
    """Walk the records of a decompressed chunk; returns where it stopped (``len(buf)`` unless cut off)."""
    pos = 0
    end = len(buf)
    unpack = _U32.unpack_from
    view = memoryview(buf)
    while pos < end:
        if pos + 4 > end:
            return pos
        (hlen,) = unpack(buf, pos)
        hend = pos + 4 + hlen
        if hend + 4 > end:
            return pos
        (dlen,) = unpack(buf, hend)
        dstart = hend + 4
        dend = dstart + dlen
        if dend > end:
            return pos
        if hlen == 0:
            rest = bytes(buf[pos:end]).lstrip(b"\x00")
            pos = end - len(rest)
            continue
        hdr = _fields(buf, pos + 4, hend)
        op_raw = hdr.get(b"op")
        if op_raw is None or len(op_raw) != 1:
            raise _BadRecordError(f"record at byte {pos} of a chunk has no op code")
        op = op_raw[0]
        if op == OP_MSG_DATA:
            content.add_message(_U32.unpack(hdr[b"conn"])[0], _stamp(hdr), view[dstart:dend])
        elif op == OP_CONNECTION:
            c = _connection(hdr, buf, dstart, dend)
            content.connections.setdefault(c.id, c)
        elif op == OP_CHUNK:
            raise _BadRecordError("chunk inside a chunk")
        pos = dend
    return pos


def _header_end(src: FileSource, pos: int) -> tuple[int, int] | None:
    """(header length, header end) of the top-level record at ``pos``; None when its header or the data length
    after it is cut off."""
    if pos + 4 > src.size:
        return None
    (hlen,) = _U32.unpack(src.read(pos, 4))
    hend = pos + 4 + hlen
    if hend + 4 > src.size:
        return None
    return hlen, hend


def _record(src: FileSource, pos: int) -> tuple[dict[bytes, bytes], int, int] | None:
    """(header fields, data start, data end) of the top-level record at ``pos``; None when it is cut off."""
    got = _header_end(src, pos)
    if got is None:
        return None
    hlen, hend = got
    (dlen,) = _U32.unpack(src.read(hend, 4))
    if hend + 4 + dlen > src.size:
        return None
    hdr = _fields(src.read(pos + 4, hlen), 0, hlen) if hlen else {}
    return hdr, hend + 4, hend + 4 + dlen


def _op(hdr: dict[bytes, bytes], pos: int) -> int:
    op_raw = hdr.get(b"op")
    if op_raw is None or len(op_raw) != 1:
        raise _BadRecordError(f"record at byte {pos} has no op code")
    return op_raw[0]


def _chunk_index(src: FileSource, pos: int) -> tuple[int, list[tuple[int, int, int, int]], list[IntArray]]:
    """The IndexData records after a chunk ending at ``pos``: (where they end, [(connection, count, first
    log time ns, last log time ns)], the offsets of each connection's records in the uncompressed chunk)."""
    out: list[tuple[int, int, int, int]] = []
    offsets: list[IntArray] = []
    while True:
        got = _record(src, pos)
        if got is None:
            break
        hdr, dstart, dend = got
        if not hdr or hdr.get(b"op") != bytes([OP_INDEX_DATA]) or b"conn" not in hdr or b"count" not in hdr:
            break
        conn = _U32.unpack(hdr[b"conn"])[0]
        count = _U32.unpack(hdr[b"count"])[0]
        if count * 12 != dend - dstart:
            break
        entries = np.frombuffer(src.read(dstart, 12 * count), dtype="<u4").reshape(-1, 3).astype(np.int64)
        times = entries[:, 0] * 1_000_000_000 + entries[:, 1]
        lo, hi = (int(times.min()), int(times.max())) if count else (0, 0)
        out.append((int(conn), int(count), lo, hi))
        offsets.append(entries[:, 2])
        pos = dend
    return pos, out, offsets


def _skippable(content: BagContent, index: list[tuple[int, int, int, int]]) -> bool:
    """True when the chunk's index records show only connections already defined (a connection record sits in
    the chunk of its first message) whose payloads are not wanted."""
    return bool(index) and all(c in content.connections and content.keep(c) is Keep.NONE for c, *_ in index)


WANTED_SHARE = 0.25
"""Share of an uncompressed chunk's bytes below which only its wanted records are read (one read each) instead
of the whole chunk: a disk read costs about as much as copying a few hundred kB."""


def _count_unread(content: BagContent, index: list[tuple[int, int, int, int]], *, skip_all: bool) -> None:
    """Count the messages the index lists for connections whose payloads are not wanted (all, with ``skip_all``)."""
    for conn, count, lo, hi in index:
        if skip_all or content.keep(conn) is Keep.NONE:
            content.counts[conn] = content.counts.get(conn, 0) + count
            content.messages_read += count
            if count:
                content.note_log(lo, hi)


def _read_wanted_records(
    src: FileSource, start: int, size: int, content: BagContent, *, index: list[tuple[int, int, int, int]],
    offsets: list[IntArray],
) -> bool:  # fmt: skip
    """Read only the wanted message records of an uncompressed chunk (data at ``start``, ``size`` bytes), located
    by its index records, when they are a small share of it. False (nothing read): read the whole chunk."""
    if not index or not all(c in content.connections for c, *_ in index):
        return False
    every = np.sort(np.concatenate(offsets))
    if len(every) == 0 or int(every[-1]) >= size or (len(every) > 1 and not bool(np.all(np.diff(every) > 0))):
        return False
    ends = np.append(every[1:], size)  # a record ends where the next begins (or the chunk does)
    size_of = dict(zip(every.tolist(), (ends - every).tolist(), strict=True))
    wanted = sorted(o for (c, *_), offs in zip(index, offsets, strict=True) if content.keep(c) is not Keep.NONE
                    for o in offs.tolist())  # fmt: skip
    if sum(size_of[o] for o in wanted) > WANTED_SHARE * size:
        return False
    records = b"".join(src.read(start + o, size_of[o]) for o in wanted)
    before = content.messages_read
    if _walk_chunk(records, content) != len(records) or content.messages_read - before != len(wanted):
        msg = f"chunk at byte {start}: its index records do not point at its messages"
        raise _BadRecordError(msg)
    _count_unread(content, index, skip_all=False)
    return True


def _decompress(compression: str, raw: bytes, pos: int) -> bytes:
    try:
        if compression == "none":
            return raw
        if compression == "bz2":
            return bz2.decompress(raw)
        if compression == "lz4":
            return bytes(lz4.frame.decompress(raw))
    except (OSError, ValueError, RuntimeError, EOFError) as err:
        raise _BadRecordError(f"chunk at byte {pos}: {compression} data does not decompress") from err
    raise _BadRecordError(f"unknown chunk compression {compression!r}")


def _walk_top(src: FileSource, start: int, content: BagContent) -> int:
    """Walk the top-level records from ``start``; returns where it stopped (the file size unless cut off)."""
    pos = start
    while pos < src.size:
        content.record_pos = pos
        got = _record(src, pos)
        if got is None:
            return pos
        hdr, dstart, dend = got
        if not hdr:  # zero padding some writers leave before the index: resume at the index
            if content.index_pos > pos:
                pos = content.index_pos
            else:
                while pos < src.size and not src.read(pos, WINDOW).strip(b"\x00"):
                    pos += WINDOW
                block = src.read(pos, WINDOW)
                pos += len(block) - len(block.lstrip(b"\x00"))
            continue
        op = _op(hdr, pos)
        if op == OP_MSG_DATA:
            conn = _U32.unpack(hdr[b"conn"])[0]
            if content.keep(conn) is Keep.NONE:
                content.add_message(conn, _stamp(hdr), b"")
            else:
                content.add_message(conn, _stamp(hdr), src.read(dstart, dend - dstart))
        elif op == OP_BAG_HEADER and b"index_pos" in hdr:
            content.index_pos = int(struct.unpack("<Q", hdr[b"index_pos"])[0])
            if b"chunk_count" in hdr:
                content.chunk_count = int(_U32.unpack(hdr[b"chunk_count"])[0])
        elif op == OP_CONNECTION:
            data = src.read(dstart, dend - dstart)
            c = _connection(hdr, data, 0, len(data))
            content.connections.setdefault(c.id, c)
        elif op == OP_CHUNK:
            compression = hdr.get(b"compression", b"none").decode(errors="replace")
            (size,) = _U32.unpack(hdr[b"size"])
            nxt, index, offsets = _chunk_index(src, dend)
            before = content.messages_read
            counts_before = dict(content.counts)
            if _skippable(content, index):
                _count_unread(content, index, skip_all=True)
            elif (
                compression != "none"
                or size != dend - dstart
                or not _read_wanted_records(src, dstart, size, content, index=index, offsets=offsets)
            ):
                inner = _decompress(compression, src.read(dstart, dend - dstart), pos)
                if len(inner) != size:
                    raise _BadRecordError(f"chunk at byte {pos} decompressed to {len(inner)} bytes, header says {size}")
                if _walk_chunk(inner, content) != len(inner):
                    raise _BadRecordError(f"chunk at byte {pos} holds a cut-off record")
            if content.chunks_read:
                content.rate_messages += content.messages_read - before
                content.rate_bytes += nxt - pos
            per_conn = [n - counts_before.get(c, 0) for c, n in content.counts.items()]
            content.data_resume = dend + sum(_INDEX_DATA_BYTES + 12 * n for n in per_conn if n > 0)
            content.chunks_read += 1
            content.chunk_messages_read += content.messages_read - before
            content.chunk_bytes_read += size
            pos = nxt
            continue
        pos = dend
    return pos


def _cut_chunk(src: FileSource, pos: int, content: BagContent) -> tuple[int, int] | None:
    """Recovery at a top-level record cut off by the end of the file at ``pos``: when it is a chunk, keep the
    complete messages at the front of an uncompressed one (compressed data cannot be cut and decoded).
    Returns (the uncompressed size its header announces, the bytes of it the kept messages cover); None when
    it is not a chunk or its header is cut."""
    got = _header_end(src, pos)
    if got is None:
        return None
    hlen, hend = got
    hdr = _fields(src.read(pos + 4, hlen), 0, hlen)
    if hdr.get(b"op") != bytes([OP_CHUNK]) or b"size" not in hdr:
        return None
    covered = 0
    if hdr.get(b"compression", b"none") == b"none":
        covered = _walk_chunk(src.read(hend + 4, src.size - hend - 4), content)
    return int(_U32.unpack(hdr[b"size"])[0]), covered


def read_bag(path: Path, *, recover: bool = False, want: Want = keep_all, label: str | None = None) -> BagContent:
    """Read a ROS 1 bag, keeping the payloads ``want`` asks for; memory holds one chunk at a time plus those.

    A chunk whose index records show only connections whose payloads are not wanted is skipped without being
    read. Raises ``RecordingError`` / ``TruncatedRecordingError`` (byte offset). With ``recover=True``, damage
    (a cut, a malformed record, a chunk that does not decompress, a missing index) stops the read instead:
    every message before it is kept and the result says what was lost (``damage``, ``damage_offset``,
    ``lost_messages``). ``label`` names the file in messages (default: ``path``).
    """
    name = label or str(path)
    content = BagContent(want=want)
    with FileSource(path) as src:
        magic = src.read(0, 13)
        if not magic.startswith(b"#ROSBAG V"):
            raise RecordingError(name, "not a recording (no ROS bag magic)")
        if magic != b"#ROSBAG V2.0\n":
            version = magic[9:12].decode(errors="replace")
            raise RecordingError(name, f"unsupported ROS bag version {version}")
        try:
            stop = _walk_top(src, len(magic), content)
        except (_BadRecordError, KeyError, ValueError, struct.error) as err:
            what = str(err) if isinstance(err, _BadRecordError) else f"malformed record ({type(err).__name__}: {err})"
            if not recover:
                raise RecordingError(name, f"corrupt bag: {what}") from err
            _note_damage(content, f"corrupt bag: {what}", content.record_pos, None, 0)
        else:
            if stop != src.size:
                if not recover:
                    raise TruncatedRecordingError(name, stop, "record cut off")
                before = content.messages_read
                try:
                    cut = _cut_chunk(src, stop, content)
                except (_BadRecordError, KeyError, ValueError, struct.error):
                    cut = None
                salvaged = content.messages_read - before
                where = f"truncated at byte {src.size}" + (
                    f" (inside the chunk that starts at byte {stop})" if cut else f" (record at byte {stop} cut off)"
                )
                _note_damage(content, where, stop, cut, salvaged)
                content.damage_offset = src.size if cut else stop
            elif content.index_pos > src.size:
                if not recover:
                    raise TruncatedRecordingError(name, src.size, f"the index at byte {content.index_pos} is missing")
                _note_damage(content, f"the index at byte {content.index_pos} is missing", src.size, None, 0)
    missing = set(content.counts) - set(content.connections)
    if missing:
        raise RecordingError(name, f"corrupt bag: messages on connection {min(missing)} which is never defined")
    return content


def _note_damage(content: BagContent, what: str, offset: int, cut: tuple[int, int] | None, salvaged: int) -> None:
    """Record the damage and what it cost: ``cut`` (uncompressed size, bytes salvaged) of a chunk the damage
    cut (None: none was), ``salvaged`` the messages kept from its front.

    With the bag header's index position (the end of the last chunk) the loss is estimated from the file bytes
    between the damage and that end at the messages per byte of the chunks read; without it (a recorder killed
    before it wrote the header), it is a lower bound: the cut chunk's size over the mean message size."""
    content.damage = what
    content.damage_offset = offset
    content.past_data = 0 < content.index_pos <= offset and cut is None
    if content.past_data:
        return
    if content.index_pos > offset and content.rate_messages and content.rate_bytes:
        rate = content.rate_messages / content.rate_bytes
        start = max(offset, content.data_resume) if cut is None else offset
        content.lost_messages = max(1, round((content.index_pos - start) * rate) - salvaged)
        content.lost_estimated = True
        return
    lost = 0
    if cut is not None:
        size, covered = cut
        if content.chunk_messages_read and content.chunks_read:
            per_message = content.chunk_bytes_read / content.chunk_messages_read
            lost = max(1, round(size / per_message) - salvaged)
        elif salvaged and covered:
            lost = max(1, round((size - covered) * salvaged / covered))
        else:
            lost = 1
    unreached = content.chunk_count - content.chunks_read - (1 if cut is not None else 0)
    content.lost_messages = lost + max(0, unreached)
