"""``--recover`` on ROS 1 bags and rosbag2: the intact messages before the damage are kept, the loss reported.

Bags are written by rosbags' rosbag1 ``Writer`` with small chunks (several chunks per bag, as a long recording
has) and then cut or damaged; rosbag2 folders by rosbags' rosbag2 ``Writer`` (sqlite3 and MCAP storage). Without
``recover`` each case stays the clean error it was (tests/ingest/test_corrupt.py).
"""

from __future__ import annotations

import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tasks.errors import RecordingError
from tasks.ingest.api import ingest_recording
from tasks.recording.load import load_recording
from tasks.store import Store

T0 = 1_700_000_000_000_000_000
N = 600
RNG = np.random.default_rng(5)
STAMPS = T0 + np.arange(N, dtype=np.int64) * 10_000_000
XYZ = RNG.normal(size=(N, 3))
TYPE = "geometry_msgs/msg/PointStamped"


def _messages(ros1: bool) -> list[tuple[str, int, bytes]]:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    t = store.types
    out = []
    for i in range(N):
        sec, nsec = divmod(int(STAMPS[i]), 1_000_000_000)
        stamp = t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
        header = (
            t["std_msgs/msg/Header"](seq=i, stamp=stamp, frame_id="w")
            if ros1
            else t["std_msgs/msg/Header"](stamp=stamp, frame_id="w")
        )
        msg = t[TYPE](header=header, point=t["geometry_msgs/msg/Point"](x=XYZ[i, 0], y=XYZ[i, 1], z=XYZ[i, 2]))
        data = store.serialize_ros1(msg, TYPE) if ros1 else store.serialize_cdr(msg, TYPE)
        out.append((f"/mocap/m{i % 2}", int(STAMPS[i]), bytes(data)))
    return out


def _bag(path: Path, compression: str, chunk_bytes: int = 3000) -> Path:
    """A ROS 1 bag of two marker topics in chunks of about ``chunk_bytes`` (rosbags' rosbag1 Writer)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    writer = Writer(path)
    writer.chunk_threshold = chunk_bytes
    if compression != "none":
        writer.set_compression(getattr(Writer.CompressionFormat, compression.upper()))
    with writer:
        conns = {f"/mocap/m{k}": writer.add_connection(f"/mocap/m{k}", TYPE, typestore=store) for k in range(2)}
        for topic, stamp, data in _messages(ros1=True):
            writer.write(conns[topic], stamp, data)
    return path


def _rosbag2(path: Path, storage: str) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        conns = {f"/mocap/m{k}": writer.add_connection(f"/mocap/m{k}", TYPE, typestore=store) for k in range(2)}
        for topic, stamp, data in _messages(ros1=False):
            writer.write(conns[topic], stamp, data)
    return path


def _kept_prefix(store: Store, rec_id: str) -> int:
    """Messages kept, after checking that each topic holds an exact prefix of what was written."""
    rec = load_recording(store, rec_id)
    kept = 0
    for k in range(2):
        m = rec.markers[f"/mocap/m{k}"]
        n = len(m.stamps_ns)
        np.testing.assert_array_equal(m.stamps_ns, STAMPS[k::2][:n])
        np.testing.assert_array_equal(m.points, XYZ[k::2][:n])
        kept += n
    return kept


def _chunk_offsets(data: bytes) -> list[int]:
    """Byte offsets of the bag's chunk records (op 0x05), read off the records."""
    out, pos = [], len(b"#ROSBAG V2.0\n")
    while pos + 4 <= len(data):
        hlen = int.from_bytes(data[pos : pos + 4], "little")
        header = data[pos + 4 : pos + 4 + hlen]
        dlen = int.from_bytes(data[pos + 4 + hlen : pos + 8 + hlen], "little")
        if b"op=\x05" in header:
            out.append(pos)
        pos += 8 + hlen + dlen
    return out


