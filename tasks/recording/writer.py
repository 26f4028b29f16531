"""Write demonstration recordings in the conventions of ``../shared/RECORDING.md`` with the real writers.

MCAP files are written with ``mcap.writer.Writer`` (ROS 2 profile, ``cdr`` messages, ``ros2msg`` schemas);
ROS 1 bags with ``rosbags.rosbag1.Writer``; rosbag2 folders with ``rosbags.rosbag2.Writer`` (sqlite3 storage).
Messages are serialised by the rosbags typestore. Everything is buffered and written in time order when the
``with`` block ends, into a temporary path that is renamed into place: a block that raises leaves nothing,
and an existing output is never overwritten. The same input gives byte-identical output.
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, Literal

import numpy as np
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.rosbag1 import Writer as Bag1Writer
from rosbags.rosbag2 import Writer as Bag2Writer
from rosbags.typesys import Stores, get_typestore

from tasks.arrays import FloatArray, check_points
from tasks.errors import RecordingError

Format = Literal["mcap", "bag", "rosbag2"]
FORMATS: tuple[Format, ...] = ("mcap", "bag", "rosbag2")
COMPRESSIONS: dict[str, tuple[str, ...]] = {
    "mcap": ("zstd", "lz4", "none"),
    "bag": ("none", "bz2", "lz4"),
    "rosbag2": ("none",),
}
"""Chunk compressions each container supports here (rosbag2: sqlite3 storage, uncompressed)."""
DEFAULT_COMPRESSION: dict[str, str] = {"mcap": "zstd", "bag": "none", "rosbag2": "none"}

POINT_STAMPED = "geometry_msgs/msg/PointStamped"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POINT_CLOUD2 = "sensor_msgs/msg/PointCloud2"
STRING = "std_msgs/msg/String"


@dataclass(frozen=True)
class _Pending:
    """One buffered message: sort key, topic, type and the fields to build it from."""

    stamp_ns: int
    order: int
    topic: str
    msgtype: str
    fields: tuple[Any, ...]


class RecordingWriter:
    """Context manager writing one recording file (``mcap``, ``bag``) or folder (``rosbag2``).

    ``frame_id`` is the world frame written into every header (metres, REP 103).
    """

    def __init__(
        self,
        path: str | Path,
        fmt: Format,
        *,
        frame_id: str = "world",
        compression: str | None = None,
    ) -> None:
        if fmt not in FORMATS:
            msg = f"unknown format {fmt!r} (expected one of {', '.join(FORMATS)})"
            raise RecordingError(path, msg)
        compression = compression or DEFAULT_COMPRESSION[fmt]
        if compression not in COMPRESSIONS[fmt]:
            msg = f"{fmt} cannot use compression {compression!r} (one of {', '.join(COMPRESSIONS[fmt])})"
            raise RecordingError(path, msg)
        self.path = Path(path)
        self.fmt: Format = fmt
        self.frame_id = frame_id
        self.compression = compression
        self._pending: list[_Pending] = []
        self._topics: dict[str, str] = {}

    # -- adding messages ------------------------------------------------------------------------------
    def _topic(self, topic: str, msgtype: str) -> None:
        known = self._topics.setdefault(topic, msgtype)
        if known != msgtype:
            msg = f"topic already has type {known}, cannot add {msgtype}"
            raise RecordingError(self.path, msg, topic)

    def add_points(self, topic: str, stamps_ns: Any, xyz: Any) -> None:
        """Add ``geometry_msgs/PointStamped`` samples; rows with a NaN are dropouts and are not written.

        stamps_ns: (n,) int64 ns; xyz: (n, 3) float64 metres, world frame.
        """
        stamps = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
        pts = check_points(xyz, f"{topic} xyz")
        if len(stamps) != len(pts):
            msg = f"{len(stamps)} stamps for {len(pts)} points"
            raise ValueError(msg)
        self._topic(topic, POINT_STAMPED)
        keep = np.isfinite(pts).all(axis=1)
        for stamp, row in zip(stamps[keep].tolist(), pts[keep].tolist(), strict=True):
            self._pending.append(_Pending(stamp, len(self._pending), topic, POINT_STAMPED, tuple(row)))

    def add_poses(self, topic: str, stamps_ns: Any, xyz: Any, quat_xyzw: Any) -> None:
        """Add ``geometry_msgs/PoseStamped`` samples (position metres, quaternion [x, y, z, w], world frame)."""
        stamps = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
        pts = check_points(xyz, f"{topic} xyz")
        quats = np.asarray(quat_xyzw, dtype=np.float64)
        if quats.shape != (len(pts), 4) or len(stamps) != len(pts):
            msg = f"{topic}: expected {len(pts)} stamps and ({len(pts)}, 4) quaternions, got {quats.shape}"
            raise ValueError(msg)
        self._topic(topic, POSE_STAMPED)
        keep = np.isfinite(pts).all(axis=1) & np.isfinite(quats).all(axis=1)
        rows = np.hstack([pts, quats])[keep].tolist()
        for stamp, row in zip(stamps[keep].tolist(), rows, strict=True):
            self._pending.append(_Pending(stamp, len(self._pending), topic, POSE_STAMPED, tuple(row)))

    def add_cloud(self, topic: str, stamp_ns: int, points: Any) -> None:
        """Add one ``sensor_msgs/PointCloud2`` with float32 fields x, y, z (metres, world frame)."""
        pts = check_points(points, f"{topic} points").astype(np.float32)
        self._topic(topic, POINT_CLOUD2)
        self._pending.append(_Pending(int(stamp_ns), len(self._pending), topic, POINT_CLOUD2, (pts,)))

    def add_string(self, topic: str, stamp_ns: int, text: str) -> None:
        """Add one ``std_msgs/String``."""
        self._topic(topic, STRING)
        self._pending.append(_Pending(int(stamp_ns), len(self._pending), topic, STRING, (text,)))

    # -- context manager ------------------------------------------------------------------------------
    def __enter__(self) -> RecordingWriter:
        if self.path.exists():
            msg = "output exists; refusing to overwrite"
            raise RecordingError(self.path, msg)
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is not None:
            return
        self.close()

    def close(self) -> None:
        """Write everything buffered, in time order, to a temporary path and rename it into place."""
        if self.path.exists():
            msg = "output exists; refusing to overwrite"
            raise RecordingError(self.path, msg)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        messages = sorted(self._pending, key=lambda m: (m.stamp_ns, m.order))
        tmp_root = Path(tempfile.mkdtemp(dir=self.path.parent, prefix=f".{self.path.name}."))
        try:
            tmp = tmp_root / self.path.name
            if self.fmt == "mcap":
                _write_mcap(tmp, messages, self.frame_id, self.compression)
            elif self.fmt == "bag":
                _write_bag(tmp, messages, self.frame_id, self.compression)
            else:
                _write_rosbag2(tmp, messages, self.frame_id)
            tmp.rename(self.path)
        finally:
            shutil.rmtree(tmp_root, ignore_errors=True)


def _build(typestore: Any, m: _Pending, frame_id: str, ros1: bool) -> Any:
    """Build a rosbags message object for a buffered message."""
    types = typestore.types
    sec, nsec = divmod(m.stamp_ns, 1_000_000_000)
    stamp = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
    header_type = types["std_msgs/msg/Header"]
    header = header_type(seq=0, stamp=stamp, frame_id=frame_id) if ros1 else header_type(stamp=stamp, frame_id=frame_id)
    if m.msgtype == POINT_STAMPED:
        x, y, z = m.fields
        return types[POINT_STAMPED](header=header, point=types["geometry_msgs/msg/Point"](x=x, y=y, z=z))
    if m.msgtype == POSE_STAMPED:
        x, y, z, qx, qy, qz, qw = m.fields
        pose = types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=x, y=y, z=z),
            orientation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
        )
        return types[POSE_STAMPED](header=header, pose=pose)
    if m.msgtype == POINT_CLOUD2:
        (pts,) = m.fields
        field_type = types["sensor_msgs/msg/PointField"]
        fields = [field_type(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate("xyz")]  # 7 = FLOAT32
        data: FloatArray = np.frombuffer(np.ascontiguousarray(pts, dtype="<f4").tobytes(), dtype=np.uint8)
        return types[POINT_CLOUD2](
            header=header,
            height=1,
            width=len(pts),
            fields=fields,
            is_bigendian=False,
            point_step=12,
            row_step=12 * len(pts),
            data=data,
            is_dense=True,
        )
    (text,) = m.fields
    return types[STRING](data=text)


def _typestore(ros1: bool) -> Any:
    return get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)


def _topic_order(messages: list[_Pending]) -> list[tuple[str, str]]:
    """(topic, type) in order of first appearance, so channel ids are deterministic."""
    seen: dict[str, str] = {}
    for m in messages:
        seen.setdefault(m.topic, m.msgtype)
    return list(seen.items())


def _write_mcap(path: Path, messages: list[_Pending], frame_id: str, compression: str) -> None:
    typestore = _typestore(ros1=False)
    kind = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
    with path.open("wb") as fh:
        writer = McapWriter(fh, compression=kind)
        writer.start(profile="ros2", library="pbd")
        schema_ids: dict[str, int] = {}
        channel_ids: dict[str, int] = {}
        for topic, msgtype in _topic_order(messages):
            if msgtype not in schema_ids:
                msgdef, _ = typestore.generate_msgdef(msgtype, ros_version=2)
                name = msgtype.replace("/msg/", "/")
                schema_ids[msgtype] = writer.register_schema(name, "ros2msg", msgdef.encode())
            channel_ids[topic] = writer.register_channel(topic, "cdr", schema_ids[msgtype])
        sequence: dict[str, int] = {}
        for m in messages:
            data = typestore.serialize_cdr(_build(typestore, m, frame_id, ros1=False), m.msgtype)
            seq = sequence.get(m.topic, 0)
            sequence[m.topic] = seq + 1
            writer.add_message(channel_ids[m.topic], m.stamp_ns, bytes(data), m.stamp_ns, seq)
        writer.finish()  # type: ignore[no-untyped-call]


def _write_bag(path: Path, messages: list[_Pending], frame_id: str, compression: str) -> None:
    typestore = _typestore(ros1=True)
    writer = Bag1Writer(path)
    if compression == "lz4":
        writer.set_compression(Bag1Writer.CompressionFormat.LZ4)
    elif compression == "bz2":
        writer.set_compression(Bag1Writer.CompressionFormat.BZ2)
    with writer:
        conns = {t: writer.add_connection(t, ty, typestore=typestore) for t, ty in _topic_order(messages)}
        for m in messages:
            data = typestore.serialize_ros1(_build(typestore, m, frame_id, ros1=True), m.msgtype)
            writer.write(conns[m.topic], m.stamp_ns, bytes(data))


def _write_rosbag2(path: Path, messages: list[_Pending], frame_id: str) -> None:
    typestore = _typestore(ros1=False)
    with Bag2Writer(path, version=9) as writer:
        conns = {t: writer.add_connection(t, ty, typestore=typestore) for t, ty in _topic_order(messages)}
        for m in messages:
            data = typestore.serialize_cdr(_build(typestore, m, frame_id, ros1=False), m.msgtype)
            writer.write(conns[m.topic], m.stamp_ns, bytes(data))
