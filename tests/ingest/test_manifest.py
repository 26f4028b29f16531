"""One test per trouble spot that ../shared/logs/MANIFEST.md names."""

from __future__ import annotations

import numpy as np
import pytest

from tasks.errors import RecordingError
from tasks.ingest.api import ingest_recording
from tasks.ingest.containers import read_recording
from tasks.ingest.extract import child_frames
from tasks.recording.load import load_recording
from tasks.store import Store
from tests.conftest import LOGS

CONFORMANCE = LOGS / "mcap" / "conformance"


def test_chunk_index_without_summary_channels() -> None:
    """``-chx`` without ``-rch``/``-rsh``: a seeking reader fails (no channels in the summary); we stream."""
    files = sorted(p for p in CONFORMANCE.glob("TenMessages/*.mcap") if "chx" in p.name and "rch" not in p.name)
    assert len(files) >= 8
    for path in files:
        raw = read_recording(path)
        assert {n: t.count for n, t in raw.topics.items()} == {"example": 10}
        assert raw.topics["example"].encoding == "a"  # the conformance suite's placeholder encoding


def test_rosbag2_qos_mismatch_reads_every_message(store: Store) -> None:
    """metadata QoS differs from the data file: rosbags returned 0 messages; we read all metadata promises."""
    for storage in ("mcap", "sqlite3"):
        bag = LOGS / "rosbag2/HEAD/rosbag2_py/test/resources" / storage / "convert_a"
        raw = read_recording(bag)
        assert {n: (t.count, t.expected) for n, t in raw.topics.items()} == {
            "a_empty": (100, 100),
            "b_basictypes": (50, 50),
        }
    result = ingest_recording(LOGS / "rosbag2/HEAD/rosbag2_py/test/resources/mcap/convert_a", store)
    counts = {t["name"]: t["count"] for t in load_recording(store, result.recording_id).info["topics"]}
    assert counts == {"a_empty": 100, "b_basictypes": 50}


def test_service_event_topics_are_skipped(store: Store) -> None:
    """Service-event schemas neither reference library parses: skipped with a warning, the rest ingests."""
    bag = LOGS / "rosbag2/HEAD/rosbag2_tests/resources/mcap/bag_with_topics_and_service_events"
    result = ingest_recording(bag, store)
    assert sorted(w.split(" topic ")[1] for w in result.warnings) == [
        "/test_service1/_service_event: skipped (service events are not demonstration data)",
        "/test_service2/_service_event: skipped (service events are not demonstration data)",
    ]
    roles = {t["name"]: (t["role"], t["count"]) for t in load_recording(store, result.recording_id).info["topics"]}
    assert roles["/test_topic1"] == ("ignored", 1)
    assert roles["/test_service1/_service_event"] == ("ignored", 4)


def test_zero_byte_bag(store: Store) -> None:
    """A 0-byte bag."""
    with pytest.raises(RecordingError, match=r"empty-file\.bag: empty file \(0 bytes\)"):
        ingest_recording(LOGS / "foxglove_rosbag/empty-file.bag", store)


def test_legacy_tf_message() -> None:
    """Legacy ``tf/tfMessage`` decodes from the bag's own definition (its child frames are read)."""
    raw = read_recording(LOGS / "PlotJuggler/tilt_laser.bag")
    tf = raw.topics["/tf"]
    assert (tf.msgtype, tf.count) == ("tf/msg/tfMessage", 711)
    frames = child_frames(tf, "tilt_laser.bag")
    assert frames
    assert not any("wrist" in f for f in frames)


def test_topic_names_without_leading_slash(store: Store) -> None:
    """Topics ``ORB-SLAM``, ``S-PTAM``, ``groundtruth`` (PoseStamped rigid bodies) keep their names."""
    result = ingest_recording(LOGS / "evo/test/data/ROS_example.bag", store)
    rec = load_recording(store, result.recording_id)
    assert sorted(rec.markers) == ["ORB-SLAM", "S-PTAM", "groundtruth"]
    assert {k: len(v.stamps_ns) for k, v in rec.markers.items()} == {
        "ORB-SLAM": 8362,
        "S-PTAM": 5439,
        "groundtruth": 12765,
    }
    gt = rec.poses["groundtruth"]
    assert gt.role == "markers"
    np.testing.assert_allclose(np.linalg.norm(gt.quats, axis=1), 1.0, atol=1e-6)
    assert np.all(np.diff(gt.stamps_ns) >= 0)
