"""Every ``RecordingError`` the readers raise, provoked with hand-built bytes (MCAP records, bag records,
rosbag2 folders) so that each message names the file and says what is wrong."""

from __future__ import annotations

import shutil
import sqlite3
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml

from tasks.errors import RecordingError, TruncatedRecordingError
from tasks.ingest.api import ingest_recording
from tasks.ingest.containers import read_recording
from tasks.ingest.extract import Extracted, extract_topic
from tasks.ingest.mcap_stream import MAGIC, Batch
from tasks.ingest.raw import RawTopic
from tasks.store import Store

# -- MCAP records by hand (https://mcap.dev/spec) -------------------------------------------------------


def _s(text: str) -> bytes:
    b = text.encode()
    return struct.pack("<I", len(b)) + b


def _rec(op: int, body: bytes) -> bytes:
    return struct.pack("<BQ", op, len(body)) + body


def _header() -> bytes:
    return _rec(0x01, _s("ros2") + _s("test"))


def _schema(sid: int = 1, name: str = "std_msgs/msg/String", data: bytes = b"string data\n") -> bytes:
    return _rec(0x03, struct.pack("<H", sid) + _s(name) + _s("ros2msg") + struct.pack("<I", len(data)) + data)


def _channel(cid: int = 1, sid: int = 1, topic: str = "/demo/meta", enc: str = "cdr") -> bytes:
    return _rec(0x04, struct.pack("<HH", cid, sid) + _s(topic) + _s(enc) + struct.pack("<I", 0))


def _message(cid: int = 1, t: int = 5, data: bytes = b"\x00\x01\x00\x00\x03\x00\x00\x00{}\x00\x00") -> bytes:
    return _rec(0x05, struct.pack("<HIQQ", cid, 0, t, t) + data)


def _chunk(records: bytes, compression: str = "", usize: int | None = None, crc: int | None = None) -> bytes:
    size = len(records) if usize is None else usize
    body = struct.pack("<QQQI", 0, 10, size, zlib.crc32(records) if crc is None else crc)
    body += _s(compression) + struct.pack("<Q", len(records)) + records
    return _rec(0x06, body)


def _footer() -> bytes:
    return _rec(0x02, struct.pack("<QQI", 0, 0, 0)) + MAGIC


def _mcap(tmp: Path, *records: bytes, footer: bool = True) -> Path:
    path = tmp / "hand.mcap"
    path.write_bytes(MAGIC + _header() + b"".join(records) + (_footer() if footer else b""))
    return path


GOOD = (_schema(), _channel(), _message())


def test_hand_built_mcap_reads(tmp_path: Path, store: Store) -> None:
    """The builder itself is right: the plain file ingests, its meta is the JSON in the message."""
    result = ingest_recording(_mcap(tmp_path, *GOOD), store)
    assert result.created


