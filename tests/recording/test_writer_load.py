"""The recording writer (real writers, every container) and the Parquet loader."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from rosbags.highlevel import AnyReader

from schemas.tables import MARKERS_SCHEMA, OBJECT_MODEL_SCHEMA, POSES_SCHEMA
from tasks.errors import RecordingError
from tasks.recording.load import load_recording, load_recording_folder
from tasks.recording.writer import RecordingWriter
from tasks.store import Store

T0 = 1_700_000_000_000_000_000


def _write(path: Path, fmt: str, compression: str | None = None) -> np.ndarray:
    stamps = T0 + np.arange(50, dtype=np.int64) * 10_000_000
    xyz = np.random.default_rng(1).normal(size=(50, 3))
    xyz[7] = np.nan
    with RecordingWriter(path, fmt, compression=compression) as w:  # type: ignore[arg-type]
        w.add_points("/mocap/door_0", stamps, xyz)
        w.add_poses("/wrist/pose", stamps[::5], xyz[::5] * 0 + 1.0, np.tile([0.0, 0.0, 0.0, 1.0], (10, 1)))
        w.add_cloud("/object/model", int(stamps[0]), np.ones((20, 3)))
        w.add_string("/demo/meta", int(stamps[0]), json.dumps({"action": "open", "object": "microwave"}))
    return xyz


def _digest(path: Path) -> str:
    files = sorted(path.iterdir()) if path.is_dir() else [path]
    return hashlib.sha256(b"".join(f.read_bytes() for f in files)).hexdigest()


@pytest.mark.parametrize(("fmt", "compression"), [("bag", "none"), ("bag", "bz2"), ("bag", "lz4"), ("rosbag2", None)])
def test_rosbags_reads_back_every_sample(tmp_path: Path, fmt: str, compression: str | None) -> None:
    path = tmp_path / ("demo.bag" if fmt == "bag" else "demo")
    xyz = _write(path, fmt, compression)
    with AnyReader([path]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        conn = next(c for c in reader.connections if c.topic == "/mocap/door_0")
        got = [reader.deserialize(raw, conn.msgtype).point for _, _, raw in reader.messages([conn])]
    assert counts == {"/mocap/door_0": 49, "/wrist/pose": 10, "/object/model": 1, "/demo/meta": 1}
    keep = np.isfinite(xyz).all(axis=1)
    np.testing.assert_array_equal(np.array([[p.x, p.y, p.z] for p in got]), xyz[keep])


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_mcap_reads_back_with_the_ros2_decoder(tmp_path: Path, compression: str) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    path = tmp_path / "demo.mcap"
    xyz = _write(path, "mcap", compression)
    with path.open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        pts = [
            (m.point.x, m.point.y, m.point.z)
            for _, ch, _, m in reader.iter_decoded_messages()
            if ch.topic == "/mocap/door_0"
        ]
    np.testing.assert_array_equal(np.array(pts), xyz[np.isfinite(xyz).all(axis=1)])


@pytest.mark.parametrize("fmt", ["mcap", "bag", "rosbag2"])
def test_same_input_gives_identical_bytes(tmp_path: Path, fmt: str) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    _write(tmp_path / "a" / "demo", fmt)
    _write(tmp_path / "b" / "demo", fmt)
    assert _digest(tmp_path / "a" / "demo") == _digest(tmp_path / "b" / "demo")


def test_refuses_overwrite_and_leaves_nothing_on_error(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    path.write_bytes(b"keep")
    with pytest.raises(RecordingError, match="refusing to overwrite"), RecordingWriter(path, "mcap"):
        pass
    assert path.read_bytes() == b"keep"
    other = tmp_path / "y.mcap"
    with pytest.raises(RuntimeError), RecordingWriter(other, "mcap") as w:
        w.add_string("/demo/meta", 0, "{}")
        raise RuntimeError
    assert not other.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.mcap"]


def test_bad_format_compression_and_topic_type(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="unknown format 'zip'"):
        RecordingWriter(tmp_path / "a", "zip")  # type: ignore[arg-type]
    with pytest.raises(RecordingError, match="bag cannot use compression 'zstd'"):
        RecordingWriter(tmp_path / "a.bag", "bag", compression="zstd")
    w = RecordingWriter(tmp_path / "b.mcap", "mcap")
    w.add_string("/t", 0, "x")
    with pytest.raises(RecordingError, match=r"topic /t: topic already has type std_msgs/msg/String"):
        w.add_points("/t", [0], [[0.0, 0.0, 0.0]])


def _fake_ingest(store: Store, rec_id: str) -> Path:
    """Parquet folder in the RECORDING.md layout, written directly with pyarrow."""
    folder = store.recording_dir(rec_id)
    folder.mkdir(parents=True)
    markers = pa.Table.from_pydict(
        {"marker": ["b", "a", "a"], "stamp_ns": [5, 2, 1], "x": [3.0, 2.0, 1.0], "y": [0.0] * 3, "z": [0.0] * 3},
        schema=MARKERS_SCHEMA,
    )
    pq.write_table(markers, folder / "markers.parquet")
    poses = pa.Table.from_pydict(
        {"frame": ["/wrist/pose"], "role": ["wrist"], "stamp_ns": [1], "x": [1.0], "y": [2.0], "z": [3.0],
         "qx": [0.0], "qy": [0.0], "qz": [0.0], "qw": [1.0]},
        schema=POSES_SCHEMA,
    )  # fmt: skip
    pq.write_table(poses, folder / "poses.parquet")
    model = pa.Table.from_pydict({"x": [0.5], "y": [0.5], "z": [0.5]}, schema=OBJECT_MODEL_SCHEMA)
    pq.write_table(model, folder / "object_model.parquet")
    info = {"id": rec_id, "start_ns": 1, "end_ns": 5, "schema_version": 1, "meta": {"action": "open"}}
    (folder / "recording.json").write_text(json.dumps(info))
    return folder


def test_loader_splits_tracks(store: Store) -> None:
    _fake_ingest(store, "0123456789abcdef")
    rec = load_recording(store, "0123456789abcdef")
    assert sorted(rec.markers) == ["a", "b"]
    np.testing.assert_array_equal(rec.markers["a"].stamps_ns, [1, 2])
    np.testing.assert_array_equal(rec.markers["a"].points[:, 0], [1.0, 2.0])
    assert rec.wrist is not None
    np.testing.assert_array_equal(rec.wrist.positions, [[1.0, 2.0, 3.0]])
    assert rec.object_model is not None
    assert rec.object_model.shape == (1, 3)
    assert rec.meta == {"action": "open"}
    assert rec.start_ns == 1


def test_loader_errors(store: Store, tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="is not in the store"):
        load_recording(store, "ffffffffffffffff")
    folder = _fake_ingest(store, "00000000000000aa")
    (folder / "recording.json").write_text(json.dumps({"id": "x", "start_ns": 0, "schema_version": 99}))
    with pytest.raises(RecordingError, match="schema_version 99"):
        load_recording_folder(folder)
    (folder / "recording.json").write_text("{")
    with pytest.raises(RecordingError, match="cannot read ingested recording"):
        load_recording_folder(folder)


def test_loader_names_a_corrupt_or_incomplete_table(store: Store) -> None:
    folder = _fake_ingest(store, "00000000000000bb")
    markers = folder / "markers.parquet"
    markers.write_bytes(markers.read_bytes()[:40])
    with pytest.raises(RecordingError, match=r"markers\.parquet: cannot read ingested table"):
        load_recording_folder(folder)
    folder = _fake_ingest(store, "00000000000000cc")
    pq.write_table(pa.table({"frame": ["/wrist"], "stamp_ns": [1]}), folder / "poses.parquet")
    with pytest.raises(RecordingError, match=r"poses\.parquet: cannot read ingested table"):
        load_recording_folder(folder)


def test_loader_keeps_nan_dropouts_and_sorts_by_stamp(store: Store) -> None:
    folder = _fake_ingest(store, "00000000000000dd")
    table = pa.Table.from_pydict(
        {"marker": ["m"] * 3, "stamp_ns": [30, 10, 20], "x": [3.0, 1.0, float("nan")], "y": [0.0] * 3, "z": [0.0] * 3},
        schema=MARKERS_SCHEMA,
    )
    pq.write_table(table, folder / "markers.parquet")
    track = load_recording_folder(folder).markers["m"]
    np.testing.assert_array_equal(track.stamps_ns, [10, 20, 30])
    np.testing.assert_array_equal(track.points[:, 0], [1.0, np.nan, 3.0])
    assert track.points.dtype == np.float64
    assert track.stamps_ns.dtype == np.int64
