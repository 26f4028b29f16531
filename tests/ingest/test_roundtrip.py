"""Round trips: recordings written by the real writers come back sample for sample after ingest.

Writers: rosbags rosbag1 ``Writer`` (none, bz2, lz4), rosbags rosbag2 ``Writer`` (sqlite3 and mcap storage),
mcap + mcap-ros2-support (zstd, lz4, none; with and without summary/index), mcap-ros1-support, and a plain
``mcap.writer.Writer`` with JSON messages. Every marker-capable type of RECORDING.md is written: PointStamped,
PoseStamped (wrist and rigid body), TransformStamped, TFMessage (wrist child frame), MarkerArray, a
PointCloud2 marker set, a PointCloud2 object model, ``mocap4r2_msgs/Markers`` (a custom type: decodes from
the recording's own definition) and the ``/demo/meta`` String.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tasks.ingest.api import ingest_recording
from tasks.recording.load import RecordingData, load_recording
from tasks.store import Store

T0 = 1_700_000_000_123_456_789
N = 30
RNG = np.random.default_rng(7)
STAMPS = T0 + np.arange(N, dtype=np.int64) * 8_333_333
HANDLE = RNG.normal(size=(N, 3))
WRIST_XYZ = RNG.normal(size=(N, 3))
WRIST_Q = RNG.normal(size=(N, 4))
WRIST_Q /= np.linalg.norm(WRIST_Q, axis=1)[:, None]
LID_XYZ = RNG.normal(size=(N, 3))
LID_Q = RNG.normal(size=(N, 4))
LID_Q /= np.linalg.norm(LID_Q, axis=1)[:, None]
TF_XYZ = RNG.normal(size=(N, 3))
VIZ = RNG.normal(size=(N, 2, 3))
CLOUD = RNG.normal(size=(N, 3, 3)).astype(np.float32)
MOCAP = RNG.normal(size=(N, 2, 3))
OBJECT = RNG.normal(size=(50, 3)).astype(np.float32)
META = {"action": "open", "object": "microwave"}

MOCAP_MSGS = {
    "mocap4r2_msgs/msg/Marker": "int8 USE_INDEX=0\nint8 USE_NAME=1\nint8 id_type\nint32 marker_index\n"
    "string marker_name\ngeometry_msgs/Point translation\n",
    "mocap4r2_msgs/msg/Markers": "std_msgs/Header header\nuint32 frame_number\nmocap4r2_msgs/Marker[] markers\n",
}


def _typestore(ros1: bool) -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    for name, text in MOCAP_MSGS.items():
        store.register(get_types_from_msg(text, name))
    if "tf2_msgs/msg/TFMessage" not in store.fielddefs:  # not in rosbags' Noetic store
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms\n", "tf2_msgs/msg/TFMessage"))
    return store


def _messages(store: Any, ros1: bool) -> list[tuple[str, str, int, Any]]:
    """(topic, type, log time, rosbags message) for the whole demonstration, in time order."""
    t = store.types

    def header(ns: int, frame: str = "world") -> Any:
        sec, nsec = divmod(int(ns), 1_000_000_000)
        stamp = t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
        return (
            t["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)
            if ros1
            else t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)
        )

    def point(v: Any) -> Any:
        return t["geometry_msgs/msg/Point"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def quat(q: Any) -> Any:
        return t["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))

    def cloud(ns: int, pts: Any) -> Any:
        fields = [
            t["sensor_msgs/msg/PointField"](name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate("xyz")
        ]
        data = np.frombuffer(np.ascontiguousarray(pts, dtype="<f4").tobytes(), dtype=np.uint8)
        return t["sensor_msgs/msg/PointCloud2"](
            header=header(ns),
            height=1,
            width=len(pts),
            fields=fields,
            is_bigendian=False,
            point_step=12,
            row_step=12 * len(pts),
            data=data,
            is_dense=True,
        )

    out: list[tuple[str, str, int, Any]] = []
    out.append(("/demo/meta", "std_msgs/msg/String", T0 - 1000, t["std_msgs/msg/String"](data=json.dumps(META))))
    out.append(("/object/points", "sensor_msgs/msg/PointCloud2", T0 - 500, cloud(T0 - 500, OBJECT)))
    for i, ns in enumerate(STAMPS.tolist()):
        log = ns + 1_000_000  # log time later than the header stamp: ingest must use the header
        out.append(
            (
                "/mocap/handle",
                "geometry_msgs/msg/PointStamped",
                log,
                t["geometry_msgs/msg/PointStamped"](header=header(ns), point=point(HANDLE[i])),
            )
        )
        pose = t["geometry_msgs/msg/Pose"](position=point(WRIST_XYZ[i]), orientation=quat(WRIST_Q[i]))
        out.append(
            (
                "/hand/wrist_pose",
                "geometry_msgs/msg/PoseStamped",
                log,
                t["geometry_msgs/msg/PoseStamped"](header=header(ns), pose=pose),
            )
        )
        tf = t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](x=LID_XYZ[i, 0], y=LID_XYZ[i, 1], z=LID_XYZ[i, 2]),
            rotation=quat(LID_Q[i]),
        )
        lid = t["geometry_msgs/msg/TransformStamped"](header=header(ns), child_frame_id="lid", transform=tf)
        out.append(("/vicon/lid", "geometry_msgs/msg/TransformStamped", log, lid))
        tf2 = t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](x=TF_XYZ[i, 0], y=TF_XYZ[i, 1], z=TF_XYZ[i, 2]),
            rotation=quat(WRIST_Q[i]),
        )
        other = t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0), rotation=quat((0, 0, 0, 1))
        )
        tfs = [
            t["geometry_msgs/msg/TransformStamped"](header=header(ns), child_frame_id="right_wrist", transform=tf2),
            t["geometry_msgs/msg/TransformStamped"](header=header(ns), child_frame_id="base", transform=other),
        ]
        tftype = "tf2_msgs/msg/TFMessage"
        out.append(("/tf", tftype, log, t[tftype](transforms=tfs)))
        mk = []
        for j in range(2):
            mk.append(
                t["visualization_msgs/msg/Marker"](
                    header=header(ns),
                    ns="hand",
                    id=j,
                    type=2,
                    action=0,
                    pose=t["geometry_msgs/msg/Pose"](position=point(VIZ[i, j]), orientation=quat((0, 0, 0, 1))),
                    scale=t["geometry_msgs/msg/Vector3"](x=0.01, y=0.01, z=0.01),
                    color=t["std_msgs/msg/ColorRGBA"](r=1.0, g=0.0, b=0.0, a=1.0),
                    lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
                    frame_locked=False,
                    points=[],
                    colors=[],
                    text="",
                    mesh_resource="",
                    mesh_use_embedded_materials=False,
                    **(
                        {}
                        if ros1
                        else {
                            "texture_resource": "",
                            "texture": t["sensor_msgs/msg/CompressedImage"](
                                header=header(0), format="", data=np.zeros(0, np.uint8)
                            ),
                            "uv_coordinates": [],
                            "mesh_file": t["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
                        }
                    ),
                )
            )
        out.append(
            (
                "/viz/markers",
                "visualization_msgs/msg/MarkerArray",
                log,
                t["visualization_msgs/msg/MarkerArray"](markers=mk),
            )
        )
        out.append(("/mocap/cloud", "sensor_msgs/msg/PointCloud2", log, cloud(ns, CLOUD[i])))
        mocap = [
            t["mocap4r2_msgs/msg/Marker"](
                id_type=0, marker_index=10 + j, marker_name="", translation=point(MOCAP[i, j])
            )
            for j in range(2)
        ]
        out.append(
            (
                "/mocap/markers",
                "mocap4r2_msgs/msg/Markers",
                log,
                t["mocap4r2_msgs/msg/Markers"](header=header(ns), frame_number=i, markers=mocap),
            )
        )
    return out


def check(rec: RecordingData, *, full: bool = True) -> None:
    """Every sample comes back exactly (positions float64; cloud points float32 as written)."""
    m = rec.markers["/mocap/handle"]
    np.testing.assert_array_equal(m.stamps_ns, STAMPS)
    np.testing.assert_array_equal(m.points, HANDLE)
    wrist = rec.poses["/hand/wrist_pose"]
    assert wrist.role == "wrist"
    np.testing.assert_array_equal(wrist.positions, WRIST_XYZ)
    np.testing.assert_array_equal(wrist.quats, WRIST_Q)
    assert rec.meta == META
    assert rec.info["start_ns"] == STAMPS[0]
    if not full:
        return
    lid = rec.poses["/vicon/lid"]
    assert lid.role == "markers"
    np.testing.assert_array_equal(lid.positions, LID_XYZ)
    np.testing.assert_array_equal(lid.quats, LID_Q)
    np.testing.assert_array_equal(rec.markers["/vicon/lid"].points, LID_XYZ)
    tf = rec.poses["right_wrist"]
    assert tf.role == "wrist"
    np.testing.assert_array_equal(tf.positions, TF_XYZ)
    np.testing.assert_array_equal(tf.stamps_ns, STAMPS)
    assert "base" not in rec.poses
    for j in range(2):
        np.testing.assert_array_equal(rec.markers[f"/viz/markers/hand/{j}"].points, VIZ[:, j])
        np.testing.assert_array_equal(rec.markers[f"/mocap/markers/{10 + j}"].points, MOCAP[:, j])
        np.testing.assert_array_equal(rec.markers[f"/mocap/markers/{10 + j}"].stamps_ns, STAMPS)
    for j in range(3):
        np.testing.assert_array_equal(rec.markers[f"/mocap/cloud/{j}"].points, CLOUD[:, j].astype(np.float64))
    assert rec.object_model is not None
    np.testing.assert_array_equal(rec.object_model, OBJECT.astype(np.float64))
    roles = {t["name"]: t["role"] for t in rec.info["topics"]}
    assert roles == {
        "/demo/meta": "meta",
        "/object/points": "object_model",
        "/mocap/handle": "markers",
        "/hand/wrist_pose": "wrist",
        "/vicon/lid": "markers",
        "/tf": "wrist",
        "/viz/markers": "markers",
        "/mocap/cloud": "markers",
        "/mocap/markers": "markers",
    }
    assert all(t["count"] == (1 if t["name"] in ("/demo/meta", "/object/points") else N) for t in rec.info["topics"])


def _ingest(path: Path, store: Store) -> RecordingData:
    result = ingest_recording(path, store)
    assert result.created
    return load_recording(store, result.recording_id)


@pytest.mark.parametrize("compression", ["none", "bz2", "lz4"])
def test_rosbag1_writer(compression: str, tmp_path: Path, store: Store) -> None:
    """rosbags rosbag1 Writer, each chunk compression."""
    from rosbags.rosbag1 import Writer

    typestore = _typestore(ros1=True)
    path = tmp_path / "demo.bag"
    writer = Writer(path)
    if compression != "none":
        writer.set_compression(getattr(Writer.CompressionFormat, compression.upper()))
    with writer:
        conns: dict[str, Any] = {}
        for topic, typ, log, msg in _messages(typestore, ros1=True):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, typ, typestore=typestore)
            writer.write(conns[topic], log, bytes(typestore.serialize_ros1(msg, typ)))
    check(_ingest(path, store))


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_rosbag2_writer(storage: str, tmp_path: Path, store: Store) -> None:
    """rosbags rosbag2 Writer with sqlite3 and mcap storage; definitions come from the bag."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    typestore = _typestore(ros1=False)
    path = tmp_path / "demo"
    plugin = StoragePlugin.SQLITE3 if storage == "sqlite3" else StoragePlugin.MCAP
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        conns: dict[str, Any] = {}
        for topic, typ, log, msg in _messages(typestore, ros1=False):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, typ, typestore=typestore)
            writer.write(conns[topic], log, bytes(typestore.serialize_cdr(msg, typ)))
    rec = _ingest(path, store)
    check(rec)
    assert rec.info["container"] == "rosbag2"


