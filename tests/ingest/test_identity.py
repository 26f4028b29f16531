"""A recording's store entry is keyed by its content and its topic map; roles by what a topic is; short lines."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

from tasks.errors import RecordingError, TopicMapError, bounded
from tasks.ingest.api import ingest_recording
from tasks.recording.load import load_recording
from tasks.recording.writer import RecordingWriter
from tasks.store import Store

T0 = 1_700_000_000_000_000_000
STAMPS = T0 + np.arange(120, dtype=np.int64) * 10_000_000
RNG = np.random.default_rng(3)


def _two_markers(path: Path) -> Path:
    with RecordingWriter(path, "mcap") as w:
        w.add_points("/mocap/a", STAMPS, RNG.normal(size=(120, 3)))
        w.add_points("/mocap/b", STAMPS, RNG.normal(size=(120, 3)))
    return path


def test_a_map_after_a_plain_ingest_is_honoured_and_the_reverse(tmp_path: Path) -> None:
    rec = _two_markers(tmp_path / "r.mcap")
    only_a = tmp_path / "a.yaml"
    only_a.write_text("markers: [/mocap/a]\n")
    for order in ((None, only_a), (only_a, None)):
        store = Store(tmp_path / f"store{order[0] is None}")
        results = [ingest_recording(rec, store, topics=m) for m in order]
        plain, mapped = results if order[0] is None else results[::-1]
        assert plain.recording_id != mapped.recording_id
        assert mapped.recording_id.startswith(plain.recording_id + "-") and len(plain.recording_id) == 16
        assert sorted(load_recording(store, plain.recording_id).markers) == ["/mocap/a", "/mocap/b"]
        assert sorted(load_recording(store, mapped.recording_id).markers) == ["/mocap/a"]
        info = json.loads((mapped.folder / "recording.json").read_text())
        assert info["topic_map"]["canonical"] == '{"markers":["/mocap/a"]}'
        assert info["content_id"] == plain.recording_id
        assert json.loads((plain.folder / "recording.json").read_text())["topic_map"] is None
        again = ingest_recording(rec, store, topics=only_a)
        assert again.recording_id == mapped.recording_id and not again.created


def test_equal_maps_share_a_key_and_a_bad_map_fails_after_a_plain_ingest(tmp_path: Path) -> None:
    rec = _two_markers(tmp_path / "r.mcap")
    store = Store(tmp_path / "store")
    one, two = tmp_path / "1.yaml", tmp_path / "2.yaml"
    one.write_text("markers: [/mocap/b, /mocap/a]\n")
    two.write_text("# the same roles\nmarkers:\n  - /mocap/a\n  - /mocap/b\n")
    assert (
        ingest_recording(rec, store, topics=one).recording_id == ingest_recording(rec, store, topics=two).recording_id
    )
    ingest_recording(rec, store)
    bad = tmp_path / "bad.yaml"
    bad.write_text("markers: [/mocap/nowhere]\n")
    with pytest.raises(TopicMapError, match="'/mocap/nowhere' matches no topic"):
        ingest_recording(rec, store, topics=bad)


def _with_cloud(path: Path, points: list[int]) -> Path:
    with RecordingWriter(path, "bag") as w:
        w.add_points("/mocap/a", STAMPS, RNG.normal(size=(120, 3)))
        for k, n in enumerate(points):
            w.add_cloud("/velodyne_points", int(STAMPS[k]), RNG.normal(size=(n, 3)))
    return path


@pytest.mark.parametrize(
    ("points", "why"),
    [([36_000, 36_000], "a dense PointCloud2 .36000 points"), ([300, 300, 300], "a dense PointCloud2 .300 points"),
     ([12, 15, 12], "point count changes between messages")],
)  # fmt: skip
def test_a_dense_or_changing_cloud_is_not_a_marker_set(points: list[int], why: str, tmp_path: Path) -> None:
    rec = _with_cloud(tmp_path / "lidar.bag", points)
    store = Store(tmp_path / "store")
    result = ingest_recording(rec, store)
    assert list(load_recording(store, result.recording_id).markers) == ["/mocap/a"]
    (line,) = [w for w in result.warnings if "velodyne" in w]
    assert re.search(why, line) and "ignored" in line and len(line) < 300
    cloud_map = tmp_path / "m.yaml"
    cloud_map.write_text("markers: [/velodyne_points]\n")
    with pytest.raises(TopicMapError, match=r"is a .*not a marker set"):
        ingest_recording(rec, store, topics=cloud_map)
    as_model = tmp_path / "o.yaml"
    as_model.write_text("object_model: /velodyne_points\n")
    model = load_recording(store, ingest_recording(rec, store, topics=as_model).recording_id).object_model
    assert model is not None and len(model) == points[0]


def test_a_small_steady_cloud_stays_a_marker_set(tmp_path: Path) -> None:
    rec = _with_cloud(tmp_path / "set.bag", [6, 6, 6])
    store = Store(tmp_path / "store")
    markers = load_recording(store, ingest_recording(rec, store).recording_id).markers
    assert sorted(markers) == ["/mocap/a"] + [f"/velodyne_points/{i}" for i in range(6)]


def test_every_error_line_is_short(tmp_path: Path) -> None:
    assert bounded([f"m{i}" for i in range(36_000)]) == "m0, m1, m2, m3, m4 and 35995 more"
    assert bounded(["x" * 500]).endswith("...") and len(bounded(["x" * 500])) == 120
    err = RecordingError("f.bag", "bad\n" * 10_000, "/t" * 10_000)
    assert "\n" not in str(err) and len(str(err)) < 600
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    with pytest.raises(RecordingError, match=r"pipe\.mcap: a FIFO .named pipe., not a recording"):
        ingest_recording(fifo, Store(tmp_path / "store"))
    loop = tmp_path / "loop.bag"
    loop.symlink_to(loop)
    with pytest.raises(RecordingError, match=r"loop\.bag: a symbolic link loop"):
        ingest_recording(loop, Store(tmp_path / "store"))
    dangling = tmp_path / "gone.bag"
    dangling.symlink_to(tmp_path / "nowhere.bag")
    with pytest.raises(RecordingError, match=r"gone\.bag: a dangling symbolic link"):
        ingest_recording(dangling, Store(tmp_path / "store"))
