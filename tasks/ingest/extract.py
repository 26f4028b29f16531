"""Turn a topic's raw messages into marker samples, poses, an object model or meta (pure, no file IO).

Time of a sample: ``header.stamp``; the log time when the message has no header or a zero stamp.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from tasks.errors import RecordingError
from tasks.ingest import roles as rl
from tasks.ingest.bulk import N_FLOATS, bulk_decode
from tasks.ingest.decode import decode_topic
from tasks.ingest.raw import RawTopic

IntArray = npt.NDArray[np.int64]
F64Array = npt.NDArray[np.float64]


@dataclass
class MarkerChunk:
    """Samples of one marker: name, stamps (n,) ns, xyz (n, 3) metres."""

    name: str
    stamps_ns: IntArray
    xyz: F64Array


@dataclass
class PoseChunk:
    """Poses of one rigid body: frame, role, stamps (n,) ns, xyz (n, 3) metres, quats (n, 4) [x, y, z, w]."""

    frame: str
    role: str
    stamps_ns: IntArray
    xyz: F64Array
    quat: F64Array


@dataclass
class Extracted:
    """Everything taken from the recording's topics."""

    markers: list[MarkerChunk] = field(default_factory=list)
    poses: list[PoseChunk] = field(default_factory=list)
    object_model: npt.NDArray[np.float32] | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def _get(obj: Any, *names: str) -> Any:
    """A field of a decoded message object or JSON dict (first of ``names`` present)."""
    for n in names:
        if isinstance(obj, dict):
            if n in obj:
                return obj[n]
        elif hasattr(obj, n):
            return getattr(obj, n)
    msg = f"field {names[0]!r} missing"
    raise KeyError(msg)


def _stamp(msg: Any, log_ns: int) -> int:
    """``header.stamp`` in ns, or the log time when there is no header or the stamp is zero."""
    try:
        st = _get(_get(msg, "header"), "stamp")
        ns = int(_get(st, "sec", "secs")) * 1_000_000_000 + int(_get(st, "nanosec", "nsecs"))
    except (KeyError, TypeError, ValueError):
        return log_ns
    return ns if ns != 0 else log_ns


def _xyz(v: Any) -> tuple[float, float, float]:
    return float(_get(v, "x")), float(_get(v, "y")), float(_get(v, "z"))


def _quat(v: Any) -> tuple[float, float, float, float]:
    return float(_get(v, "x")), float(_get(v, "y")), float(_get(v, "z")), float(_get(v, "w"))


def _fixed_rows(topic: RawTopic, path: str) -> tuple[IntArray, F64Array]:
    """Stamps (ns) and floats of a PointStamped / PoseStamped / TransformStamped topic, bulk where possible."""
    nf = N_FLOATS[topic.msgtype]
    stamps: list[IntArray] = []
    values: list[F64Array] = []
    rest: dict[int, Any] = {}
    for b, batch in enumerate(topic.batches):
        if topic.encoding in ("cdr", "ros1"):
            res = bulk_decode(batch, topic.msgtype, topic.encoding)
            st = np.where(res.stamps_ns != 0, res.stamps_ns, batch.log_ns[res.index])
            stamps.append(st.astype(np.int64))
            values.append(res.values)
            if len(res.rest):
                rest[b] = res.rest
        else:
            rest[b] = np.arange(len(batch))
    if rest:
        s_list: list[int] = []
        v_list: list[tuple[float, ...]] = []
        for log_ns, msg in decode_topic(topic, path, rest):
            s_list.append(_stamp(msg, log_ns))
            if topic.msgtype == rl.POINT:
                v_list.append(_xyz(_get(msg, "point")))
            elif topic.msgtype == rl.POSE:
                pose = _get(msg, "pose")
                v_list.append((*_xyz(_get(pose, "position")), *_quat(_get(pose, "orientation"))))
            else:
                tf = _get(msg, "transform")
                v_list.append((*_xyz(_get(tf, "translation")), *_quat(_get(tf, "rotation"))))
        stamps.append(np.asarray(s_list, dtype=np.int64))
        values.append(np.asarray(v_list, dtype=np.float64).reshape(-1, nf))
    if not stamps:
        return np.zeros(0, dtype=np.int64), np.zeros((0, nf))
    return np.concatenate(stamps), np.concatenate(values)