def _as_dict(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _as_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, np.ndarray):
        return obj.tobytes() if obj.dtype == np.uint8 else obj.tolist()
    if isinstance(obj, list):
        return [_as_dict(x) for x in obj]
    return obj


@pytest.mark.parametrize(("compression", "summary"), [("zstd", True), ("lz4", True), ("none", True), ("zstd", False)])
def test_mcap_ros2_writer(compression: str, summary: bool, tmp_path: Path, store: Store) -> None:
    """mcap + mcap-ros2-support (ros2msg schemas, cdr); also a file without summary and index."""
    from mcap.writer import CompressionType
    from mcap_ros2.writer import Writer

    typestore = _typestore(ros1=False)
    path = tmp_path / "demo.mcap"
    schemas: dict[str, Any] = {}
    with path.open("wb") as fh:
        kind = getattr(CompressionType, compression.upper())
        if summary:
            writer = Writer(fh, compression=kind)
            for topic, typ, log, msg in _messages(typestore, ros1=False):
                if typ not in schemas:
                    text, _ = typestore.generate_msgdef(typ, ros_version=2)
                    schemas[typ] = writer.register_msgdef(typ, text)
                writer.write_message(topic, schemas[typ], _as_dict(msg), log_time=log)
            writer.finish()
        else:  # plain mcap Writer: no summary section, no chunk or message indexes
            from mcap.writer import IndexType
            from mcap.writer import Writer as McapWriter

            raw = McapWriter(
                fh,
                compression=kind,
                index_types=IndexType.NONE,
                repeat_channels=False,
                repeat_schemas=False,
                use_statistics=False,
                use_summary_offsets=False,
            )
            raw.start(profile="ros2", library="test")
            channels: dict[str, int] = {}
            for topic, typ, log, msg in _messages(typestore, ros1=False):
                if typ not in schemas:
                    text, _ = typestore.generate_msgdef(typ, ros_version=2)
                    schemas[typ] = raw.register_schema(typ, "ros2msg", text.encode())
                if topic not in channels:
                    channels[topic] = raw.register_channel(topic, "cdr", schemas[typ])
                raw.add_message(channels[topic], log, bytes(typestore.serialize_cdr(msg, typ)), log)
            raw.finish()
    check(_ingest(path, store))


