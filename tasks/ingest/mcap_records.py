"""MCAP records (https://mcap.dev/spec): opcodes, schema and channel records, what a read found, and the
``Collector`` that gathers the kept message payloads of the chunks read."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from tasks.ingest.batch import Batch, IntArray, gather_bytes
from tasks.ingest.selection import SMALL_PAYLOAD_BYTES, Keep, Want, normalize_type

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX, OP_DATA_END = (
    0x01,
    0x02,
    0x03,
    0x04,
    0x05,
    0x06,
    0x07,
    0x0F,
)
REC = struct.Struct("<BQ")
MSG = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
MSG_HEAD = 9 + MSG.size  # opcode + length + the fixed message fields = 31 bytes before the payload


@dataclass
class McapSchema:
    """An MCAP schema record."""

    id: int
    name: str
    encoding: str
    data: bytes


@dataclass
class McapChannel:
    """An MCAP channel record."""

    id: int
    schema_id: int
    topic: str
    message_encoding: str


@dataclass
class McapContent:
    """Everything read from an MCAP file: schemas, channels, message batches per channel id."""

    profile: str = ""
    schemas: dict[int, McapSchema] = field(default_factory=dict)
    channels: dict[int, McapChannel] = field(default_factory=dict)
    batches: dict[int, list[Batch]] = field(default_factory=dict)
    damage: str | None = None
    """What was wrong where reading stopped (only with ``recover=True``)."""
    damage_offset: int | None = None
    cut_chunk: int | None = None
    """Where the chunk the damage cut starts (None: the damage is not inside a chunk)."""
    lost_bytes: int = 0
    lost_messages: int = 0
    """The messages lost in the chunk the damage cut (estimated from the uncompressed size its header gives and
    the mean message size), at least 1 when a chunk or message was cut; whatever followed is not counted."""
    past_data: bool = False
    """The damage lies after the data section (in the summary): no message was lost."""
    counts: dict[int, int] = field(default_factory=dict)
    """Messages per channel id, kept or not."""
    log_range: tuple[int, int] | None = None
    """Earliest and latest log time (ns) of every message, kept or not."""
    chunks_skipped: int = 0
    """Chunks passed over unread: their indexes showed only channels whose payloads are not wanted."""
    summary_channels: bool = False
    """Schemas and channels were read from an intact summary: every channel is known before the data."""

    def note_log(self, lo: int, hi: int) -> None:
        """Widen ``log_range`` to include [lo, hi] (ns)."""
        if self.log_range is None:
            self.log_range = (lo, hi)
        else:
            self.log_range = (min(self.log_range[0], lo), max(self.log_range[1], hi))


def string_field(buf: memoryview | bytes, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise ValueError("string runs past its record")
    return bytes(buf[pos + 4 : end]).decode("utf-8", errors="replace"), end


def parse_schema(rec: bytes) -> McapSchema:
    (sid,) = struct.unpack_from("<H", rec, 0)
    name, p = string_field(rec, 2)
    enc, p = string_field(rec, p)
    (n,) = struct.unpack_from("<I", rec, p)
    if p + 4 + n > len(rec):
        raise ValueError("schema data runs past its record")
    return McapSchema(sid, name, enc, bytes(rec[p + 4 : p + 4 + n]))


def parse_channel(rec: bytes) -> McapChannel:
    cid, sid = struct.unpack_from("<HH", rec, 0)
    topic, p = string_field(rec, 4)
    enc, p = string_field(rec, p)
    return McapChannel(cid, sid, topic, enc)


class CorruptChunkError(Exception):
    """A record inside a chunk is malformed (the reader turns it into a ``RecordingError``)."""


class Collector:
    """Accumulates the kept message payloads per buffer (chunk); ``finish`` emits one batch per channel.

    Every message is counted (``content.counts``, ``content.log_range``); payloads are kept as the reader's
    selection says (``Keep``): a chunk whose messages are all kept stays as it is, otherwise its kept payloads
    are copied out and the chunk is let go. All kept buffers are joined at the end, so a channel's messages
    form a single batch however many chunks they came from (the bulk decoder runs once per topic).
    """

    def __init__(self, content: McapContent, want: Want) -> None:
        self.content = content
        self.want = want
        self.parts: list[tuple[bytes, IntArray, IntArray, IntArray, IntArray]] = []
        self.top: list[bytes] = []
        self.count = 0
        self.record_bytes = 0
        self._keep: dict[int, Keep] = {}
        self._first_kept: set[int] = set()

    def keep(self, cid: int) -> Keep:
        """What to keep of channel ``cid`` (decided when it is first needed; an undefined channel: all)."""
        k = self._keep.get(cid)
        if k is None:
            ch = self.content.channels.get(cid)
            if ch is None:
                return Keep.ALL
            schema = self.content.schemas.get(ch.schema_id)
            k = self.want(ch.topic, normalize_type(schema.name) if schema else "")
            self._keep[cid] = k
        return k

    def skip(self, cid: int, n: int) -> None:
        """Count ``n`` messages of channel ``cid`` that were not read."""
        self.content.counts[cid] = self.content.counts.get(cid, 0) + n

    def add_top(self, record: bytes) -> None:
        """A whole message record (opcode, length, content) outside any chunk."""
        self.top.append(record)

    def add_walked(self, buf: bytes, rec_offsets: list[int], rec_lengths: list[int]) -> None:
        """Message records found by walking: read their fixed fields in bulk."""
        if not rec_offsets:
            return
        self.add_indexed(buf, np.asarray(rec_offsets, dtype=np.int64), np.asarray(rec_lengths, dtype=np.int64))

    def add_indexed(
        self, buf: bytes, rec_off: IntArray, rec_len: IntArray, heads: npt.NDArray[np.uint8] | None = None
    ) -> None:
        """Message records at ``rec_off`` (record start) with record content length ``rec_len``.

        ``heads``: the first 31 bytes of each record, if already gathered.
        """
        if heads is None:
            heads = gather_bytes(np.frombuffer(buf, dtype=np.uint8), rec_off, MSG_HEAD)
        chan = heads[:, 9:11].copy().view("<u2").reshape(-1).astype(np.int64)
        log = heads[:, 15:23].copy().view("<u8").reshape(-1).astype(np.int64)
        self.count += len(rec_off)
        self.record_bytes += int(rec_len.sum()) + 9 * len(rec_off)
        if len(log):
            self.content.note_log(int(log.min()), int(log.max()))
        counts = np.bincount(chan)
        present = np.flatnonzero(counts).tolist()
        kinds = {cid: self.keep(cid) for cid in present}
        for cid in present:
            self.skip(cid, int(counts[cid]))
        pay_off = rec_off + MSG_HEAD
        pay_len = rec_len - MSG.size
        if any(k is not Keep.ALL for k in kinds.values()):
            mask = np.zeros(len(chan), dtype=bool)
            for cid, k in kinds.items():
                if k is Keep.NONE:
                    continue
                sel = chan == cid
                if k is Keep.SMALL:
                    small = sel & (pay_len <= SMALL_PAYLOAD_BYTES)
                    if cid not in self._first_kept:
                        small[int(np.argmax(sel))] = True
                    sel = small
                mask |= sel
            if not mask.any():
                return
            if not mask.all():
                view = memoryview(buf)
                kept_off, kept_len = pay_off[mask].tolist(), pay_len[mask].tolist()
                buf = b"".join([view[o : o + n] for o, n in zip(kept_off, kept_len, strict=True)])
                pay_len = pay_len[mask]
                pay_off = np.zeros(len(pay_len), dtype=np.int64)
                if len(pay_len) > 1:
                    np.cumsum(pay_len[:-1], out=pay_off[1:])
                chan, log = chan[mask], log[mask]
        self._first_kept.update(cid for cid, k in kinds.items() if k is Keep.SMALL)
        self.parts.append((buf, chan, log, pay_off, pay_len))

    def finish(self) -> None:
        """Join the buffers and put one batch per channel into the content."""
        if self.top:
            data = b"".join(self.top)
            lengths = np.fromiter((len(r) - 9 for r in self.top), dtype=np.int64, count=len(self.top))
            offsets = np.zeros(len(self.top), dtype=np.int64)
            np.cumsum(lengths[:-1] + 9, out=offsets[1:])
            self.top = []
            self.add_indexed(data, offsets, lengths)
        if not self.parts:
            return
        bufs: list[bytes] = []
        base: dict[int, int] = {}
        total = 0
        for buf, *_ in self.parts:
            if id(buf) not in base:
                base[id(buf)] = total
                bufs.append(buf)
                total += len(buf)
        big = bufs[0] if len(bufs) == 1 else b"".join(bufs)
        chan = np.concatenate([p[1] for p in self.parts])
        log = np.concatenate([p[2] for p in self.parts])
        off = np.concatenate([p[3] + base[id(p[0])] for p in self.parts])
        length = np.concatenate([p[4] for p in self.parts])
        self.parts = []
        for cid in np.flatnonzero(np.bincount(chan)).tolist():  # channel ids are uint16: no sort needed
            idx = np.flatnonzero(chan == cid)
            self.content.batches.setdefault(int(cid), []).append(Batch(big, off[idx], length[idx], log[idx]))


def walk_records(buf: bytes, start: int, end: int, content: McapContent, msgs: tuple[list[int], list[int]]) -> None:
    """Walk the records in ``buf[start:end]``, keeping schemas/channels, noting message records."""
    pos = start
    unpack_rec = REC.unpack_from
    while pos < end:
        if pos + 9 > end:
            raise CorruptChunkError(f"record header cut at byte {pos}")
        op, length = unpack_rec(buf, pos)
        body = pos + 9
        if body + length > end:
            raise CorruptChunkError(f"record at byte {pos} runs past its end")
        if op == OP_MESSAGE:
            if length < MSG.size:
                raise CorruptChunkError(f"message record at byte {pos} too short")
            msgs[0].append(pos)
            msgs[1].append(length)
        elif op == OP_SCHEMA:
            try:
                s = parse_schema(buf[body : body + length])
            except (ValueError, struct.error) as err:
                raise CorruptChunkError(f"bad schema record at byte {pos}") from err
            content.schemas[s.id] = s
        elif op == OP_CHANNEL:
            try:
                c = parse_channel(buf[body : body + length])
            except (ValueError, struct.error) as err:
                raise CorruptChunkError(f"bad channel record at byte {pos}") from err
            content.channels[c.id] = c
        pos = body + length


def walk_prefix(buf: bytes, content: McapContent, msgs: tuple[list[int], list[int]]) -> None:
    """Walk the complete records at the front of a cut-off buffer (recovery); stop at the first bad one."""
    pos = 0
    end = len(buf)
    while pos + 9 <= end:
        _op, length = REC.unpack_from(buf, pos)
        if pos + 9 + length > end:
            return
        try:
            walk_records(buf, pos, pos + 9 + length, content, msgs)
        except CorruptChunkError:
            return
        pos += 9 + length
