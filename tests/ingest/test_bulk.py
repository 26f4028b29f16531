"""Bulk numpy decoding equals the rosbags deserializer, message for message; odd messages fall back.

Also: the IKEA demonstration bags decode their custom ``pr2_unstructured_lfd/WMData`` from the bag's own
definitions, and an object model can come from a file (``--object-model``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tasks.errors import RecordingError
from tasks.ingest.api import ingest_recording
from tasks.ingest.batch import Batch
from tasks.ingest.bulk import bulk_decode
from tasks.ingest.containers import read_recording
from tasks.ingest.decode import decode_topic
from tasks.ingest.raw import RawTopic
from tasks.recording.load import load_recording
from tasks.store import Store
from tests.conftest import REAL

TYPES = ("geometry_msgs/msg/PointStamped", "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/TransformStamped")


def _messages(store: Any, typ: str, n: int, ros1: bool, rng: np.random.Generator) -> list[tuple[Any, int, np.ndarray]]:
    """(message, stamp ns, floats) with frame ids of varying length (so payload lengths vary)."""
    t = store.types
    out = []
    for i in range(n):
        ns = int(rng.integers(0, 2**31 - 1)) * 1_000_000_000 + int(rng.integers(0, 1_000_000_000))
        sec, nsec = divmod(ns, 1_000_000_000)
        frame = "f" * int(rng.integers(0, 12))
        stamp = t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
        header = (
            t["std_msgs/msg/Header"](seq=i, stamp=stamp, frame_id=frame)
            if ros1
            else t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)
        )
        v = rng.normal(size=7)
        p = t["geometry_msgs/msg/Point"](x=v[0], y=v[1], z=v[2])
        q = t["geometry_msgs/msg/Quaternion"](x=v[3], y=v[4], z=v[5], w=v[6])
        if typ.endswith("PointStamped"):
            msg = t[typ](header=header, point=p)
            vals = v[:3]
        elif typ.endswith("PoseStamped"):
            msg = t[typ](header=header, pose=t["geometry_msgs/msg/Pose"](position=p, orientation=q))
            vals = v
        else:
            tr = t["geometry_msgs/msg/Vector3"](x=v[0], y=v[1], z=v[2])
            child = "c" * int(rng.integers(0, 9))
            msg = t[typ](
                header=header,
                child_frame_id=child,
                transform=t["geometry_msgs/msg/Transform"](translation=tr, rotation=q),
            )
            vals = v
        out.append((msg, ns, vals))
    return out


@pytest.mark.parametrize("typ", TYPES)
@pytest.mark.parametrize("encoding", ["cdr", "ros1"])
def test_bulk_equals_deserializer(typ: str, encoding: str) -> None:
    """Random stamps, frame ids of 0 to 11 chars: bulk rows equal the written values; nothing falls back."""
    from rosbags.typesys import Stores, get_typestore

    ros1 = encoding == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    rng = np.random.default_rng(hash((typ, encoding)) % 2**32)
    msgs = _messages(store, typ, 300, ros1, rng)
    ser = store.serialize_ros1 if ros1 else store.serialize_cdr
    payloads = [bytes(ser(m, typ)) for m, _, _ in msgs]
    batch = Batch.from_payloads(payloads, list(range(len(msgs))))
    res = bulk_decode(batch, typ, encoding)
    assert len(res.rest) == 0
    order = np.argsort(res.index)
    np.testing.assert_array_equal(res.index[order], np.arange(len(msgs)))
    np.testing.assert_array_equal(res.stamps_ns[order], [ns for _, ns, _ in msgs])
    nf = res.values.shape[1]
    np.testing.assert_array_equal(res.values[order], np.array([v[:nf] for _, _, v in msgs]))


def test_big_endian_cdr_falls_back() -> None:
    """Big-endian CDR is not bulk-decoded; the general decoder reads it, with the same values."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    typ = TYPES[0]
    msgs = _messages(store, typ, 20, False, np.random.default_rng(2))
    payloads = [bytes(store.serialize_cdr(m, typ, little_endian=(i % 2 == 0))) for i, (m, _, _) in enumerate(msgs)]
    batch = Batch.from_payloads(payloads, list(range(20)))
    res = bulk_decode(batch, typ, "cdr")
    np.testing.assert_array_equal(res.rest, np.arange(1, 20, 2))
    text, _ = store.generate_msgdef(typ, ros_version=2)
    topic = RawTopic("/p", typ, "cdr", "ros2msg", text, [batch])
    decoded = dict(decode_topic(topic, "mem", {0: res.rest}))
    for i in res.rest.tolist():
        assert decoded[i].point.x == msgs[i][2][0]


