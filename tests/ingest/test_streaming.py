"""Streaming readers: memory bounded by a chunk, unwanted topics never decoded (nor read, where the container
says what a chunk holds), counts of every topic kept. Recordings are written by the real writers."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tasks.ingest.api import ingest_recording
from tasks.ingest.containers import read_recording
from tasks.ingest.mcap_stream import read_mcap
from tasks.ingest.roles import wanted
from tasks.recording.load import load_recording
from tasks.store import Store
from tests.conftest import REPO

T0 = 1_700_000_000_000_000_000
FRAME = 1 << 20  # bytes of one camera frame


def _camera_mcap(path: Path, frames: int, markers_per_frame: int = 4, *, cameras_first: bool = False) -> Path:
    """``frames`` 1 MB ``sensor_msgs/Image`` at 30 Hz and a PointStamped marker at 120 Hz, uncompressed chunks
    of 4 MB (mcap writer, rosbags CDR). ``cameras_first``: every frame before every marker."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    t = store.types
    point, image = "geometry_msgs/msg/PointStamped", "sensor_msgs/msg/Image"

    def header(ns: int) -> object:
        sec, nsec = divmod(ns, 1_000_000_000)
        return t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id="w")

    pixels = np.zeros(FRAME, dtype=np.uint8)
    events: list[tuple[int, int, str]] = []
    for i in range(frames):
        events.append((T0 + i * 33_333_333 + (0 if not cameras_first else -(10**12)), 0, "cam"))
        for k in range(markers_per_frame):
            events.append((T0 + i * 33_333_333 + k * 8_333_333, 1, "mark"))
    events.sort()
    with path.open("wb") as fh:
        w = Writer(fh, chunk_size=4 << 20, compression=CompressionType.NONE)
        w.start(profile="ros2", library="test")
        sids = {typ: w.register_schema(typ, "ros2msg", store.generate_msgdef(typ, ros_version=2)[0].encode())
                for typ in (point, image)}  # fmt: skip
        cam = w.register_channel("/camera/image_raw", "cdr", sids[image])
        mark = w.register_channel("/mocap/m0", "cdr", sids[point])
        for n, (stamp, _order, kind) in enumerate(events):
            if kind == "cam":
                msg = t[image](header=header(stamp), height=1024, width=1024, encoding="mono8", is_bigendian=0,
                               step=1024, data=pixels)  # fmt: skip
                w.add_message(cam, stamp, bytes(store.serialize_cdr(msg, image)), stamp, n)
            else:
                p = t["geometry_msgs/msg/Point"](x=float(n), y=0.0, z=1.0)
                data = bytes(store.serialize_cdr(t[point](header=header(stamp), point=p), point))
                w.add_message(mark, stamp, data, stamp, n)
        w.finish()
    return path


def test_chunks_of_camera_frames_only_are_skipped_unread(tmp_path: Path) -> None:
    """Frames first, markers after: the chunks holding only frames are never read, every topic is counted."""
    path = _camera_mcap(tmp_path / "cams.mcap", 12, cameras_first=True)
    content = read_mcap(path, want=wanted(None))
    assert content.chunks_skipped >= 2
    counts = {content.channels[c].topic: n for c, n in content.counts.items()}
    assert counts == {"/camera/image_raw": 12, "/mocap/m0": 48}
    kept = {content.channels[c].topic: sum(len(b) for b in bs) for c, bs in content.batches.items()}
    assert kept == {"/mocap/m0": 48}
    raw = read_recording(path, want=wanted(None))
    assert raw.topics["/camera/image_raw"].count == 12 and raw.topics["/camera/image_raw"].kept == 0


def test_mixed_chunks_keep_only_the_wanted_payloads(tmp_path: Path) -> None:
    """Frames and markers interleaved in every chunk: the frames are counted, never kept nor decoded."""
    path = _camera_mcap(tmp_path / "mixed.mcap", 10)
    raw = read_recording(path, want=wanted(None))
    assert raw.topics["/camera/image_raw"].count == 10 and not raw.topics["/camera/image_raw"].batches
    assert sum(len(b.buf) for b in raw.topics["/mocap/m0"].batches) < 40 * 100  # the markers' bytes only
    store = Store(tmp_path / "store")
    rec = load_recording(store, ingest_recording(path, store).recording_id)
    assert list(rec.markers) == ["/mocap/m0"] and len(rec.markers["/mocap/m0"].stamps_ns) == 40
    info = json.loads((rec.folder / "recording.json").read_text())
    assert {t["name"]: t["count"] for t in info["topics"]} == {"/camera/image_raw": 10, "/mocap/m0": 40}


_RSS_PROBE = """
import sys
from pathlib import Path
from tasks.ingest.api import ingest_recording
from tasks.store import Store
ingest_recording(Path(sys.argv[1]), Store(sys.argv[2]))
status = Path("/proc/self/status").read_text().splitlines()
print(next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmHWM:")))
"""
"""Peak RSS of this process alone (``VmHWM``; ``ru_maxrss`` would include the parent's from before exec)."""


def test_peak_memory_of_an_ingest_is_far_below_the_file_size(tmp_path: Path) -> None:
    """A 160 MB camera-heavy MCAP ingests in a process whose peak RSS stays under 150 MB (the interpreter with
    numpy and pyarrow takes about 100 MB; reading the whole file would add 160 MB)."""
    path = _camera_mcap(tmp_path / "big.mcap", 160)
    assert path.stat().st_size > 160e6
    probe = subprocess.run(
        [sys.executable, "-c", _RSS_PROBE, str(path), str(tmp_path / "store")],
        capture_output=True, text=True, check=True, cwd=REPO, timeout=120,
    )  # fmt: skip
    assert int(probe.stdout.split()[-1]) < 150e6