@pytest.mark.parametrize("compression", ["none", "bz2", "lz4"])
@pytest.mark.parametrize("fraction", [0.2, 0.5, 0.8])
def test_cut_bag_keeps_the_chunks_before_the_cut(compression: str, fraction: float, tmp_path: Path) -> None:
    full = _bag(tmp_path / "full.bag", compression).read_bytes()
    chunks = _chunk_offsets(full)
    assert len(chunks) >= 8
    path = tmp_path / "cut.bag"
    path.write_bytes(full[: int(len(full) * fraction)])
    store = Store(tmp_path / "store")
    with pytest.raises(RecordingError, match=r"cut\.bag: truncated at byte \d+"):
        ingest_recording(path, store)
    result = ingest_recording(path, store, recover=True)
    kept = _kept_prefix(store, result.recording_id)
    whole_chunks = sum(1 for c in chunks[1:] if c <= len(full) * fraction)  # chunks ending before the cut
    assert kept >= whole_chunks * 10  # every whole chunk's messages (each holds > 10 here)
    assert 0 < kept < N
    lost = N - kept
    assert abs(result.lost_messages - lost) <= max(2, 0.1 * lost)  # the header gives where the data ends
    (warning,) = [w for w in result.warnings if "recovered" in w]
    assert f"recovered {kept} messages, lost about {result.lost_messages} (estimated from" in warning
    assert f"truncated at byte {int(len(full) * fraction)}" in warning  # where the damage is: the end of the file
    assert load_recording(store, result.recording_id).info["lost_messages"] == result.lost_messages