def test_undecodable_message_names_topic() -> None:
    """A payload that the general decoder cannot read: RecordingError naming topic and message."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    text, _ = store.generate_msgdef("std_msgs/msg/String", ros_version=2)
    topic = RawTopic("/s", "std_msgs/msg/String", "cdr", "ros2msg", text, [Batch.from_payloads([b"\x00\x01"], [0])])
    with pytest.raises(RecordingError, match=r"topic /s: message 0 does not decode as std_msgs/msg/String"):
        list(decode_topic(topic, "mem"))
    bad = RawTopic("/s", "std_msgs/msg/String", "cdr", "ros2msg", "float64[ x\n", [])
    with pytest.raises(RecordingError, match="cannot parse the message definition"):
        list(decode_topic(bad, "mem"))
    custom = RawTopic("/c", "my_pkg/msg/Thing", "cdr", "", "", [])
    with pytest.raises(RecordingError, match="no message definition for my_pkg/msg/Thing"):
        list(decode_topic(custom, "mem"))
    odd = RawTopic("/o", "my_pkg/msg/Thing", "flatbuffer", "", "", [])
    with pytest.raises(RecordingError, match="unknown message encoding 'flatbuffer'"):
        list(decode_topic(odd, "mem"))


IKEA = sorted((REAL / "champ" / "ikea_pos_1").glob("part*.bag"))


def test_ikea_custom_type_from_bag_definitions() -> None:
    """pr2_unstructured_lfd/WMData decodes from the bag's own definition; counts and fields match rosbags."""
    from rosbags.highlevel import AnyReader

    assert len(IKEA) == 4
    for bag in IKEA[:2]:
        raw = read_recording(bag)
        topic = raw.topics["/ar_world_model"]
        assert topic.msgtype == "pr2_unstructured_lfd/msg/WMData"
        ours = list(decode_topic(topic, str(bag)))
        with AnyReader([bag]) as reader:
            conns = [c for c in reader.connections if c.topic == "/ar_world_model"]
            ref = [reader.deserialize(raw_, c.msgtype) for c, _, raw_ in reader.messages(connections=conns)]
        assert len(ours) == len(ref) == topic.count
        ids = {o.id for _, m in ours for o in m.objects}
        assert ids == {0, 13}  # AR markers 0 and 13
        for (_, a), b in zip(ours, ref, strict=True):
            pa_ = [(o.id, o.pose.pose.position.x, o.pose.pose.orientation.w) for o in a.objects]
            pb_ = [(o.id, o.pose.pose.position.x, o.pose.pose.orientation.w) for o in b.objects]
            assert pa_ == pb_
    first = next(iter(decode_topic(read_recording(IKEA[0]).topics["/ar_world_model"], "x")))[1]
    assert first.objects[0].pose.pose.position.x == pytest.approx(0.35946211905208253, abs=0)


def test_ikea_ingests(store: Store) -> None:
    """The IKEA bags ingest (WMData has no role in RECORDING.md: kept as an ignored topic with its count)."""
    result = ingest_recording(IKEA[0], store)
    rec = load_recording(store, result.recording_id)
    topics = {t["name"]: (t["type"], t["role"], t["count"]) for t in rec.info["topics"]}
    assert topics["/ar_world_model"] == ("pr2_unstructured_lfd/msg/WMData", "ignored", 249)