@pytest.mark.parametrize(
    ("records", "match"),
    [
        (
            (_schema(), _channel(), _chunk(_message(), "brotli")),
            r"corrupt chunk at byte \d+ \(unknown chunk compression 'brotli'\)",
        ),
        ((_schema(), _channel(), _chunk(_message(), "", crc=1)), r"corrupt chunk .*CRC mismatch"),
        ((_schema(), _channel(), _chunk(_message(), "", usize=999)), r"decompressed to \d+ bytes, header says 999"),
        ((_schema(), _channel(), _chunk(b"\x05\x00\x00", "")), r"record header cut at byte 0"),
        ((_schema(), _channel(), _chunk(_rec(0x05, b"\x01\x00"), "")), r"message record at byte 0 too short"),
        ((_chunk(_rec(0x03, b"\x01\x00\xff\xff\xff\x00"), ""),), r"bad schema record at byte 0"),
        ((_chunk(_rec(0x04, b"\x01\x00\x01\x00\xff\xff\x00\x00"), ""),), r"bad channel record at byte 0"),
        ((_schema(), _channel(), _chunk(struct.pack("<BQ", 5, 10**6) + b"x" * 40, "")), r"runs past its end"),
        ((_schema(), _channel(), _chunk(b"garbage!" * 4, "zstd")), r"zstd data does not decompress"),
        ((_schema(), _channel(), _rec(0x06, b"\x00" * 10)), r"corrupt chunk .*bad chunk header"),
        (
            (_schema(), _channel(), _rec(0x06, struct.pack("<QQQI", 0, 0, 4, 0) + _s("") + struct.pack("<Q", 99))),
            r"run past the chunk",
        ),
        (
            (_schema(), _channel(), _rec(0x05, b"\x01\x00")),
            r"corrupt chunk at byte \d+ \(message record .* too short\)",
        ),
        ((_rec(0x03, b"\x01\x00\xff\xff\xff\x00"),), r"corrupt record at byte \d+"),
        ((_schema(), _message()), r"messages on channel id 1 which the file never defines"),
        (
            (_schema(), _channel(), _channel(2, 2, "/demo/meta"), _schema(2, "std_msgs/msg/Int32"), _message()),
            r"topic /demo/meta: two channels with types",
        ),
    ],
)
def test_mcap_damage(records: tuple[bytes, ...], match: str, tmp_path: Path, store: Store) -> None:
    """Each malformed MCAP record gives a RecordingError naming the file."""
    path = _mcap(tmp_path, *records)
    with pytest.raises(RecordingError, match=match) as err:
        ingest_recording(path, store)
    assert str(path) in str(err.value)


def test_mcap_end_magic_and_cut_header(tmp_path: Path, store: Store) -> None:
    """A footer without the closing magic; a file ending inside a record header."""
    path = tmp_path / "nomagic.mcap"
    path.write_bytes(MAGIC + _header() + b"".join(GOOD) + _footer()[:-8])
    with pytest.raises(TruncatedRecordingError, match=r"end magic missing"):
        ingest_recording(path, store)
    path = tmp_path / "cuthead.mcap"
    path.write_bytes(MAGIC + _header() + b"".join(GOOD) + b"\x02\x00")
    with pytest.raises(TruncatedRecordingError, match=r"record header cut off"):
        ingest_recording(path, store)


# -- ROS 1 bag records by hand (http://wiki.ros.org/Bags/Format/2.0) -----------------------------------


def _field(name: str, value: bytes) -> bytes:
    item = name.encode() + b"=" + value
    return struct.pack("<I", len(item)) + item


def _brec(fields: bytes, data: bytes) -> bytes:
    return struct.pack("<I", len(fields)) + fields + struct.pack("<I", len(data)) + data


def _bag_conn(conn: int = 0, topic: str = "/a", typ: str = "std_msgs/String") -> bytes:
    hdr = _field("op", b"\x07") + _field("conn", struct.pack("<I", conn)) + _field("topic", topic.encode())
    data = _field("topic", topic.encode()) + _field("type", typ.encode()) + _field("md5sum", b"x")
    data += _field("message_definition", b"string data\n")
    return _brec(hdr, data)


def _bag_msg(conn: int = 0) -> bytes:
    hdr = _field("op", b"\x02") + _field("conn", struct.pack("<I", conn)) + _field("time", struct.pack("<II", 1, 0))
    return _brec(hdr, struct.pack("<I", 2) + b"hi")


def _bag_chunk(inner: bytes, compression: str = "none", size: int | None = None) -> bytes:
    hdr = _field("op", b"\x05") + _field("compression", compression.encode())
    hdr += _field("size", struct.pack("<I", len(inner) if size is None else size))
    return _brec(hdr, inner)


def _bag(tmp: Path, *records: bytes, version: bytes = b"2.0") -> Path:
    path = tmp / "hand.bag"
    head = _brec(_field("op", b"\x03") + _field("index_pos", struct.pack("<Q", 0)), b"")
    path.write_bytes(b"#ROSBAG V" + version + b"\n" + head + b"".join(records))
    return path