def child_frames(topic: RawTopic, path: str) -> set[str]:
    """Child frame ids of a TransformStamped / TFMessage topic (bulk where the layout allows)."""
    frames: set[str] = set()
    rest: dict[int, Any] = {}
    for b, batch in enumerate(topic.batches):
        if topic.encoding in ("cdr", "ros1"):
            res = bulk_decode(batch, topic.msgtype, topic.encoding)
            frames.update(res.children)
            if len(res.rest):
                rest[b] = res.rest
        else:
            rest[b] = np.arange(len(batch))
    for _log, msg in decode_topic(topic, path, rest):
        if topic.msgtype == rl.TRANSFORM:
            frames.add(str(_get(msg, "child_frame_id")))
        else:
            frames.update(str(_get(tf, "child_frame_id")) for tf in _get(msg, "transforms"))
    return frames


def cloud_points(msg: Any) -> npt.NDArray[np.float64]:
    """(n, 3) x, y, z of a ``sensor_msgs/PointCloud2`` (float32 or float64 fields), in point order."""
    fields = {str(_get(f, "name")): (int(_get(f, "offset")), int(_get(f, "datatype"))) for f in _get(msg, "fields")}
    if not all(k in fields for k in "xyz"):
        msg_ = "PointCloud2 without x, y, z fields"
        raise ValueError(msg_)
    step = int(_get(msg, "point_step"))
    n = int(_get(msg, "width")) * int(_get(msg, "height"))
    data = np.asarray(_get(msg, "data"), dtype=np.uint8).tobytes()
    endian = ">" if bool(_get(msg, "is_bigendian")) else "<"
    kinds = {7: "f4", 8: "f8"}
    cols = []
    for k in "xyz":
        off, dt = fields[k]
        if dt not in kinds:
            msg_ = f"PointCloud2 field {k} has datatype {dt}, expected FLOAT32 (7) or FLOAT64 (8)"
            raise ValueError(msg_)
        arr = np.ndarray((n,), dtype=f"{endian}{kinds[dt]}", buffer=data, offset=off, strides=(step,))
        cols.append(arr.astype(np.float64))
    return np.column_stack(cols) if n else np.zeros((0, 3))


def dense_cloud(topic: RawTopic, path: str) -> str | None:
    """Why a PointCloud2 topic cannot be a marker set (None: it can): more points than a marker set has (or
    payloads too big to have been kept), or a point count that changes between messages."""
    first = next(decode_topic(topic, path, {0: [0]}), None) if topic.batches else None
    points = None
    if first is not None:
        try:
            points = int(_get(first[1], "width")) * int(_get(first[1], "height"))
        except (KeyError, TypeError, ValueError):
            points = None
    if topic.kept < topic.count or (points is not None and points > rl.MARKER_SET_MAX_POINTS):
        size = f"{points} points" if points is not None else "too many points"
        return f"a dense PointCloud2 ({size} in its first message; a marker set has at most {rl.MARKER_SET_MAX_POINTS})"
    lengths = np.concatenate([b.lengths for b in topic.batches]) if topic.batches else np.zeros(0, np.int64)
    if len(lengths) > 1 and int(lengths.min()) != int(lengths.max()):
        return "a PointCloud2 whose point count changes between messages (a marker set keeps its points in order)"
    return None


def extract_topic(topic: RawTopic, role: str, path: str, out: Extracted) -> None:
    """Add the samples of one topic with its role to ``out``; raises ``RecordingError`` naming the topic."""
    try:
        _extract(topic, role, path, out)
    except RecordingError:
        raise
    except (KeyError, ValueError, TypeError, AttributeError, IndexError) as err:
        msg = f"cannot read {topic.msgtype} samples ({type(err).__name__}: {err})"
        raise RecordingError(path, msg, topic.name) from err