@pytest.mark.parametrize("fmt", ["bag", "rosbag2"])
def test_bag_and_sqlite_keep_only_wanted_payloads(fmt: str, tmp_path: Path) -> None:
    """ROS 1 bag and rosbag2 sqlite: a large cloud topic no marker set can be keeps its first message only,
    every count is read."""
    from tasks.recording.writer import RecordingWriter

    stamps = T0 + np.arange(50, dtype=np.int64) * 10_000_000
    path = tmp_path / ("rec.bag" if fmt == "bag" else "rec")
    with RecordingWriter(path, fmt) as w:  # type: ignore[arg-type]
        w.add_points("/mocap/m0", stamps, np.random.default_rng(0).normal(size=(50, 3)))
        for k in range(5):
            w.add_cloud("/lidar/points", int(stamps[k * 10]), np.random.default_rng(k).normal(size=(8000, 3)))
    raw = read_recording(path, want=wanted(None))
    assert raw.topics["/lidar/points"].count == 5 and raw.topics["/lidar/points"].kept == 1
    assert raw.topics["/mocap/m0"].kept == 50


def test_camera_bag_reads_only_the_marker_records(tmp_path: Path) -> None:
    """A ROS 1 bag of 1 MB frames and markers in uncompressed 4 MB chunks (the markers read record by record):
    the markers come out exact, the frames are counted and never kept."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from tasks.ingest.bag_stream import read_bag

    store = get_typestore(Stores.ROS1_NOETIC)
    t = store.types
    point, image = "geometry_msgs/msg/PointStamped", "sensor_msgs/msg/Image"
    path = tmp_path / "cams.bag"
    writer = Writer(path)
    writer.chunk_threshold = 4 << 20
    xyz = np.random.default_rng(4).normal(size=(48, 3))
    with writer:
        cam = writer.add_connection("/camera/image_raw", image, typestore=store)
        mark = writer.add_connection("/mocap/m0", point, typestore=store)
        for i in range(48):
            stamp = T0 + i * 8_333_333
            sec, nsec = divmod(stamp, 1_000_000_000)
            header = t["std_msgs/msg/Header"](seq=i, stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                              frame_id="w")  # fmt: skip
            if i % 4 == 0:
                msg = t[image](header=header, height=1024, width=1024, encoding="mono8", is_bigendian=0, step=1024,
                               data=np.zeros(FRAME, dtype=np.uint8))  # fmt: skip
                writer.write(cam, stamp, bytes(store.serialize_ros1(msg, image)))
            p = t["geometry_msgs/msg/Point"](x=xyz[i, 0], y=xyz[i, 1], z=xyz[i, 2])
            writer.write(mark, stamp + 1, bytes(store.serialize_ros1(t[point](header=header, point=p), point)))
    content = read_bag(path, want=wanted(None))
    assert {c.topic: content.counts[i] for i, c in content.connections.items()} == {
        "/camera/image_raw": 12,
        "/mocap/m0": 48,
    }
    assert set(content.payloads) == {mark.id}
    store_ = Store(tmp_path / "store")
    m = load_recording(store_, ingest_recording(path, store_).recording_id).markers["/mocap/m0"]
    np.testing.assert_array_equal(m.points, xyz)


def test_index_records_that_miss_their_messages_are_a_corrupt_bag(tmp_path: Path) -> None:
    """The markers of a camera chunk are read where its index records say: a shifted offset is one line."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from tasks.errors import RecordingError

    store = get_typestore(Stores.ROS1_NOETIC)
    t = store.types
    path = tmp_path / "cams.bag"
    writer = Writer(path)
    writer.chunk_threshold = 4 << 20
    with writer:
        cam = writer.add_connection("/camera/image_raw", "sensor_msgs/msg/Image", typestore=store)
        mark = writer.add_connection("/mocap/m0", "geometry_msgs/msg/PointStamped", typestore=store)
        for i in range(8):
            header = t["std_msgs/msg/Header"](seq=i, stamp=t["builtin_interfaces/msg/Time"](sec=i + 1, nanosec=0),
                                              frame_id="w")  # fmt: skip
            pixels = np.zeros(FRAME, dtype=np.uint8)
            image = t["sensor_msgs/msg/Image"](header=header, height=1024, width=1024, encoding="mono8",
                                               is_bigendian=0, step=1024, data=pixels)  # fmt: skip
            writer.write(cam, T0 + i, bytes(store.serialize_ros1(image, "sensor_msgs/msg/Image")))
            p = t["geometry_msgs/msg/PointStamped"](
                header=header, point=t["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=3.0)
            )
            writer.write(mark, T0 + i, bytes(store.serialize_ros1(p, "geometry_msgs/msg/PointStamped")))
    data = bytearray(path.read_bytes())
    pos, found = len(b"#ROSBAG V2.0\n"), []
    while pos < len(data):  # the IndexData records (op 4) of the marker connection
        hlen = int.from_bytes(data[pos : pos + 4], "little")
        header = bytes(data[pos + 4 : pos + 4 + hlen])
        dstart = pos + 8 + hlen
        if b"op=\x04" in header and b"conn=" + mark.id.to_bytes(4, "little") in header:
            found.append(dstart)
        pos = dstart + int.from_bytes(data[pos + 4 + hlen : dstart], "little")
    last = found[1]  # the second chunk's: frames and markers, its markers read where the index says
    first = int.from_bytes(data[last + 8 : last + 12], "little")  # an entry: secs, nsecs, offset
    data[last + 8 : last + 12] = (first + 3).to_bytes(4, "little")
    bad = tmp_path / "bad.bag"
    bad.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match=r"bad\.bag: corrupt bag"):
        ingest_recording(bad, Store(tmp_path / "store"))
