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

import lz4.frame

from tasks.errors import RecordingError, TruncatedRecordingError
from tasks.ingest.mcap_stream import Batch

OP_MSG_DATA, OP_BAG_HEADER, OP_INDEX_DATA, OP_CHUNK, OP_CHUNK_INFO, OP_CONNECTION = 0x02, 0x03, 0x04, 0x05, 0x06, 0x07
_U32 = struct.Struct("<I")


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

    connections: dict[int, BagConnection] = field(default_factory=dict)
    payloads: dict[int, list[bytes]] = field(default_factory=dict)
    stamps: dict[int, list[int]] = field(default_factory=dict)
    index_pos: int = 0
    chunk_count: int = 0
    """Chunks the bag header announces (0: not written, as when the recorder was killed)."""
    chunks_read: int = 0
    messages_read: int = 0
    chunk_bytes_read: int = 0
    chunk_messages_read: int = 0
    """Uncompressed bytes and messages of the complete chunks read (to estimate what a cut chunk held)."""
    record_pos: int = 0
    """Where the top-level record being read starts (the damage offset when it is bad)."""
    damage: str | None = None
    """What was wrong where reading stopped (only with ``recover=True``)."""
    damage_offset: int | None = None
    lost_messages: int = 0
    """An estimate of the messages lost: those of a chunk cut by the damage (from its size), plus one per chunk
    the header announces that was never reached."""
    past_data: bool = False
    """The damage lies in the index after the last chunk: no message was lost."""

    def batch(self, conn_id: int) -> Batch | None:
        """The raw messages of one connection as a batch (None when it has none)."""
        p = self.payloads.get(conn_id)
        return Batch.from_payloads(p, self.stamps[conn_id]) if p else None


class _BadRecordError(Exception):
    """Internal: a malformed record."""


def _fields(buf: bytes, start: int, end: int) -> dict[bytes, bytes]:
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


def _connection(hdr: dict[bytes, bytes], data: bytes, start: int, end: int) -> BagConnection:
    conn_id = _U32.unpack(hdr[b"conn"])[0]
    topic = hdr[b"topic"].decode("utf-8", errors="replace")
    info = _fields(data, start, end)
    return BagConnection(
        conn_id,
        normalize_topic(topic),
        _normalize_type(info.get(b"type", b"").decode("utf-8", errors="replace")),
        info.get(b"message_definition", b"").decode("utf-8", errors="replace"),
    )


def _walk(buf: bytes, start: int, end: int, content: BagContent, top: bool) -> int:
    """Walk records in ``buf[start:end]``; returns where it stopped (``end`` unless cut off, top level only)."""
    pos = start
    unpack = _U32.unpack_from
    while pos < end:
        if top:
            content.record_pos = pos
        if pos + 4 > end:
            return pos
        (hlen,) = unpack(buf, pos)
        hstart = pos + 4
        hend = hstart + hlen
        if hend + 4 > end:
            return pos
        (dlen,) = unpack(buf, hend)
        dstart = hend + 4
        dend = dstart + dlen
        if dend > end:
            return pos
        if hlen == 0:  # zero padding some writers leave before the index: resume at the index
            if top and content.index_pos > pos:
                pos = content.index_pos
            else:
                rest = bytes(buf[pos:end]).lstrip(b"\x00")
                pos = end - len(rest)
            continue
        hdr = _fields(buf, hstart, hend)
        op_raw = hdr.get(b"op")
        if op_raw is None or len(op_raw) != 1:
            raise _BadRecordError(f"record at byte {pos} has no op code")
        op = op_raw[0]
        if op == OP_MSG_DATA:
            conn = _U32.unpack(hdr[b"conn"])[0]
            secs, nsecs = struct.unpack("<II", hdr[b"time"])
            content.payloads.setdefault(conn, []).append(bytes(buf[dstart:dend]))
            content.stamps.setdefault(conn, []).append(secs * 1_000_000_000 + nsecs)
            content.messages_read += 1
        elif op == OP_BAG_HEADER and b"index_pos" in hdr:
            content.index_pos = int(struct.unpack("<Q", hdr[b"index_pos"])[0])
            if b"chunk_count" in hdr:
                content.chunk_count = int(_U32.unpack(hdr[b"chunk_count"])[0])
        elif op == OP_CONNECTION:
            c = _connection(hdr, buf, dstart, dend)
            content.connections.setdefault(c.id, c)
        elif op == OP_CHUNK:
            if not top:
                raise _BadRecordError("chunk inside a chunk")
            compression = hdr.get(b"compression", b"none").decode()
            (size,) = _U32.unpack(hdr[b"size"])
            raw = bytes(buf[dstart:dend])
            try:
                if compression == "none":
                    inner = raw
                elif compression == "bz2":
                    inner = bz2.decompress(raw)
                elif compression == "lz4":
                    inner = lz4.frame.decompress(raw)
                else:
                    raise _BadRecordError(f"unknown chunk compression {compression!r}")
            except (OSError, ValueError, RuntimeError, EOFError) as err:
                raise _BadRecordError(f"chunk at byte {pos}: {compression} data does not decompress") from err
            if len(inner) != size:
                raise _BadRecordError(f"chunk at byte {pos} decompressed to {len(inner)} bytes, header says {size}")
            before = content.messages_read
            if _walk(inner, 0, len(inner), content, top=False) != len(inner):
                raise _BadRecordError(f"chunk at byte {pos} holds a cut-off record")
            content.chunks_read += 1
            content.chunk_bytes_read += size
            content.chunk_messages_read += content.messages_read - before
        pos = dend
    return pos