def test_hand_built_bag_reads(tmp_path: Path) -> None:
    """The builder is right: one String message on /a."""
    raw = read_recording(_bag(tmp_path, _bag_chunk(_bag_conn() + _bag_msg())))
    assert raw.topics["/a"].count == 1


@pytest.mark.parametrize(
    ("records", "match"),
    [
        ((_bag_chunk(_bag_conn() + _bag_msg(), "zip"),), r"corrupt bag: unknown chunk compression 'zip'"),
        (
            (_bag_chunk(_bag_conn() + _bag_msg(), "bz2"),),
            r"corrupt bag: chunk at byte \d+: bz2 data does not decompress",
        ),
        ((_bag_chunk(_bag_conn() + _bag_msg(), size=3),), r"decompressed to \d+ bytes, header says 3"),
        ((_bag_chunk(_bag_conn() + _bag_msg()[:-3]),), r"holds a cut-off record"),
        ((_bag_chunk(_bag_chunk(b"")),), r"chunk inside a chunk"),
        ((_brec(_field("conn", b"\x00\x00\x00\x00"), b""),), r"has no op code"),
        ((_brec(struct.pack("<I", 3) + b"op\x02", b""),), r"header field without '='"),
        ((_brec(struct.pack("<I", 50) + b"op=\x02", b""),), r"header field runs past its header"),
        ((_brec(b"\x01\x00", b""),), r"header field cut off"),
        ((_bag_chunk(_bag_msg(3)),), r"messages on connection 3 which is never defined"),
        (
            (_bag_chunk(_bag_conn(0, "/a") + _bag_conn(1, "/a", "std_msgs/Int32") + _bag_msg()),),
            r"topic /a: two connections",
        ),
    ],
)
def test_bag_damage(records: tuple[bytes, ...], match: str, tmp_path: Path, store: Store) -> None:
    """Each malformed bag record gives a RecordingError naming the file."""
    path = _bag(tmp_path, *records)
    with pytest.raises(RecordingError, match=match) as err:
        ingest_recording(path, store)
    assert str(path) in str(err.value)


def test_bag_version_and_magic(tmp_path: Path) -> None:
    """An old bag version; a file with the bag magic only."""
    with pytest.raises(RecordingError, match=r"unsupported ROS bag version 1\.2"):
        read_recording(_bag(tmp_path, version=b"1.2"))
    from tasks.ingest.bag_stream import read_bag

    (tmp_path / "x.bag").write_bytes(b"nope")
    with pytest.raises(RecordingError, match="not a recording"):
        read_bag(tmp_path / "x.bag")


# -- rosbag2 folders ------------------------------------------------------------------------------------


@pytest.fixture
def bag2(tmp_path: Path) -> Path:
    """A small rosbag2 (sqlite3) written by the project's writer."""
    from tasks.recording.writer import RecordingWriter

    path = tmp_path / "bag2"
    with RecordingWriter(path, "rosbag2") as w:
        w.add_points("/m", np.arange(3, dtype=np.int64) + 1, np.zeros((3, 3)))
    return path


def _edit_meta(bag: Path, **changes: object) -> None:
    doc = yaml.safe_load((bag / "metadata.yaml").read_text())
    doc["rosbag2_bagfile_information"].update(changes)
    (bag / "metadata.yaml").write_text(yaml.safe_dump(doc))


def test_rosbag2_metadata_problems(bag2: Path, tmp_path: Path, store: Store) -> None:
    """No storage files listed; an unknown compression format; an unknown storage plugin."""
    for i, (changes, match) in enumerate(
        [
            ({"relative_file_paths": [], "files": []}, "empty: metadata.yaml lists no storage files"),
            ({"compression_format": "lz4", "compression_mode": "FILE"}, "unknown compression format 'lz4'"),
            (
                {"storage_identifier": "parquet", "relative_file_paths": ["x.parquet"]},
                "unknown rosbag2 storage 'parquet'",
            ),
        ]
    ):
        bag = tmp_path / f"copy{i}"
        shutil.copytree(bag2, bag)
        if changes.get("relative_file_paths"):
            (bag / "x.parquet").write_bytes(b"")
        _edit_meta(bag, **changes)
        with pytest.raises(RecordingError, match=match):
            ingest_recording(bag, store)