def test_mcap_ros1_writer(tmp_path: Path, store: Store) -> None:
    """mcap + mcap-ros1-support (ros1msg schemas, ros1 encoding): points, wrist poses and meta."""
    from mcap_ros1._vendor.genpy import dynamic
    from mcap_ros1.writer import Writer

    typestore = _typestore(ros1=True)
    classes: dict[str, Any] = {}
    for typ in ("geometry_msgs/msg/PointStamped", "geometry_msgs/msg/PoseStamped", "std_msgs/msg/String"):
        ros1_name = typ.replace("/msg/", "/")
        text, _ = typestore.generate_msgdef(typ, ros_version=1)
        classes[typ] = dynamic.generate_dynamic(ros1_name, text)
    path = tmp_path / "demo.mcap"

    def build(cls_map: dict[str, Any], obj: Any) -> Any:
        if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            name = obj.__msgtype__.replace("/msg/", "/")
            if name == "builtin_interfaces/Time":
                from mcap_ros1._vendor.genpy.rostime import Time

                return Time(obj.sec, obj.nanosec)
            fields = [f.name for f in dataclasses.fields(obj) if f.name != "__msgtype__"]
            return cls_map[name](**{f: build(cls_map, getattr(obj, f)) for f in fields})
        return obj

    with path.open("wb") as fh:
        writer = Writer(fh)
        for topic, typ, log, msg in _messages(typestore, ros1=True):
            if typ in classes:
                writer.write_message(topic, build(classes[typ], msg), log_time=log)
        writer.finish()
    check(_ingest(path, store), full=False)


