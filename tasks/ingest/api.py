"""Ingest: a recording (MCAP, ROS 1 bag, rosbag2 folder) into the store's Parquet layout (RECORDING.md).

``ingest_recording`` reads the raw messages (``containers``), gives every topic a role (``roles``), decodes
the topics that have one (bulk numpy for the fixed-layout types, the recording's own definitions for the
rest; ``extract``), and writes ``markers.parquet``, ``poses.parquet``, ``object_model.parquet`` and
``recording.json`` into a staging folder that is renamed to ``recordings/<id>/``. Bad input raises a
``RecordingError`` (or ``TopicMapError``) and leaves nothing in the store.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from schemas.tables import (
    INGEST_VERSION,
    MARKERS_FILE,
    MARKERS_SCHEMA,
    OBJECT_MODEL_FILE,
    OBJECT_MODEL_SCHEMA,
    POSES_FILE,
    POSES_SCHEMA,
    RECORDING_FILE,
    SCHEMA_VERSION,
)
from tasks.errors import NAME_CHARS, RecordingError, TopicMapError, one_line
from tasks.ingest import roles as rl
from tasks.ingest.containers import KNOWN_ENCODINGS, read_recording
from tasks.ingest.content_id import check_source, content_id_beside, recording_id_of
from tasks.ingest.extract import Extracted, MarkerChunk, PoseChunk, child_frames, dense_cloud, extract_topic
from tasks.ingest.object_model import load_object_model
from tasks.ingest.raw import RawRecording
from tasks.store import Store

__all__ = ["IngestResult", "assign_roles", "ingest_recording", "recording_id_of", "recording_key"]


@dataclass(frozen=True)
class IngestResult:
    """Outcome of ``ingest_recording``: the id, its folder, whether it was new, what was lost and warned."""

    recording_id: str
    folder: Path
    created: bool
    lost_messages: int
    warnings: tuple[str, ...]


MAP_KEY_HEX = 8
"""Hex digits of the canonical topic map's SHA-256 in a mapped recording's store key: one user's maps of one
recording never collide at 32 bits."""


def recording_key(content_id: str, tmap: rl.TopicMap | None) -> str:
    """The store key of a recording read with ``tmap``: its content id alone without a map, else
    ``<content id>-<first 8 hex of the SHA-256 of the canonical map>`` (``../shared/RECORDING.md``)."""
    if tmap is None:
        return content_id
    return f"{content_id}-{hashlib.sha256(tmap.canonical().encode()).hexdigest()[:MAP_KEY_HEX]}"


def _special(raw: RawRecording) -> tuple[dict[str, str], list[str]]:
    """Topics skipped before decoding (unknown encodings, service events): reason per topic, warnings."""
    skipped: dict[str, str] = {}
    for name, t in raw.topics.items():
        if t.encoding not in KNOWN_ENCODINGS:
            skipped[name] = f"unknown message encoding {t.encoding!r}"
        elif rl.is_service_event(name, t.msgtype):
            skipped[name] = "service events are not demonstration data"
    with_msgs = [n for n, t in raw.topics.items() if t.count]
    if with_msgs and all(n in skipped for n in with_msgs):
        first = sorted(with_msgs, key=lambda n: ("unknown" not in skipped[n], n))[0]
        what = skipped[first]
        if "service" in what:
            what = "only service-event topics, nothing to ingest"
        raise RecordingError(raw.path, what, first if "unknown" in what else None)
    warnings = [f"{raw.path} topic {n}: skipped ({why})" for n, why in sorted(skipped.items()) if raw.topics[n].count]
    return skipped, warnings


def assign_roles(raw: RawRecording, tmap: rl.TopicMap | None) -> tuple[dict[str, str], list[str]]:
    """The role of every topic (detection, then the topic map); returns roles and warnings."""
    skipped, warnings = _special(raw)
    path = str(raw.path)
    detected: dict[str, str] = {}
    for name, t in raw.topics.items():
        if name in skipped:
            detected[name] = rl.IGNORED
            continue
        frames: set[str] = set()
        if t.count and t.msgtype in (rl.TRANSFORM, rl.TF, rl.TF_LEGACY) and "wrist" not in name.lower():
            frames = child_frames(t, path)
        detected[name] = rl.detect_role(name, t.msgtype, frames)
    if tmap is not None:
        types = {n: t.msgtype for n, t in raw.topics.items()}
        roles = rl.apply_topic_map(tmap, detected, types)
        for name in skipped:
            if roles[name] != rl.IGNORED:
                msg = f"cannot use this topic ({skipped[name]})"
                raise RecordingError(path, msg, name)
    else:
        roles = detected
    for name, role in sorted(roles.items()):
        t = raw.topics[name]
        if t.msgtype != rl.CLOUD or role != rl.MARKERS or not t.count:
            continue
        why = dense_cloud(t, path)
        if why is None:
            continue
        if tmap is not None and tmap.role_of(name) == rl.MARKERS:
            msg = f"topic {one_line(name, NAME_CHARS)} is {why}, not a marker set"
            raise TopicMapError(tmap.source, msg)
        roles[name] = rl.IGNORED
        warnings.append(
            f"{path} topic {one_line(name, NAME_CHARS)}: {why}: ignored (a topic map can make it object_model)"
        )
    return roles, warnings


_NUMPY_OF = {pa.int64(): np.int64, pa.float64(): np.float64, pa.float32(): np.float32}


def _numeric_column(values: Any, kind: Any) -> Any:
    """A pyarrow array of type ``kind`` sharing the buffer of ``values`` (1-D, no nulls). ``pa.array`` on an
    ndarray would first import ``numpy.ma`` to test for a masked array, a tenth of a small ingest's time."""
    arr = np.ascontiguousarray(values, dtype=_NUMPY_OF[kind])
    return pa.Array.from_buffers(kind, len(arr), [None, pa.py_buffer(arr)])


