"""Roles: detection by type and name, and the ``--topics`` map override (RECORDING.md "Roles")."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tasks.errors import RecordingError, TopicMapError
from tasks.ingest.api import ingest_recording
from tasks.ingest.roles import detect_role, is_mocap_markers, is_service_event
from tasks.recording.load import load_recording
from tasks.store import Store

STAMPS = 1_700_000_000_000_000_000 + np.arange(20, dtype=np.int64) * 10_000_000
XYZ = np.random.default_rng(1).normal(size=(20, 3))
Q = np.tile([0.0, 0.0, 0.0, 1.0], (20, 1))


@pytest.fixture
def recording(tmp_path: Path) -> Path:
    """Topics whose names do not reveal their roles."""
    from tasks.recording.writer import RecordingWriter

    path = tmp_path / "plain.mcap"
    with RecordingWriter(path, "mcap") as w:
        w.add_points("/mocap/a", STAMPS, XYZ)
        w.add_points("/mocap/b", STAMPS, XYZ + 1)
        w.add_poses("/hand", STAMPS, XYZ + 2, Q)
        w.add_cloud("/cam/cloud", int(STAMPS[0]), XYZ[:5])
        w.add_string("/notes", int(STAMPS[0]), json.dumps({"action": "slide", "object": "drawer"}))
    return path


def test_detection_by_type_and_name() -> None:
    """The table of RECORDING.md."""
    assert detect_role("/demo/meta", "std_msgs/msg/String") == "meta"
    assert detect_role("demo/meta", "std_msgs/msg/String") == "meta"  # topic names without a leading slash
    assert detect_role("/object_cloud", "sensor_msgs/msg/PointCloud2") == "object_model"
    assert detect_role("/markers", "sensor_msgs/msg/PointCloud2") == "markers"
    assert detect_role("/Wrist/pose", "geometry_msgs/msg/PoseStamped") == "wrist"
    assert detect_role("/tf", "tf2_msgs/msg/TFMessage", ["base", "r_wrist"]) == "wrist"
    assert detect_role("/tf", "tf/msg/tfMessage", ["hand_wrist"]) == "wrist"  # legacy tf
    assert detect_role("/tf", "tf2_msgs/msg/TFMessage", ["base"]) == "ignored"
    assert detect_role("/lid", "geometry_msgs/msg/TransformStamped", ["lid"]) == "markers"
    assert detect_role("/m", "mocap4r2_msgs/msg/Markers") == "markers"
    assert detect_role("/rosout", "rcl_interfaces/msg/Log") == "ignored"
    assert is_mocap_markers("mocap4r2_msgs/msg/Markers")
    assert not is_mocap_markers("visualization_msgs/msg/MarkerArray")
    assert is_service_event("/x/_service_event", "example_interfaces/srv/AddTwoInts_Event")


def test_without_map(recording: Path, store: Store) -> None:
    """Without a map the anonymous topics are all markers (and /notes is ignored)."""
    result = ingest_recording(recording, store)
    rec = load_recording(store, result.recording_id)
    roles = {t["name"]: t["role"] for t in rec.info["topics"]}
    assert roles == {
        "/mocap/a": "markers",
        "/mocap/b": "markers",
        "/hand": "markers",
        "/cam/cloud": "markers",
        "/notes": "ignored",
    }
    assert sorted(rec.markers) == [
        "/cam/cloud/0",
        "/cam/cloud/1",
        "/cam/cloud/2",
        "/cam/cloud/3",
        "/cam/cloud/4",
        "/hand",
        "/mocap/a",
        "/mocap/b",
    ]
    assert rec.poses["/hand"].role == "markers"
    assert rec.wrist is None


def test_topic_map_overrides(recording: Path, store: Store, tmp_path: Path) -> None:
    """markers by regex, wrist, object model, meta and ignore from the map."""
    tmap = tmp_path / "topics.yaml"
    tmap.write_text(
        "markers: ['/mocap/.*']\nwrist: /hand\nobject_model: /cam/cloud\nmeta: /notes\nignore: [/mocap/b]\n"
    )
    result = ingest_recording(recording, store, topics=tmap)
    rec = load_recording(store, result.recording_id)
    roles = {t["name"]: t["role"] for t in rec.info["topics"]}
    assert roles == {
        "/mocap/a": "markers",
        "/mocap/b": "ignored",
        "/hand": "wrist",
        "/cam/cloud": "object_model",
        "/notes": "meta",
    }
    assert sorted(rec.markers) == ["/mocap/a"]
    assert rec.wrist is not None
    np.testing.assert_array_equal(rec.wrist.positions, XYZ + 2)
    assert rec.object_model is not None
    np.testing.assert_allclose(rec.object_model, XYZ[:5].astype(np.float32))
    assert rec.meta == {"action": "slide", "object": "drawer"}


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("markers: [/nope]\n", r"markers: '/nope' matches no topic"),
        ("wrist: /notes\n", r"topic /notes has type std_msgs/msg/String, which cannot be wrist"),
        ("object_model: /mocap/a\n", r"cannot be object_model"),
        ("colour: /mocap/a\n", r"unknown key 'colour'"),
        ("- just\n- a list\n", r"a topic map is a YAML mapping"),
        ("markers: ['(']\n", r"not a valid regular expression"),
        ("markers: [1, 2]\n", r"expected a topic name or a list"),
        ("markers: [unclosed\n", r"not valid YAML"),
    ],
)
def test_bad_topic_map(text: str, match: str, recording: Path, store: Store, tmp_path: Path) -> None:
    """A bad map is a TopicMapError naming the map file; nothing lands in the store."""
    tmap = tmp_path / "topics.yaml"
    tmap.write_text(text)
    with pytest.raises(TopicMapError, match=match) as err:
        ingest_recording(recording, store, topics=tmap)
    assert str(tmap) in str(err.value)
    assert not store.recordings_dir.exists() or not any(store.recordings_dir.iterdir())


def test_missing_topic_map(recording: Path, store: Store, tmp_path: Path) -> None:
    """A map file that does not exist."""
    with pytest.raises(TopicMapError, match="cannot read topic map"):
        ingest_recording(recording, store, topics=tmp_path / "none.yaml")


def test_map_cannot_use_a_skipped_topic(store: Store, tmp_path: Path) -> None:
    """A topic skipped for its encoding cannot be given a role by the map."""
    from mcap.writer import Writer

    path = tmp_path / "mixed.mcap"
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="", library="test")
        s1 = w.register_schema("geometry_msgs/msg/PointStamped", "jsonschema", b"{}")
        s2 = w.register_schema("geometry_msgs/msg/PointStamped", "protobuf", b"")
        c1 = w.register_channel("/a", "json", s1)
        c2 = w.register_channel("/b", "protobuf", s2)
        msg = {"header": {"stamp": {"sec": 1, "nanosec": 0}, "frame_id": "w"}, "point": {"x": 1.0, "y": 2.0, "z": 3.0}}
        w.add_message(c1, 1, json.dumps(msg).encode(), 1)
        w.add_message(c2, 1, b"\x00", 1)
        w.finish()
    tmap = tmp_path / "topics.yaml"
    tmap.write_text("markers: [/a, /b]\n")
    with pytest.raises(
        RecordingError, match=r"topic /b: cannot use this topic \(unknown message encoding 'protobuf'\)"
    ):
        ingest_recording(path, store, topics=tmap)
    result = ingest_recording(path, store)
    assert any("topic /b: skipped (unknown message encoding 'protobuf')" in w for w in result.warnings)
    rec = load_recording(store, result.recording_id)
    np.testing.assert_array_equal(rec.markers["/a"].points, [[1.0, 2.0, 3.0]])


def test_only_service_events_is_an_error(store: Store, tmp_path: Path) -> None:
    """A recording holding nothing but service events."""
    from mcap.writer import Writer

    path = tmp_path / "services.mcap"
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="ros2", library="test")
        sid = w.register_schema("example_interfaces/srv/AddTwoInts_Event", "ros2msg", b"MSG: broken\n---\n")
        cid = w.register_channel("/add/_service_event", "cdr", sid)
        w.add_message(cid, 1, b"\x00\x01\x00\x00", 1)
        w.finish()
    with pytest.raises(RecordingError, match="only service-event topics, nothing to ingest"):
        ingest_recording(path, store)