def _extract(topic: RawTopic, role: str, path: str, out: Extracted) -> None:
    typ = topic.msgtype
    name = topic.name
    if role == rl.META:
        for _log, msg in decode_topic(topic, path):
            text = _get(msg, "data") if not isinstance(msg, dict) or "data" in msg else json.dumps(msg)
            try:
                doc = json.loads(text) if isinstance(text, str) else text
            except json.JSONDecodeError:
                out.warnings.append(f"{path} topic {name}: meta is not JSON, kept as text")
                doc = {"text": text}
            if isinstance(doc, dict):
                out.meta.update(doc)
            else:
                out.warnings.append(f"{path} topic {name}: meta JSON is not an object, ignored")
        return
    if role == rl.OBJECT_MODEL:
        for _log, msg in decode_topic(topic, path, {0: [0]} if topic.batches else {}):
            pts = cloud_points(msg)
            pts = pts[np.isfinite(pts).all(axis=1)]
            out.object_model = pts.astype(np.float32)
        if topic.count > 1:
            out.warnings.append(f"{path} topic {name}: {topic.count} object clouds, kept the first")
        return
    if typ in (rl.POINT, rl.POSE, rl.TRANSFORM) and role in (rl.MARKERS, rl.WRIST):
        stamps, vals = _fixed_rows(topic, path)
        if typ == rl.POINT:
            out.markers.append(MarkerChunk(name, stamps, vals[:, :3]))
            return
        if role == rl.MARKERS:
            out.markers.append(MarkerChunk(name, stamps, vals[:, :3].copy()))
        out.poses.append(PoseChunk(name, role, stamps, vals[:, :3].copy(), vals[:, 3:7].copy()))
        return
    if typ in (rl.TF, rl.TF_LEGACY):
        tf_rows: dict[str, tuple[list[int], list[tuple[float, ...]]]] = {}
        all_wrist = "wrist" in name.lower()
        bulk_parts: list[tuple[str, IntArray, F64Array]] = []
        rest: dict[int, Any] = {}
        for b, batch in enumerate(topic.batches):
            if topic.encoding not in ("cdr", "ros1"):
                rest[b] = np.arange(len(batch))
                continue
            res = bulk_decode(batch, typ, topic.encoding)
            if len(res.rest):
                rest[b] = res.rest
            assert res.child_index is not None
            st = np.where(res.stamps_ns != 0, res.stamps_ns, batch.log_ns[res.index])
            for k, child in enumerate(res.children):
                if all_wrist or "wrist" in child.lower():
                    sel = res.child_index == k
                    bulk_parts.append((child, st[sel], res.values[sel]))
        for child, st_, vals in bulk_parts:
            ts, tv = tf_rows.setdefault(child, ([], []))
            ts.extend(st_.tolist())
            tv.extend(map(tuple, vals.tolist()))
        for log_ns, msg in decode_topic(topic, path, rest):
            for tf in _get(msg, "transforms"):
                child = str(_get(tf, "child_frame_id"))
                if not all_wrist and "wrist" not in child.lower():
                    continue
                t = _get(tf, "transform")
                ts, tv = tf_rows.setdefault(child, ([], []))
                ts.append(_stamp(tf, log_ns))
                tv.append((*_xyz(_get(t, "translation")), *_quat(_get(t, "rotation"))))
        for child, (ts, tv) in sorted(tf_rows.items()):
            arr = np.asarray(tv, dtype=np.float64).reshape(-1, 7)
            out.poses.append(PoseChunk(child, rl.WRIST, np.asarray(ts, dtype=np.int64), arr[:, :3], arr[:, 3:]))
        return
    groups: dict[str, tuple[list[int], list[tuple[float, float, float]]]] = {}

    def add(marker: str, stamp: int, xyz: tuple[float, float, float]) -> None:
        s, v = groups.setdefault(marker, ([], []))
        s.append(stamp)
        v.append(xyz)

    if typ == rl.MARKER_ARRAY:
        for log_ns, msg in decode_topic(topic, path):
            for m in _get(msg, "markers"):
                if int(_get(m, "action")) in (2, 3):  # DELETE, DELETEALL
                    continue
                add(
                    f"{name}/{_get(m, 'ns')}/{int(_get(m, 'id'))}",
                    _stamp(m, log_ns),
                    _xyz(_get(_get(m, "pose"), "position")),
                )
    elif typ == rl.CLOUD:
        for log_ns, msg in decode_topic(topic, path):
            stamp = _stamp(msg, log_ns)
            for i, p in enumerate(cloud_points(msg).tolist()):
                add(f"{name}/{i}", stamp, (p[0], p[1], p[2]))
    elif rl.is_mocap_markers(typ):
        for log_ns, msg in decode_topic(topic, path):
            stamp = _stamp(msg, log_ns)
            for m in _get(msg, "markers"):
                add(f"{name}/{int(_get(m, 'marker_index'))}", stamp, _xyz(_get(m, "translation", "position")))
    else:
        msg_ = f"type {typ} cannot be {role}"
        raise RecordingError(path, msg_, name)
    for marker, (s, v) in groups.items():
        out.markers.append(MarkerChunk(marker, np.asarray(s, dtype=np.int64), np.asarray(v, dtype=np.float64)))