def _markers_table(chunks: list[MarkerChunk]) -> Any:
    merged: dict[str, list[MarkerChunk]] = {}
    for c in chunks:
        merged.setdefault(c.name, []).append(c)
    names = sorted(merged)
    idx_parts, stamp_parts, xyz_parts = [], [], []
    for k, name in enumerate(names):
        st = np.concatenate([c.stamps_ns for c in merged[name]])
        xyz = np.concatenate([c.xyz for c in merged[name]]).reshape(-1, 3)
        keep = np.isfinite(xyz).all(axis=1)
        st, xyz = st[keep], xyz[keep]
        if len(st) > 1 and not bool(np.all(st[1:] >= st[:-1])):
            order = np.argsort(st, kind="stable")
            st, xyz = st[order], xyz[order]
        idx_parts.append(np.full(len(st), k, dtype=np.int32))
        stamp_parts.append(st)
        xyz_parts.append(xyz)
    if names:
        idx = np.concatenate(idx_parts)
        stamps = np.concatenate(stamp_parts)
        xyz = np.concatenate(xyz_parts)
    else:
        idx, stamps, xyz = np.zeros(0, np.int32), np.zeros(0, np.int64), np.zeros((0, 3))
    encoded = [nm.encode() for nm in names]
    name_len = np.asarray([len(e) for e in encoded], dtype=np.int64)
    data = b"".join(e * len(p) for e, p in zip(encoded, idx_parts, strict=True))
    wide = len(data) >= 2**31  # string offsets are int32 below 2 GiB of names, else a large_string column
    offsets = np.zeros(len(idx) + 1, dtype=np.int64 if wide else np.int32)
    np.cumsum(name_len[idx] if len(idx) else np.zeros(0, np.int64), out=offsets[1:])
    kind = pa.LargeStringArray if wide else pa.StringArray
    marker = kind.from_buffers(len(idx), pa.py_buffer(offsets), pa.py_buffer(data))
    if wide:  # rare: needs pyarrow.compute (slow to import) for the cast
        marker = marker.cast(pa.string())
    cols = [marker, _numeric_column(stamps, pa.int64())] + [_numeric_column(xyz[:, i], pa.float64()) for i in range(3)]
    return pa.Table.from_arrays(cols, schema=MARKERS_SCHEMA)


def _poses_table(chunks: list[PoseChunk]) -> Any:
    chunks = sorted(chunks, key=lambda c: c.frame)
    frames, roles, stamps, vals = [], [], [], []
    for c in chunks:
        order = np.argsort(c.stamps_ns, kind="stable")
        frames += [c.frame] * len(order)
        roles += [c.role] * len(order)
        stamps.append(c.stamps_ns[order])
        vals.append(np.hstack([c.xyz, c.quat])[order])
    st = np.concatenate(stamps) if stamps else np.zeros(0, np.int64)
    v = np.concatenate(vals) if vals else np.zeros((0, 7))
    cols = [pa.array(frames, pa.string()), pa.array(roles, pa.string()), _numeric_column(st, pa.int64())]
    cols += [_numeric_column(v[:, i], pa.float64()) for i in range(7)]
    return pa.Table.from_arrays(cols, schema=POSES_SCHEMA)


def _span(raw: RawRecording, ex: Extracted) -> tuple[int | None, int | None, int | None, int | None]:
    """(start, end) of the samples (header stamps) and of the log times of every message; None when empty."""
    logs = [b.log_ns for t in raw.topics.values() for b in t.batches if len(b)]
    log_lo = min(int(x.min()) for x in logs) if logs else None
    log_hi = max(int(x.max()) for x in logs) if logs else None
    if raw.log_range is not None:
        log_lo = raw.log_range[0] if log_lo is None else min(log_lo, raw.log_range[0])
        log_hi = raw.log_range[1] if log_hi is None else max(log_hi, raw.log_range[1])
    st = [c.stamps_ns for c in ex.markers if len(c.stamps_ns)] + [c.stamps_ns for c in ex.poses if len(c.stamps_ns)]
    lo = min(int(x.min()) for x in st) if st else log_lo
    hi = max(int(x.max()) for x in st) if st else log_hi
    return lo, hi, log_lo, log_hi