def test_mcap_json(tmp_path: Path, store: Store) -> None:
    """Plain mcap Writer with JSON messages and jsonschema schemas (PointStamped, PoseStamped, meta)."""
    from mcap.writer import Writer

    path = tmp_path / "demo.mcap"
    with path.open("wb") as fh:
        writer = Writer(fh)
        writer.start(profile="", library="test")
        ids: dict[str, int] = {}
        for topic, typ in (
            ("/mocap/handle", "geometry_msgs/msg/PointStamped"),
            ("/hand/wrist_pose", "geometry_msgs/msg/PoseStamped"),
            ("/demo/meta", "std_msgs/msg/String"),
        ):
            sid = writer.register_schema(typ, "jsonschema", b'{"type": "object"}')
            ids[topic] = writer.register_channel(topic, "json", sid)
        writer.add_message(ids["/demo/meta"], T0 - 1000, json.dumps({"data": json.dumps(META)}).encode(), T0 - 1000)
        for i, ns in enumerate(STAMPS.tolist()):
            stamp = {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}
            x, y, z = HANDLE[i].tolist()
            p = {"header": {"stamp": stamp, "frame_id": "world"}, "point": {"x": x, "y": y, "z": z}}
            writer.add_message(ids["/mocap/handle"], ns + 5, json.dumps(p).encode(), ns + 5)
            wx, wy, wz = WRIST_XYZ[i].tolist()
            qx, qy, qz, qw = WRIST_Q[i].tolist()
            pose = {
                "header": {"stamp": stamp, "frame_id": "world"},
                "pose": {"position": {"x": wx, "y": wy, "z": wz}, "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}},
            }
            writer.add_message(ids["/hand/wrist_pose"], ns + 5, json.dumps(pose).encode(), ns + 5)
        writer.finish()
    check(_ingest(path, store), full=False)


def test_lead_writer_every_container(tmp_path: Path, store: Store) -> None:
    """tasks.recording.writer (the project's own writer) in every container and compression."""
    from tasks.recording.writer import COMPRESSIONS, RecordingWriter

    for fmt, comps in COMPRESSIONS.items():
        for comp in comps:
            path = tmp_path / (f"r-{comp}" if fmt == "rosbag2" else f"r-{comp}.{fmt}")
            with RecordingWriter(path, fmt, compression=comp) as w:
                w.add_points("/mocap/handle", STAMPS, HANDLE)
                w.add_poses("/hand/wrist_pose", STAMPS, WRIST_XYZ, WRIST_Q)
                w.add_string("/demo/meta", T0 - 1000, json.dumps(META))
            check(_ingest(path, store), full=False)