def test_the_front_of_a_cut_uncompressed_chunk_is_kept(tmp_path: Path) -> None:
    full = _bag(tmp_path / "full.bag", "none", chunk_bytes=1 << 20).read_bytes()
    assert len(_chunk_offsets(full)) == 1
    path = tmp_path / "cut.bag"
    path.write_bytes(full[: len(full) // 2])
    store = Store(tmp_path / "store")
    result = ingest_recording(path, store, recover=True)
    kept = _kept_prefix(store, result.recording_id)
    assert N // 3 < kept < N  # half the file: the front half of its one chunk
    assert abs(result.lost_messages - (N - kept)) <= max(2, 0.1 * (N - kept))


def test_a_killed_recorder_gives_a_lower_bound_from_the_cut_chunk(tmp_path: Path) -> None:
    """No index position in the header (the recorder never closed the bag): the one cut uncompressed chunk's
    size in its header still bounds the loss within 10 %, and the warning calls it a lower bound."""
    full = bytearray(_bag(tmp_path / "full.bag", "none", chunk_bytes=1 << 20).read_bytes())
    at = full.index(b"index_pos=") + len(b"index_pos=")
    full[at : at + 8] = bytes(8)  # a header as the recorder writes it before it closes the bag
    path = tmp_path / "cut.bag"
    path.write_bytes(bytes(full[: len(full) // 2]))
    store = Store(tmp_path / "store")
    result = ingest_recording(path, store, recover=True)
    lost = N - _kept_prefix(store, result.recording_id)
    assert abs(result.lost_messages - lost) <= max(2, 0.1 * lost)
    assert any(f"lost at least {result.lost_messages} (a lower bound" in w for w in result.warnings)


def test_a_bag_cut_in_its_index_loses_nothing(tmp_path: Path) -> None:
    full = _bag(tmp_path / "full.bag", "bz2").read_bytes()
    end_of_data = _chunk_offsets(full)[-1]
    path = tmp_path / "cut.bag"
    path.write_bytes(full[: len(full) - 40])  # inside the chunk-info records at the end
    assert len(full) - 40 > end_of_data
    store = Store(tmp_path / "store")
    with pytest.raises(RecordingError, match=r"cut\.bag: truncated"):
        ingest_recording(path, store)
    result = ingest_recording(path, store, recover=True)
    assert _kept_prefix(store, result.recording_id) == N
    assert result.lost_messages == 0
    assert any(f"recovered all {N} messages" in w for w in result.warnings)


def test_a_chunk_that_does_not_decompress_stops_the_read_there(tmp_path: Path) -> None:
    full = bytearray(_bag(tmp_path / "full.bag", "bz2").read_bytes())
    chunks = _chunk_offsets(bytes(full))
    middle = chunks[len(chunks) // 2]
    full[middle + 200 : middle + 240] = bytes(40)  # zeros inside the bz2 stream of a middle chunk
    path = tmp_path / "bad.bag"
    path.write_bytes(bytes(full))
    store = Store(tmp_path / "store")
    with pytest.raises(RecordingError, match=r"bad\.bag: corrupt bag: chunk at byte \d+"):
        ingest_recording(path, store)
    result = ingest_recording(path, store, recover=True)
    kept = _kept_prefix(store, result.recording_id)
    assert 0 < kept < N
    assert any(f"corrupt bag: chunk at byte {middle}" in w and "lost about" in w for w in result.warnings)


def test_rosbag2_sqlite_shortfall_and_cut_storage(tmp_path: Path) -> None:
    bag = _rosbag2(tmp_path / "bag", "sqlite3")
    db = next(bag.glob("*.db3"))
    with sqlite3.connect(db) as con:
        con.execute("DELETE FROM messages WHERE id > 500")
    store = Store(tmp_path / "store")
    with pytest.raises(RecordingError, match=r"metadata.yaml promises 300 messages, the storage holds 250"):
        ingest_recording(bag, store)
    result = ingest_recording(bag, store, recover=True)
    assert _kept_prefix(store, result.recording_id) == 500
    assert result.lost_messages == 100  # exact: metadata.yaml counts every topic
    assert any("lost 50 of 300" in w and w.count("lost 50") == 2 for w in result.warnings)

    cut = tmp_path / "cut"
    shutil.copytree(_rosbag2(tmp_path / "bag2", "sqlite3"), cut)
    db = next(cut.glob("*.db3"))
    data = db.read_bytes()
    db.write_bytes(data[: len(data) * 2 // 3])
    with pytest.raises(RecordingError, match="corrupt sqlite3 storage"):
        ingest_recording(cut, Store(tmp_path / "store2"))
    store2 = Store(tmp_path / "store2")
    try:
        result = ingest_recording(cut, store2, recover=True)
    except RecordingError as err:  # the cut took the schema pages: nothing to recover, still a clean error
        assert "corrupt sqlite3 storage" in str(err) or "empty" in str(err)
        return
    kept = _kept_prefix(store2, result.recording_id)
    assert result.lost_messages == N - kept


def test_rosbag2_mcap_cut_reports_the_exact_loss(tmp_path: Path) -> None:
    bag = _rosbag2(tmp_path / "bag", "mcap")
    storage = next(bag.glob("*.mcap"))
    data = storage.read_bytes()
    storage.write_bytes(data[: len(data) // 2])
    store = Store(tmp_path / "store")
    with pytest.raises(RecordingError, match="truncated at byte"):
        ingest_recording(bag, store)
    result = ingest_recording(bag, store, recover=True)
    kept = _kept_prefix(store, result.recording_id)
    assert 0 < kept < N
    assert result.lost_messages == N - kept


def test_cli_recovers_a_cut_bag(tmp_path: Path) -> None:
    full = _bag(tmp_path / "full.bag", "lz4").read_bytes()
    path = tmp_path / "cut.bag"
    path.write_bytes(full[: len(full) // 2])
    pbd = str(Path(sys.executable).parent / "pbd")
    store = str(tmp_path / "store")
    failed = subprocess.run([pbd, "ingest", str(path), "--store", store], capture_output=True, text=True, check=False)
    assert failed.returncode == 2 and "cut.bag: truncated at byte" in failed.stderr
    done = subprocess.run(
        [pbd, "ingest", str(path), "--recover", "--store", store], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    assert "recovered" in done.stderr and "lost about" in done.stderr


def test_a_cut_mcap_chunk_loss_is_a_lower_bound_from_its_header(tmp_path: Path) -> None:
    """MCAP has no chunk count up front: the cut chunk's size in its header bounds the loss (within 10 % when
    the cut falls in the last chunk), and the warning names the byte where the file ends."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "one.mcap"
    with path.open("wb") as fh:
        w = Writer(fh, chunk_size=1 << 24, compression=CompressionType.NONE)
        w.start(profile="ros2", library="test")
        sid = w.register_schema(TYPE, "ros2msg", store.generate_msgdef(TYPE, ros_version=2)[0].encode())
        chans = {f"/mocap/m{k}": w.register_channel(f"/mocap/m{k}", "cdr", sid) for k in range(2)}
        for topic, stamp, data in _messages(ros1=False):
            w.add_message(chans[topic], stamp, data, stamp)
        w.finish()
    full = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full[: len(full) // 2])
    store_ = Store(tmp_path / "store")
    result = ingest_recording(cut, store_, recover=True)
    lost = N - _kept_prefix(store_, result.recording_id)
    assert lost > 0 and abs(result.lost_messages - lost) <= 0.1 * lost
    (warning,) = [w for w in result.warnings if "recovered" in w]
    assert f"truncated at byte {len(full) // 2} (inside the chunk that starts at byte" in warning
    assert f"lost at least {result.lost_messages} (a lower bound" in warning