def test_object_model_file(tmp_path: Path, store: Store) -> None:
    """``--object-model`` from a .ply point cloud replaces the recording's (none here)."""
    import open3d as o3d

    from tasks.recording.writer import RecordingWriter

    pts = np.random.default_rng(4).normal(size=(100, 3))
    ply = tmp_path / "model.ply"
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    assert o3d.io.write_point_cloud(str(ply), cloud)
    rec_path = tmp_path / "demo.bag"
    with RecordingWriter(rec_path, "bag") as w:
        w.add_points("/mocap/handle", np.arange(5, dtype=np.int64) + 1, pts[:5])
    result = ingest_recording(rec_path, store, object_model=ply)
    rec = load_recording(store, result.recording_id)
    assert rec.object_model is not None
    np.testing.assert_allclose(rec.object_model, pts.astype(np.float32), rtol=0, atol=1e-6)
    assert rec.info["object_model_file"]["path"] == str(ply)
    bad = tmp_path / "model.xyz"
    bad.write_text("1 2 3\n")
    with pytest.raises(RecordingError, match=r"unknown object model format \.xyz"):
        ingest_recording(rec_path, Store(tmp_path / "s2"), object_model=bad)
    with pytest.raises(RecordingError, match="object model file not found"):
        ingest_recording(rec_path, Store(tmp_path / "s3"), object_model=tmp_path / "nope.ply")


def test_reingest_with_another_object_model_warns(tmp_path: Path, store: Store) -> None:
    """Ingesting again is a no-op; with a different --object-model it says the stored one was kept."""
    from tasks.recording.writer import RecordingWriter

    rec_path = tmp_path / "demo.mcap"
    with RecordingWriter(rec_path, "mcap") as w:
        w.add_points("/mocap/handle", np.arange(3, dtype=np.int64) + 1, np.zeros((3, 3)))
    first = ingest_recording(rec_path, store)
    ply = tmp_path / "m.ply"
    header = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
    ply.write_text(header + "end_header\n0 0 0\n")
    again = ingest_recording(rec_path, store, object_model=ply)
    assert (again.recording_id, again.created) == (first.recording_id, False)
    assert again.warnings == (
        f"{rec_path}: already ingested as {first.recording_id} with another object model; kept the stored one",
    )


@pytest.mark.parametrize("encoding", ["cdr", "ros1"])
def test_bulk_tf_single_transform(encoding: str) -> None:
    """TFMessage with one transform per message is bulk-decoded, child frame ids included; two go general."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ros1 = encoding == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    typ = "tf2_msgs/msg/TFMessage"
    if typ not in store.fielddefs:
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms\n", typ))
    rng = np.random.default_rng(9)
    items = _messages(store, "geometry_msgs/msg/TransformStamped", 200, ros1, rng)
    children = ["l_wrist", "r_wrist", "base", "b"]
    payloads = []
    for i, (m, _, _) in enumerate(items):
        m.child_frame_id = children[i % 4]
        tfs = [m] if i % 10 else [m, m]  # every tenth message holds two transforms
        ser = store.serialize_ros1 if ros1 else store.serialize_cdr
        payloads.append(bytes(ser(store.types[typ](transforms=tfs), typ)))
    batch = Batch.from_payloads(payloads, list(range(200)))
    res = bulk_decode(batch, typ, encoding)
    np.testing.assert_array_equal(res.rest, np.arange(0, 200, 10))
    assert res.child_index is not None
    for j, i in enumerate(res.index.tolist()):
        assert res.children[int(res.child_index[j])] == children[i % 4]
        assert res.stamps_ns[j] == items[i][1]
        np.testing.assert_array_equal(res.values[j], items[i][2])


def test_tf_wrist_through_ingest(tmp_path: Path, store: Store) -> None:
    """A /tf topic of single-transform messages (bulk path): the wrist child frame becomes the wrist pose."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    items = _messages(ts, "geometry_msgs/msg/TransformStamped", 60, False, np.random.default_rng(12))
    path = tmp_path / "tfbag"
    with Writer(path, version=9) as w:
        conn = w.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=ts)
        for i, (m, ns, _) in enumerate(items):
            m.child_frame_id = "hand_wrist" if i % 2 else "base"
            w.write(
                conn,
                ns,
                bytes(ts.serialize_cdr(ts.types["tf2_msgs/msg/TFMessage"](transforms=[m]), "tf2_msgs/msg/TFMessage")),
            )
    rec = load_recording(store, ingest_recording(path, store).recording_id)
    wrist = rec.poses["hand_wrist"]
    assert wrist.role == "wrist"
    assert "base" not in rec.poses
    expect = sorted((ns, tuple(v)) for i, (_, ns, v) in enumerate(items) if i % 2)
    np.testing.assert_array_equal(wrist.stamps_ns, [e[0] for e in expect])
    np.testing.assert_array_equal(np.hstack([wrist.positions, wrist.quats]), [e[1] for e in expect])
