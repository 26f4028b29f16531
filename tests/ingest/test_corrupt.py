"""Damaged input: truncations, flipped bytes, random bytes, empty files, short rosbag2 storage.

Every case ends in a clean ``RecordingError`` naming the file (and nothing in the store), or, where the
damage does not touch the data (a flipped byte in the summary section), in exactly the original samples.
``--recover`` keeps the intact messages before the damage of a truncated MCAP and reports the loss.
"""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from tasks.errors import RecordingError, TruncatedRecordingError
from tasks.ingest.api import ingest_recording
from tasks.recording.load import load_recording
from tasks.store import Store

T0 = 1_700_000_000_000_000_000
N = 400
RNG = np.random.default_rng(11)
STAMPS = T0 + np.arange(N, dtype=np.int64) * 10_000_000
XYZ = RNG.normal(size=(N, 3))


def _mcap(path: Path, compression: str = "zstd", chunk_size: int = 4096) -> Path:
    """PointStamped markers on two topics, written with mcap + rosbags CDR in small chunks."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    typ = "geometry_msgs/msg/PointStamped"
    text, _ = store.generate_msgdef(typ, ros_version=2)
    t = store.types
    with path.open("wb") as fh:
        w = Writer(fh, chunk_size=chunk_size, compression=getattr(CompressionType, compression.upper()))
        w.start(profile="ros2", library="test")
        sid = w.register_schema(typ, "ros2msg", text.encode())
        chans = [w.register_channel(f"/mocap/m{k}", "cdr", sid) for k in range(2)]
        for i in range(N):
            sec, nsec = divmod(int(STAMPS[i]), 1_000_000_000)
            header = t["std_msgs/msg/Header"](
                stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id="w"
            )
            msg = t[typ](header=header, point=t["geometry_msgs/msg/Point"](x=XYZ[i, 0], y=XYZ[i, 1], z=XYZ[i, 2]))
            w.add_message(chans[i % 2], int(STAMPS[i]), bytes(store.serialize_cdr(msg, typ)), int(STAMPS[i]))
        w.finish()
    return path


def _bag(path: Path, compression: str = "none") -> Path:
    from tasks.recording.writer import RecordingWriter

    with RecordingWriter(path, "bag", compression=compression) as w:
        w.add_points("/mocap/m0", STAMPS[0::2], XYZ[0::2])
        w.add_points("/mocap/m1", STAMPS[1::2], XYZ[1::2])
    return path


def _empty_store(store: Store) -> None:
    for d in (store.recordings_dir, store.tmp_dir):
        assert not d.exists() or not any(d.iterdir()), f"{d} is not empty"


def _same_as_original(store: Store, rec_id: str) -> None:
    rec = load_recording(store, rec_id)
    for k in range(2):
        m = rec.markers[f"/mocap/m{k}"]
        np.testing.assert_array_equal(m.stamps_ns, STAMPS[k::2])
        np.testing.assert_array_equal(m.points, XYZ[k::2])


@pytest.mark.parametrize("fraction", [0.02, 0.1, 0.33, 0.5, 0.77, 0.95, 0.999])
def test_truncated_mcap(fraction: float, tmp_path: Path, store: Store) -> None:
    """A cut MCAP: error naming the byte offset; ``recover`` keeps an exact prefix and reports the loss."""
    full = _mcap(tmp_path / "full.mcap").read_bytes()
    cut = int(len(full) * fraction)
    path = tmp_path / "cut.mcap"
    path.write_bytes(full[:cut])
    with pytest.raises(TruncatedRecordingError, match=r"cut\.mcap: truncated at byte \d+") as err:
        ingest_recording(path, store)
    assert 8 <= err.value.offset <= cut
    _empty_store(store)
    try:
        result = ingest_recording(path, store, recover=True)
    except RecordingError as e:  # cut before the first complete message: nothing to recover
        assert "empty: no messages" in str(e)
        assert fraction < 0.05
        _empty_store(store)
        return
    assert result.created
    assert any("recovered" in w for w in result.warnings)
    rec = load_recording(store, result.recording_id)
    kept = 0
    for k in range(2):
        m = rec.markers[f"/mocap/m{k}"]
        n = len(m.stamps_ns)
        kept += n
        np.testing.assert_array_equal(m.stamps_ns, STAMPS[k::2][:n])  # an exact prefix, nothing invented
        np.testing.assert_array_equal(m.points, XYZ[k::2][:n])
    assert rec.info["lost_messages"] == result.lost_messages
    if kept == N:  # cut in the summary section: nothing lost
        assert result.lost_messages == 0
        assert any("recovered all 400 messages" in w for w in result.warnings)
    else:  # a lower bound: the cut chunk's messages (the rest of the file is gone and cannot be counted)
        assert 0 <= result.lost_messages <= N - kept
        assert any(f"lost at least {result.lost_messages}" in w for w in result.warnings)


def test_truncated_inside_last_chunk_salvages_its_front(tmp_path: Path, store: Store) -> None:
    """Recovery decodes the complete records at the front of a chunk cut by the end of file (zstd stream)."""
    # one uncompressed chunk (a zstd or lz4 chunk this small is one block: nothing of it decodes when cut)
    full = _mcap(tmp_path / "full.mcap", compression="none", chunk_size=1 << 20).read_bytes()
    path = tmp_path / "cut.mcap"
    path.write_bytes(full[: len(full) // 2])
    result = ingest_recording(path, store, recover=True)
    rec = load_recording(store, result.recording_id)
    kept = sum(len(m.stamps_ns) for m in rec.markers.values())
    assert kept > N // 4
    assert abs(result.lost_messages - (N - kept)) <= 2  # one chunk: the estimate is nearly exact


@pytest.mark.parametrize("fraction", [0.001, 0.3, 0.6, 0.99])
@pytest.mark.parametrize("compression", ["none", "bz2"])
def test_truncated_bag(fraction: float, compression: str, tmp_path: Path, store: Store) -> None:
    """A cut ROS 1 bag: error naming the byte offset, nothing in the store."""
    full = _bag(tmp_path / "full.bag", compression).read_bytes()
    path = tmp_path / "cut.bag"
    path.write_bytes(full[: int(len(full) * fraction)])
    with pytest.raises(TruncatedRecordingError, match=r"cut\.bag: truncated at byte \d+"):
        ingest_recording(path, store)
    _empty_store(store)


@pytest.mark.parametrize("kind", ["mcap-zstd", "mcap-lz4", "bag-bz2"])
def test_flipped_bytes(kind: str, tmp_path: Path, store: Store) -> None:
    """Flip single bytes at 40 places: a clean RecordingError, or (damage outside the data) the original."""
    if kind.startswith("mcap"):
        original = _mcap(tmp_path / "orig.mcap", compression=kind.split("-")[1]).read_bytes()
    else:
        original = _bag(tmp_path / "orig.bag", "bz2").read_bytes()
    rng = np.random.default_rng(3)
    outcomes = {"error": 0, "same": 0}
    for j, pos in enumerate(sorted(rng.choice(len(original), size=40, replace=False).tolist())):
        damaged = bytearray(original)
        damaged[pos] ^= 0xFF
        path = tmp_path / f"flip{j}.{kind.split('-', maxsplit=1)[0]}"
        path.write_bytes(bytes(damaged))
        s = Store(tmp_path / f"store{j}")
        try:
            result = ingest_recording(path, s)
        except RecordingError as err:
            assert str(path) in str(err)
            _empty_store(s)
            outcomes["error"] += 1
            continue
        _same_as_original(s, result.recording_id)
        outcomes["same"] += 1
    assert outcomes["error"] > 0
    del store


@pytest.mark.parametrize("suffix", [".mcap", ".bag", ".db3", ""])
def test_random_bytes(suffix: str, tmp_path: Path, store: Store) -> None:
    """Random bytes are not a recording, whatever the file is called."""
    path = tmp_path / f"noise{suffix}"
    path.write_bytes(np.random.default_rng(5).integers(0, 256, size=5000, dtype=np.uint8).tobytes())
    with pytest.raises(RecordingError, match=r"noise.*: not a recording"):
        ingest_recording(path, store)
    _empty_store(store)


@pytest.mark.parametrize("magic", [b"\x89MCAP0\r\n", b"#ROSBAG V2.0\n"])
def test_magic_then_noise(magic: bytes, tmp_path: Path, store: Store) -> None:
    """The right magic followed by noise: corrupt or truncated, never a crash."""
    path = tmp_path / "noise.rec"
    noise = np.random.default_rng(6).integers(0, 256, size=3000, dtype=np.uint8).tobytes()
    path.write_bytes(magic + noise)
    with pytest.raises(RecordingError, match=r"noise\.rec: (corrupt|truncated)"):
        ingest_recording(path, store)
    _empty_store(store)


@pytest.mark.parametrize("name", ["empty.mcap", "empty.bag", "empty.db3"])
def test_empty_file(name: str, tmp_path: Path, store: Store) -> None:
    """A 0-byte file."""
    path = tmp_path / name
    path.write_bytes(b"")
    with pytest.raises(RecordingError, match=r"empty file \(0 bytes\)"):
        ingest_recording(path, store)
    _empty_store(store)


def test_mcap_without_messages(tmp_path: Path, store: Store) -> None:
    """A valid MCAP with channels but no messages is empty."""
    from mcap.writer import Writer

    path = tmp_path / "none.mcap"
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="ros2", library="test")
        sid = w.register_schema("std_msgs/msg/String", "ros2msg", b"string data\n")
        w.register_channel("/demo/meta", "cdr", sid)
        w.finish()
    with pytest.raises(RecordingError, match=r"none\.mcap: empty: no messages"):
        ingest_recording(path, store)


def _rosbag2(path: Path) -> Path:
    from tasks.recording.writer import RecordingWriter

    with RecordingWriter(path, "rosbag2") as w:
        w.add_points("/mocap/m0", STAMPS[0::2], XYZ[0::2])
        w.add_points("/mocap/m1", STAMPS[1::2], XYZ[1::2])
    return path


def test_rosbag2_shortfall_is_reported(tmp_path: Path, store: Store) -> None:
    """Fewer messages in the storage than metadata.yaml promises: an error naming the topic."""
    bag = _rosbag2(tmp_path / "bag")
    db = next(bag.glob("*.db3"))
    with sqlite3.connect(db) as con:
        (tid,) = con.execute("SELECT id FROM topics WHERE name = '/mocap/m1'").fetchone()
        con.execute("DELETE FROM messages WHERE topic_id = ? AND id % 3 = 0", (tid,))
    with pytest.raises(
        RecordingError, match=r"topic /mocap/m1: metadata.yaml promises 200 messages, the storage holds 13\d"
    ):
        ingest_recording(bag, store)
    _empty_store(store)


def test_rosbag2_missing_storage_and_bad_metadata(tmp_path: Path, store: Store) -> None:
    """A storage file named in metadata.yaml is missing; metadata.yaml is not rosbag2 metadata."""
    bag = _rosbag2(tmp_path / "bag")
    broken = tmp_path / "broken"
    shutil.copytree(bag, broken)
    next(broken.glob("*.db3")).unlink()
    with pytest.raises(RecordingError, match=r"storage file .*\.db3 listed in metadata.yaml is missing"):
        ingest_recording(broken, store)
    (bag / "metadata.yaml").write_text("just: text\n")
    with pytest.raises(RecordingError, match="not a rosbag2 metadata file"):
        ingest_recording(bag, store)
    (bag / "metadata.yaml").write_text("{unclosed: [\n")
    with pytest.raises(RecordingError, match=r"unreadable metadata\.yaml"):
        ingest_recording(bag, store)
    _empty_store(store)


def test_truncated_db3(tmp_path: Path, store: Store) -> None:
    """A cut sqlite3 storage file."""
    bag = _rosbag2(tmp_path / "bag")
    db = next(bag.glob("*.db3"))
    data = db.read_bytes()
    cut = tmp_path / "cut.db3"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(RecordingError, match=r"cut\.db3: corrupt sqlite3 storage"):
        ingest_recording(cut, store)
    _empty_store(store)


def test_sqlite_without_rosbag2_tables(tmp_path: Path, store: Store) -> None:
    """An sqlite3 file that is not a rosbag2 storage."""
    db = tmp_path / "other.db3"
    with sqlite3.connect(db) as con:
        con.execute("CREATE TABLE t (x INTEGER)")
    with pytest.raises(RecordingError, match="sqlite3 file without rosbag2 tables"):
        ingest_recording(db, store)


def test_missing_path(tmp_path: Path, store: Store) -> None:
    """A path that does not exist."""
    with pytest.raises(RecordingError, match="no such file or folder"):
        ingest_recording(tmp_path / "nope.mcap", store)