def test_rosbag2_sqlite_problems(bag2: Path, tmp_path: Path, store: Store) -> None:
    """A storage file that is not .db3 under sqlite3 storage; a message on an undefined topic id."""
    bag = tmp_path / "txt"
    shutil.copytree(bag2, bag)
    db = next(bag.glob("*.db3"))
    db.rename(bag / "data.txt")
    _edit_meta(bag, relative_file_paths=["data.txt"])
    with pytest.raises(RecordingError, match=r"unexpected storage file data\.txt for sqlite3 storage"):
        ingest_recording(bag, store)
    bag = tmp_path / "orphan"
    shutil.copytree(bag2, bag)
    db = next(bag.glob("*.db3"))
    with sqlite3.connect(db) as con:
        con.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (77, 1, x'00')")
    with pytest.raises(RecordingError, match="message on topic id 77 which the topics table does not define"):
        ingest_recording(bag, store)


def test_rosbag2_message_compression(bag2: Path, tmp_path: Path, store: Store) -> None:
    """Per-message zstd compression is undone; data that is not zstd is an error."""
    import zstandard

    bag = tmp_path / "msgzstd"
    shutil.copytree(bag2, bag)
    db = next(bag.glob("*.db3"))
    with sqlite3.connect(db) as con:
        rows = con.execute("SELECT id, data FROM messages").fetchall()
        for rid, data in rows:
            con.execute("UPDATE messages SET data = ? WHERE id = ?", (zstandard.compress(bytes(data)), rid))
    _edit_meta(bag, compression_format="zstd", compression_mode="MESSAGE")
    raw = read_recording(bag)
    assert raw.topics["/m"].count == 3
    assert ingest_recording(bag, store).created
    bad = tmp_path / "msgbad"
    shutil.copytree(bag2, bad)
    _edit_meta(bad, compression_format="zstd", compression_mode="MESSAGE")
    with pytest.raises(RecordingError, match="zstd data does not decompress"):
        read_recording(bad)


def test_read_missing_path(tmp_path: Path) -> None:
    """read_recording on a path that does not exist."""
    with pytest.raises(RecordingError, match="no such file or folder"):
        read_recording(tmp_path / "gone.bag")


def test_extract_type_that_cannot_play_role() -> None:
    """extract_topic refuses a type for a role it cannot have; bad cloud layouts name the topic."""
    topic = RawTopic("/s", "std_msgs/msg/String", "cdr", "", "", [Batch.from_payloads([b"\x00\x01\x00\x00"], [1])])
    with pytest.raises(RecordingError, match=r"topic /s: type std_msgs/msg/String cannot be markers"):
        extract_topic(topic, "markers", "mem", Extracted())
    cloud = RawTopic("/c", "sensor_msgs/msg/PointCloud2", "json", "", "", [])
    cloud.batches.append(Batch.from_payloads([b'{"header": {}, "fields": [], "point_step": 12}'], [1]))
    with pytest.raises(RecordingError, match=r"topic /c: cannot read sensor_msgs/msg/PointCloud2 samples \(ValueError"):
        extract_topic(cloud, "markers", "mem", Extracted())


def test_object_model_without_points(tmp_path: Path) -> None:
    """A model file holding no points."""
    from tasks.ingest.object_model import load_object_model

    ply = tmp_path / "empty.ply"
    ply.write_text(
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
    with pytest.raises(RecordingError, match="object model file holds no points"):
        load_object_model(ply)