def _cut_chunk(buf: bytes, pos: int, content: BagContent) -> int | None:
    """Recovery at a top-level record cut off by the end of ``buf`` at ``pos``: when it is a chunk, keep the
    complete messages at the front of an uncompressed one (compressed data cannot be cut and decoded) and
    return the uncompressed size its header announces; None when it is not a chunk or its header is cut."""
    if pos + 4 > len(buf):
        return None
    (hlen,) = _U32.unpack_from(buf, pos)
    hend = pos + 4 + hlen
    if hend + 4 > len(buf):
        return None
    hdr = _fields(buf, pos + 4, hend)
    if hdr.get(b"op") != bytes([OP_CHUNK]) or b"size" not in hdr:
        return None
    if hdr.get(b"compression", b"none") == b"none":
        _walk(buf, hend + 4, len(buf), content, top=False)
    return int(_U32.unpack(hdr[b"size"])[0])


def read_bag(data: bytes, path: str, *, recover: bool = False) -> BagContent:
    """Read a ROS 1 bag's bytes; raises ``RecordingError`` / ``TruncatedRecordingError`` (byte offset). With
    ``recover=True``, damage (a cut, a malformed record, a chunk that does not decompress, a missing index)
    stops the read instead: every message before it is kept and the result says what was lost
    (``damage``, ``damage_offset``, ``lost_messages``)."""
    if not data.startswith(b"#ROSBAG V"):
        raise RecordingError(path, "not a recording (no ROS bag magic)")
    if not data.startswith(b"#ROSBAG V2.0\n"):
        version = data[9:12].decode(errors="replace")
        raise RecordingError(path, f"unsupported ROS bag version {version}")
    content = BagContent()
    start = len(b"#ROSBAG V2.0\n")
    try:
        stop = _walk(data, start, len(data), content, top=True)
    except (_BadRecordError, KeyError, ValueError, struct.error) as err:
        what = str(err) if isinstance(err, _BadRecordError) else f"malformed record ({type(err).__name__}: {err})"
        if not recover:
            raise RecordingError(path, f"corrupt bag: {what}") from err
        _note_damage(content, f"corrupt bag: {what}", content.record_pos, None, 0)
    else:
        if stop != len(data):
            if not recover:
                raise TruncatedRecordingError(path, stop, "record cut off")
            before = content.messages_read
            try:
                cut_size = _cut_chunk(data, stop, content)
            except (_BadRecordError, KeyError, ValueError, struct.error):
                cut_size = None
            salvaged = content.messages_read - before
            _note_damage(content, f"truncated at byte {stop} (record cut off)", stop, cut_size, salvaged)
        elif content.index_pos > len(data):
            if not recover:
                raise TruncatedRecordingError(path, len(data), f"the index at byte {content.index_pos} is missing")
            _note_damage(content, f"the index at byte {content.index_pos} is missing", len(data), None, 0)
    missing = set(content.payloads) - set(content.connections)
    if missing:
        raise RecordingError(path, f"corrupt bag: messages on connection {min(missing)} which is never defined")
    return content


def _note_damage(content: BagContent, what: str, offset: int, cut_chunk_size: int | None, salvaged: int) -> None:
    """Record the damage and estimate what it cost (see ``BagContent.lost_messages``): ``cut_chunk_size`` the
    uncompressed bytes of a chunk the damage cut (None: none was), ``salvaged`` the messages kept from its
    front."""
    content.damage = what
    content.damage_offset = offset
    content.past_data = 0 < content.index_pos <= offset and cut_chunk_size is None
    if content.past_data:
        return
    lost = 0
    if cut_chunk_size is not None and content.chunk_bytes_read and content.chunk_messages_read:
        per_message = content.chunk_bytes_read / content.chunk_messages_read
        lost += max(1, round(cut_chunk_size / per_message) - salvaged)
    elif cut_chunk_size is not None:
        lost += 1
    unreached = content.chunk_count - content.chunks_read - (1 if cut_chunk_size is not None else 0)
    content.lost_messages = lost + max(0, unreached)
