"""Bulk numpy decoding of the high-volume fixed-layout messages from raw CDR / ROS 1 bytes.

``PointStamped``, ``PoseStamped`` and ``TransformStamped`` are a header (stamp, frame id string) followed by
float64s. Messages of one topic whose payloads have the same length (and the same string lengths) share
one byte layout, so their fields are read for all of them at once: a strided view over the buffer when
the payloads sit at a constant stride, else one fancy-index gather.

Layouts (offsets in bytes from the payload start):

- CDR (ROS 2): 4-byte encapsulation header (``00 01`` = little endian; anything else is left to the general
  decoder), int32 sec, uint32 nanosec, uint32 frame_id length n (including the NUL), n chars; for
  TransformStamped then padding to 4, uint32 child length, chars; then padding to 8 counted from after the
  encapsulation header, then the float64s.
- ROS 1: uint32 seq, uint32 secs, uint32 nsecs, uint32 frame_id length n, n chars (no NUL); for
  TransformStamped uint32 child length and chars; then the float64s (no padding).

A ``TFMessage`` holding exactly one transform is a uint32 count (1) followed by one TransformStamped, so
it is read the same way four bytes further on, with its child frame id. Messages that fit no layout (big
endian, several transforms, short, odd) are reported back for the general decoder.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from tasks.ingest.batch import Batch, gather_bytes

IntArray = npt.NDArray[np.int64]
F64Array = npt.NDArray[np.float64]

N_FLOATS: dict[str, int] = {
    "geometry_msgs/msg/PointStamped": 3,
    "geometry_msgs/msg/PoseStamped": 7,
    "geometry_msgs/msg/TransformStamped": 7,
    "tf2_msgs/msg/TFMessage": 7,
    "tf/msg/tfMessage": 7,
}
"""Float64 count after the header(s) of each bulk-decodable type."""
_TWO_STRINGS = {"geometry_msgs/msg/TransformStamped", "tf2_msgs/msg/TFMessage", "tf/msg/tfMessage"}
_PREFIX = {"tf2_msgs/msg/TFMessage": 4, "tf/msg/tfMessage": 4}
"""Bytes before the (first) stamped header: a TF message is a uint32 count, then TransformStamped items;
only messages holding exactly one transform are bulk-decoded (the common tracker case)."""


@dataclass(frozen=True)
class BulkResult:
    """Decoded rows of one batch: ``index`` into the batch, header stamps (ns), floats (n, k).

    ``rest``: indices of messages the bulk path could not decode (for the general decoder).
    """

    index: IntArray
    stamps_ns: IntArray
    values: F64Array
    rest: IntArray
    children: tuple[str, ...] = ()
    """Child frame ids (TransformStamped, TF): ``child_index`` points into this per decoded message."""
    child_index: IntArray | None = None


def _gather(arr: npt.NDArray[np.uint8], offsets: IntArray, nbytes: int) -> npt.NDArray[np.uint8]:
    """(n, nbytes) bytes starting at each offset (one memcpy per row)."""
    return gather_bytes(arr, offsets, nbytes)


def _u32(arr: npt.NDArray[np.uint8], offsets: IntArray) -> IntArray:
    return _gather(arr, offsets, 4).view("<u4").reshape(-1).astype(np.int64)


def bulk_decode(batch: Batch, msgtype: str, encoding: str) -> BulkResult:
    """Decode the messages of ``batch`` (type ``msgtype``, encoding ``cdr`` or ``ros1``) in bulk."""
    nf = N_FLOATS[msgtype]
    two = msgtype in _TWO_STRINGS
    pre = _PREFIX.get(msgtype, 0)
    arr = np.frombuffer(batch.buf, dtype=np.uint8)
    n = len(batch)
    all_idx = np.arange(n, dtype=np.int64)
    # encapsulation (CDR) or seq (ROS 1), [TF count], stamp, frame id length
    head = 16 + pre
    fits = batch.lengths >= head
    rest_parts: list[IntArray] = [all_idx[~fits]]
    idx_parts: list[IntArray] = []
    stamp_parts: list[IntArray] = []
    value_parts: list[F64Array] = []
    child_parts: list[IntArray] = []
    children: dict[bytes, int] = {}
    cand = all_idx[fits]
    off = batch.offsets[cand]
    lens = batch.lengths[cand]
    rows: npt.NDArray[np.uint8] | None = None
    if len(lens) and int(lens.min()) == int(lens.max()):  # one payload length: gather whole payloads once
        rows = _gather(arr, off, int(lens[0]))
        heads = rows[:, :head]
    else:
        heads = _gather(arr, off, head)
    if encoding == "cdr":
        ok = (heads[:, 0] == 0) & (heads[:, 1] == 1)
        sec = heads[:, 4 + pre : 8 + pre].copy().view("<i4").reshape(-1).astype(np.int64)
        if pre:
            ok &= heads[:, 4:8].copy().view("<u4").reshape(-1) == 1
    else:
        ok = np.ones(len(cand), dtype=bool)
        sec = heads[:, 4 + pre : 8 + pre].copy().view("<u4").reshape(-1).astype(np.int64)
        if pre:
            ok &= heads[:, 0:4].copy().view("<u4").reshape(-1) == 1
    nsec = heads[:, 8 + pre : 12 + pre].copy().view("<u4").reshape(-1).astype(np.int64)
    slen = heads[:, 12 + pre : 16 + pre].copy().view("<u4").reshape(-1).astype(np.int64)
    rest_parts.append(cand[~ok])
    keep = ok
    cand, off, sec, nsec, slen = cand[keep], off[keep], sec[keep], nsec[keep], slen[keep]
    if rows is not None and not bool(keep.all()):
        rows = rows[keep]
    lengths = batch.lengths[cand]
    # group by (payload length, frame id length): each group shares one layout
    key = lengths * (1 << 20) + np.minimum(slen, (1 << 20) - 1)
    uniform = len(key) > 0 and int(key.min()) == int(key.max())
    for k in [int(key[0])] if uniform else np.unique(key).tolist():
        sel = np.arange(len(key)) if uniform else np.flatnonzero(key == k)
        L = int(lengths[sel[0]])
        s = int(slen[sel[0]])
        g_idx, g_off = cand[sel], off[sel]
        pos = 16 + pre + s  # end of the frame id chars, from the payload start
        if two and encoding == "cdr":
            pos = 4 + ((pos - 4 + 3) // 4) * 4  # CDR aligns the u32 to 4 bytes past the encapsulation header
        if two:
            if pos + 4 > L:
                rest_parts.append(g_idx)
                continue
            c = _u32(arr, g_off + pos)
            groups = [(int(cl), np.flatnonzero(c == cl)) for cl in np.unique(c).tolist()]
        else:
            groups = [(-1, np.arange(len(sel)))]
        for child_len, sub in groups:
            p = pos
            if child_len >= 0:
                p = pos + 4 + child_len
            start = 4 + ((p - 4 + 7) // 8) * 8 if encoding == "cdr" else p
            if start + 8 * nf > L:
                rest_parts.append(g_idx[sub])
                continue
            if rows is not None:
                vals = rows[sel[sub], start : start + 8 * nf].copy().view("<f8").reshape(-1, nf)
            else:
                vals = _gather(arr, g_off[sub] + start, 8 * nf).view("<f8").reshape(-1, nf)
            idx_parts.append(g_idx[sub])
            stamp_parts.append(sec[sel][sub] * 1_000_000_000 + nsec[sel][sub])
            value_parts.append(vals.astype(np.float64))
            if child_len >= 0:  # child frame ids: distinct byte strings of this group
                if child_len == 0:
                    child_parts.append(np.full(len(sub), children.setdefault(b"", len(children)), dtype=np.int64))
                else:
                    raw = _gather(arr, g_off[sub] + pos + 4, child_len)
                    names, inverse = np.unique(raw, axis=0, return_inverse=True)
                    ids = np.asarray([children.setdefault(r.tobytes(), len(children)) for r in names], dtype=np.int64)
                    child_parts.append(ids[inverse.reshape(-1)])
    if idx_parts:
        index = np.concatenate(idx_parts)
        stamps = np.concatenate(stamp_parts)
        values = np.concatenate(value_parts)
    else:
        index = np.zeros(0, dtype=np.int64)
        stamps = np.zeros(0, dtype=np.int64)
        values = np.zeros((0, nf), dtype=np.float64)
    rest = np.sort(np.concatenate(rest_parts)) if rest_parts else np.zeros(0, dtype=np.int64)
    if not two:
        return BulkResult(index, stamps, values, rest.astype(np.int64))
    child_names = tuple(b.rstrip(b"\x00").decode("utf-8", errors="replace") for b in children)
    child_index = np.concatenate(child_parts) if child_parts else np.zeros(0, dtype=np.int64)
    return BulkResult(index, stamps, values, rest.astype(np.int64), child_names, child_index)