def ingest_recording(
    source: Path,
    store: Store,
    *,
    topics: Path | None = None,
    recover: bool = False,
    object_model: Path | None = None,
    known_id: str | None = None,
) -> IngestResult:
    """Ingest the recording at ``source`` into ``store``; a no-op (``created=False``) if it is already there.

    The store key is the content id with the topic map's (``recording_key``): the same recording read with
    another map (or none) is another entry, and an entry is never rewritten. Only the topics some role can use
    are decoded; the others are counted (and skipped unread where the container allows). The content id is
    hashed on a second thread while the raw messages are read (``content_id_beside``), so a recording already
    in the store is read but not decoded or written. ``known_id``: the content id when the caller already has it
    (the flows remember ids by file state), so the bytes are not hashed again.
    Raises ``RecordingError`` (bad or unreadable recording, naming the file and topic), ``TopicMapError``
    (bad ``topics`` map). With ``recover``, a truncated or damaged MCAP, ROS 1 bag or rosbag2 keeps its intact
    messages before the damage and the loss is reported in ``lost_messages`` (exact where rosbag2 metadata counts
    the messages, an estimate or a lower bound otherwise, as the warning says) and ``warnings``.
    """

    source = Path(source)
    tmap = rl.parse_topic_map(Path(topics)) if topics is not None else None
    check_source(source)
    with content_id_beside(source, known_id) as pending:
        raw = read_recording(source, recover=recover, want=rl.wanted(tmap))
        content_id = pending.result()
    rec_id = recording_key(content_id, tmap)
    final = store.recording_dir(rec_id)
    if store.has_recording(rec_id):
        notes: tuple[str, ...] = ()
        if object_model is not None:
            stored = json.loads((final / RECORDING_FILE).read_text()).get("object_model_file") or {}
            sha = hashlib.sha256(Path(object_model).read_bytes()).hexdigest() if Path(object_model).is_file() else ""
            if stored.get("sha256") != sha:
                notes = (f"{source}: already ingested as {rec_id} with another object model; kept the stored one",)
        return IngestResult(rec_id, final, False, 0, notes)
    if raw.message_count == 0:
        n = len(raw.topics)
        what = f"empty: no messages ({n} topic{'s' if n != 1 else ''} without messages)" if n else "empty: no messages"
        raise RecordingError(source, what)
    roles, warnings = assign_roles(raw, tmap)
    warnings = raw.warnings + warnings
    ex = Extracted()
    for name in sorted(raw.topics):
        role = roles[name]
        t = raw.topics[name]
        if role != rl.IGNORED and t.count:
            extract_topic(t, role, str(source), ex)
    warnings += ex.warnings
    model_info: dict[str, Any] | None = None
    if object_model is not None:
        pts, sha = load_object_model(Path(object_model))
        if ex.object_model is not None:
            warnings.append(f"{source}: --object-model {object_model} replaces the recording's object cloud")
        ex.object_model = pts
        model_info = {"path": str(object_model), "sha256": sha}
    lo, hi, log_lo, log_hi = _span(raw, ex)
    info: dict[str, Any] = {
        "id": rec_id,
        "content_id": content_id,
        "topic_map": None if tmap is None else {"path": str(topics), "canonical": tmap.canonical()},
        "source": str(source),
        "container": raw.container,
        "topics": [
            {"name": n, "type": t.msgtype, "role": roles[n], "count": t.count} for n, t in sorted(raw.topics.items())
        ],
        "start_ns": lo,
        "end_ns": hi,
        "log_start_ns": log_lo,
        "log_end_ns": log_hi,
        "ingest_version": INGEST_VERSION,
        "schema_version": SCHEMA_VERSION,
        "meta": ex.meta,
        "lost_messages": raw.lost_messages,
        "warnings": warnings,
    }
    if model_info is not None:
        info["object_model_file"] = model_info
    with store.staging(f"ingest-{rec_id}") as stage:
        # dictionary-encode only the name columns: trying it on float columns costs more than the rest
        pq.write_table(_markers_table(ex.markers), stage / MARKERS_FILE, use_dictionary=["marker"])
        pq.write_table(_poses_table(ex.poses), stage / POSES_FILE, use_dictionary=["frame", "role"])
        if ex.object_model is not None:
            m = ex.object_model
            table = pa.Table.from_arrays(
                [_numeric_column(m[:, i], pa.float32()) for i in range(3)], schema=OBJECT_MODEL_SCHEMA
            )
            pq.write_table(table, stage / OBJECT_MODEL_FILE)
        (stage / RECORDING_FILE).write_text(json.dumps(info, indent=2) + "\n")
        created = store.publish_dir(stage, final)
    return IngestResult(rec_id, final, created, raw.lost_messages, tuple(warnings))
