"""Benchmark ``pbd ingest`` against the readers a user would use: ``mcap``'s reader and ``rosbags``' AnyReader.

Recordings are generated at run time into a temporary folder (never committed) and deleted after:

- camera-heavy: 1 MB ``sensor_msgs/Image`` frames at 30 Hz and one ``geometry_msgs/PointStamped`` marker at
  120 Hz, uncompressed 4 MB chunks, about 1.5 GB (``--big``: also about 10 GB); as an MCAP (mcap writer), a ROS 1
  bag (rosbags rosbag1 Writer) and a rosbag2 (rosbags rosbag2 Writer, sqlite3). Every reader is asked for the
  marker topic only;
- marker-only: 300,000 PointStamped over 4 topics, zstd chunks (today's file; ``--quick``: 30,000).

Each tool runs as a whole process under ``/usr/bin/time`` (wall seconds, peak RSS): ``pbd ingest FILE --store
NEW``; ``mcap`` ``make_reader(...).iter_messages(topics=...)`` + ``deserialize_cdr`` per message (MCAP only);
``rosbags`` ``AnyReader.messages(connections=...)`` + ``deserialize`` per message. All write the same marker
rows (counted and compared). Development part: the MCAP recordings of seed 0. Held-out part: the ROS 1 bag and
rosbag2 recordings and the marker-only file of seed 1. Usage::

    .venv/bin/python bench/ingest.py            # ~1.5 GB camera-heavy files and 300k markers (a few minutes)
    .venv/bin/python bench/ingest.py --quick    # ~150 MB files and 30k markers
    .venv/bin/python bench/ingest.py --big      # adds the ~10 GB camera-heavy MCAP, bag and rosbag2
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
PY = Path(sys.executable)
PBD = PY.with_name("pbd")
TIME = "/usr/bin/time"
MARKER_TOPICS = ("/mocap/m0", "/mocap/m1", "/mocap/m2", "/mocap/m3")
CAMERA_TOPIC = "/camera/image_raw"
CAMERA_HZ, MARKER_HZ, FRAME_BYTES, CHUNK_BYTES = 30, 120, 1 << 20, 4 << 20
T0 = 1_700_000_000_000_000_000
POINT, IMAGE = "geometry_msgs/msg/PointStamped", "sensor_msgs/msg/Image"
RSS_TARGET_MB = 300

BASELINE_MCAP = """
import sys
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore

typestore = get_typestore(Stores.ROS2_HUMBLE)
rows = []
with open(sys.argv[1], "rb") as fh:
    for _schema, channel, message in make_reader(fh).iter_messages(topics=sys.argv[2].split(",")):
        msg = typestore.deserialize_cdr(message.data, "geometry_msgs/msg/PointStamped")
        rows.append((channel.topic, msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec,
                     msg.point.x, msg.point.y, msg.point.z))
print(len(rows))
"""

BASELINE_ANYREADER = """
import sys
from pathlib import Path
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

topics = set(sys.argv[2].split(","))
rows = []
with AnyReader([Path(sys.argv[1])], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
    conns = [c for c in reader.connections if c.topic in topics]
    for conn, _t, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        rows.append((conn.topic, msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec,
                     msg.point.x, msg.point.y, msg.point.z))
print(len(rows))
"""


ID_ONLY = (
    "import sys; from pathlib import Path; from tasks.ingest.content_id import recording_id_of; "
    "print(recording_id_of(Path(sys.argv[1])))"
)
"""What RECORDING.md's content id (SHA-256 of every byte) costs by itself: pbd hashes it on a second thread
while it reads, so on a camera-heavy file this is the floor of pbd's CPU time."""

START_ONLY = "import flows.cli, flows.commands.ingest"
"""What ``pbd ingest`` costs before it opens the file: the interpreter, numpy, pyarrow and pbd's modules."""


# -- recordings ------------------------------------------------------------------------------------
def _templates(ros1: bool) -> tuple[bytes, bytes]:
    """Serialised PointStamped and 1 MB mono8 Image (rosbags), to be patched with stamps and values."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    t = store.types
    stamp = t["builtin_interfaces/msg/Time"](sec=1, nanosec=2)
    header = (
        t["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id="world")
        if ros1
        else t["std_msgs/msg/Header"](stamp=stamp, frame_id="world")
    )
    point = t[POINT](header=header, point=t["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0))
    side = int(FRAME_BYTES**0.5)
    image = t[IMAGE](header=header, height=side, width=side, encoding="mono8", is_bigendian=0, step=side,
                     data=np.zeros(side * side, dtype=np.uint8))  # fmt: skip
    ser = store.serialize_ros1 if ros1 else store.serialize_cdr
    return bytes(ser(point, POINT)), bytes(ser(image, IMAGE))


def _stamped(template: bytes, stamp_ns: int, ros1: bool, xyz: tuple[float, float, float] | None = None) -> bytes:
    """The template with its header stamp (and the PointStamped's x, y, z) set."""
    out = bytearray(template)
    at = 4  # CDR: after the encapsulation header; ROS 1: after seq
    sec, nsec = divmod(stamp_ns, 1_000_000_000)
    out[at : at + 8] = int(sec).to_bytes(4, "little") + int(nsec).to_bytes(4, "little")
    if xyz is not None:
        out[-24:] = np.asarray(xyz, dtype="<f8").tobytes()
    del ros1
    return bytes(out)


def _camera_events(frames: int, seed: int) -> Iterator[tuple[int, str, tuple[float, float, float] | None]]:
    """(stamp ns, topic, marker xyz or None) in time order: frames at CAMERA_HZ, one marker at MARKER_HZ."""
    rng = np.random.default_rng(seed)
    cam = T0 + np.arange(frames, dtype=np.int64) * (1_000_000_000 // CAMERA_HZ)
    n_mark = frames * MARKER_HZ // CAMERA_HZ
    mark = T0 + np.arange(n_mark, dtype=np.int64) * (1_000_000_000 // MARKER_HZ) + 1
    xyz = rng.normal(size=(n_mark, 3))
    i = j = 0
    while i < frames or j < n_mark:
        if j >= n_mark or (i < frames and cam[i] <= mark[j]):
            yield int(cam[i]), CAMERA_TOPIC, None
            i += 1
        else:
            yield int(mark[j]), MARKER_TOPICS[0], (float(xyz[j, 0]), float(xyz[j, 1]), float(xyz[j, 2]))
            j += 1


def _msgdef(typ: str) -> bytes:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE).generate_msgdef(typ, ros_version=2)[0].encode()


def write_camera_mcap(path: Path, frames: int, seed: int) -> None:
    """Camera-heavy MCAP (mcap writer, uncompressed 4 MB chunks, summary and indexes)."""
    from mcap.writer import CompressionType, Writer

    point, image = _templates(ros1=False)
    with path.open("wb") as fh:
        w = Writer(fh, chunk_size=CHUNK_BYTES, compression=CompressionType.NONE)
        w.start(profile="ros2", library="pbd-bench")
        chans = {
            CAMERA_TOPIC: w.register_channel(CAMERA_TOPIC, "cdr", w.register_schema(IMAGE, "ros2msg", _msgdef(IMAGE))),
            MARKER_TOPICS[0]: w.register_channel(
                MARKER_TOPICS[0], "cdr", w.register_schema(POINT, "ros2msg", _msgdef(POINT))
            ),
        }
        for n, (stamp, topic, xyz) in enumerate(_camera_events(frames, seed)):
            data = _stamped(point if xyz else image, stamp, False, xyz)
            w.add_message(chans[topic], stamp, data, stamp, n)
        w.finish()  # type: ignore[no-untyped-call]


def write_camera_bag(path: Path, frames: int, seed: int) -> None:
    """Camera-heavy ROS 1 bag (rosbags rosbag1 Writer, uncompressed chunks of 4 MB)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    point, image = _templates(ros1=True)
    writer = Writer(path)
    writer.chunk_threshold = CHUNK_BYTES
    with writer:
        conns = {
            CAMERA_TOPIC: writer.add_connection(CAMERA_TOPIC, IMAGE, typestore=store),
            MARKER_TOPICS[0]: writer.add_connection(MARKER_TOPICS[0], POINT, typestore=store),
        }
        for stamp, topic, xyz in _camera_events(frames, seed):
            writer.write(conns[topic], stamp, _stamped(point if xyz else image, stamp, True, xyz))


def write_camera_rosbag2(path: Path, frames: int, seed: int) -> None:
    """Camera-heavy rosbag2 (rosbags rosbag2 Writer, sqlite3 storage)."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    point, image = _templates(ros1=False)
    with Writer(path, version=9) as writer:
        conns = {
            CAMERA_TOPIC: writer.add_connection(CAMERA_TOPIC, IMAGE, typestore=store),
            MARKER_TOPICS[0]: writer.add_connection(MARKER_TOPICS[0], POINT, typestore=store),
        }
        for stamp, topic, xyz in _camera_events(frames, seed):
            writer.write(conns[topic], stamp, _stamped(point if xyz else image, stamp, False, xyz))


def write_marker_mcap(path: Path, n: int, seed: int) -> None:
    """N PointStamped messages round-robin over MARKER_TOPICS at 360 Hz per topic, zstd chunks."""
    from mcap.writer import CompressionType, Writer

    point, _image = _templates(ros1=False)
    stamps = T0 + np.arange(n, dtype=np.int64) * (1_000_000_000 // (360 * len(MARKER_TOPICS)))
    xyz = np.random.default_rng(seed).normal(size=(n, 3))
    with path.open("wb") as fh:
        w = Writer(fh, compression=CompressionType.ZSTD)
        w.start(profile="ros2", library="pbd-bench")
        sid = w.register_schema(POINT, "ros2msg", _msgdef(POINT))
        cids = [w.register_channel(t, "cdr", sid) for t in MARKER_TOPICS]
        for i in range(n):
            s = int(stamps[i])
            data = _stamped(point, s, False, (float(xyz[i, 0]), float(xyz[i, 1]), float(xyz[i, 2])))
            w.add_message(cids[i % len(MARKER_TOPICS)], s, data, s, i)
        w.finish()  # type: ignore[no-untyped-call]


# -- measuring -------------------------------------------------------------------------------------
def measure(cmd: list[str], repeats: int) -> tuple[float, float, float, str]:
    """Best wall seconds, with that run's CPU seconds (user + system) and peak RSS (MB) of ``cmd`` as a whole
    process (``/usr/bin/time``), and its stdout. ``{TMP}`` in ``cmd`` becomes a new empty folder per run. CPU time
    is printed because the machine is shared: wall clock includes waiting for a core."""
    best = (float("inf"), 0.0, 0.0, "")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    for _ in range(repeats):
        with tempfile.TemporaryDirectory(prefix="pbd-bench-run-") as tmp:
            full = [TIME, "-f", "%e %M %U %S", *[a.replace("{TMP}", tmp) for a in cmd]]
            t0 = time.perf_counter()
            proc = subprocess.run(full, capture_output=True, text=True, check=False, env=env)
            wall = time.perf_counter() - t0
            if proc.returncode != 0:
                sys.exit(f"failed: {' '.join(full)}\n{proc.stderr[-2000:]}")
            fields = proc.stderr.strip().splitlines()[-1].split()
            rss_mb = int(fields[1]) / 1024
            cpu = float(fields[2]) + float(fields[3])
            out = proc.stdout.strip()
            if "pbd" in cmd[0]:
                out = str(_pbd_rows(Path(tmp) / "store"))
        if wall < best[0]:
            best = (wall, cpu, rss_mb, out)
    return best


def _pbd_rows(store: Path) -> int:
    import pyarrow.parquet as pq

    return sum(pq.read_metadata(p).num_rows for p in store.glob("recordings/*/markers.parquet"))


def _warm(path: Path) -> None:
    """Flush the writer's pages and read the recording once, so every tool finds it in the page cache."""
    os.sync()
    buf = bytearray(1 << 20)
    for f in sorted(path.rglob("*")) if path.is_dir() else [path]:
        if f.is_file():
            with f.open("rb", buffering=0) as fh:
                while fh.readinto(buf):
                    pass


def run_case(
    name: str, path: Path, topics: tuple[str, ...], repeats: int, tmp: Path
) -> list[tuple[str, float, float, float]]:
    """Time pbd and the baselines on one recording; print and return (tool, wall s, CPU s, peak RSS MB)."""
    size = sum(p.stat().st_size for p in path.rglob("*")) if path.is_dir() else path.stat().st_size
    _warm(path)
    rows: list[tuple[str, float, float, float, str]] = []
    rows.append(("pbd ingest", *measure([str(PBD), "ingest", str(path), "--store", "{TMP}/store"], repeats)))
    is_mcap = path.suffix == ".mcap"
    joined = ",".join(topics)
    if is_mcap:
        got = measure([str(PY), str(tmp / "mcap_reader.py"), str(path), joined], repeats)
        rows.append(("mcap make_reader + deserialize_cdr", *got))
    rows.append(
        ("rosbags AnyReader + deserialize", *measure([str(PY), str(tmp / "anyreader.py"), str(path), joined], repeats))
    )
    counts = {r[4] for r in rows}
    if len(counts) != 1:
        sys.exit(f"{name}: tools disagree on the marker rows: {[(r[0], r[4]) for r in rows]}")
    wall, cpu, rss, _ = measure([str(PY), "-c", ID_ONLY, str(path)], repeats)
    rows.append(("of pbd: the id alone (SHA-256 of bytes)", wall, cpu, rss, ""))
    wall, cpu, rss, _ = measure([str(PY), "-c", START_ONLY], repeats)
    rows.append(("of pbd: start-up alone (imports)", wall, cpu, rss, ""))
    print(f"\n{name}: {size / 1e9:.2f} GB, {counts.pop()} marker rows")
    print(f"| {'tool':<40} | {'wall s':>7} | {'CPU s':>6} | {'peak RSS MB':>11} |")
    print(f"|{'-' * 42}|{'-' * 9}|{'-' * 8}|{'-' * 13}|")
    for tool, w, c, r, _ in rows:
        print(f"| {tool:<40} | {w:7.2f} | {c:6.2f} | {r:11.0f} |")
    return [(t, w, c, r) for t, w, c, r, _ in rows]


def verdicts(name: str, rows: list[tuple[str, float, float, float]], marker_only: bool) -> None:
    """One line: the targets of issue 27 for this recording (ratios of wall clock, then of CPU time)."""
    ours = rows[0]
    peers = {t.split()[0]: (w, c) for t, w, c, _ in rows[1:] if not t.startswith("of pbd")}
    rss_ok = ours[3] < RSS_TARGET_MB

    def ratio(peer: str) -> str:
        w, c = peers[peer]
        return f"{w / ours[1]:.2f}x wall, {c / ours[2]:.2f}x CPU"

    if marker_only:
        loop = ratio("rosbags")
        print(f"{name}: peak RSS {ours[3]:.0f} MB (< {RSS_TARGET_MB}: {rss_ok}); rosbags loop / pbd: {loop} (>= 10x)")
    else:
        mcap = f"mcap reader / pbd: {ratio('mcap')} (target >= 1x); " if "mcap" in peers else ""
        print(
            f"{name}: peak RSS {ours[3]:.0f} MB (< {RSS_TARGET_MB}: {rss_ok}); {mcap}rosbags / pbd: {ratio('rosbags')}"
        )


def main() -> None:
    """Generate the recordings, time pbd and the peers on each, print the tables, delete the recordings."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="~150 MB camera files and 30,000 markers")
    parser.add_argument("--big", action="store_true", help="also the ~10 GB camera-heavy recordings")
    parser.add_argument("--repeats", type=int, default=1, help="runs per tool on the camera files (best kept)")
    parser.add_argument("--dir", type=Path, default=None, help="folder for the generated files (default: /tmp)")
    args = parser.parse_args()
    frames = 150 if args.quick else 1500
    markers = 30_000 if args.quick else 300_000
    free = shutil.disk_usage(args.dir or tempfile.gettempdir()).free
    need = 3 * frames * FRAME_BYTES * (1 + (10 if args.big else 0)) * 1.1
    if free < need:
        sys.exit(f"needs {need / 1e9:.1f} GB free for the generated recordings, {free / 1e9:.1f} GB are")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    # pbd's bytecode compiled once, as in an installed package (the peers' modules in site-packages have theirs)
    subprocess.run([str(PY), "-m", "compileall", "-q", "tasks", "flows", "schemas"], cwd=REPO, check=True)
    with tempfile.TemporaryDirectory(prefix="pbd-bench-ingest-", dir=args.dir) as tmp_s:
        tmp = Path(tmp_s)
        (tmp / "mcap_reader.py").write_text(BASELINE_MCAP)
        (tmp / "anyreader.py").write_text(BASELINE_ANYREADER)
        dev, held = "development", "held-out"
        cases = [
            (dev, "camera-heavy MCAP", "cam0.mcap", write_camera_mcap, frames, 0),
            (dev, f"marker-only {markers:,} MCAP", "markers0.mcap", write_marker_mcap, markers, 0),
            (held, "camera-heavy ROS 1 bag", "cam1.bag", write_camera_bag, frames, 1),
            (held, "camera-heavy rosbag2 sqlite3", "cam1_rosbag2", write_camera_rosbag2, frames, 1),
            (held, f"marker-only {markers:,} MCAP", "markers1.mcap", write_marker_mcap, markers, 1),
        ]
        if args.big:
            big = frames * 20 // 3
            cases += [
                (held, "camera-heavy MCAP (big)", "big.mcap", write_camera_mcap, big, 2),
                (held, "camera-heavy ROS 1 bag (big)", "big.bag", write_camera_bag, big, 2),
                (held, "camera-heavy rosbag2 (big)", "big_rosbag2", write_camera_rosbag2, big, 2),
            ]
        summary: list[str] = []
        for part, name, file, write, n, seed in cases:
            path = tmp / file
            t0 = time.perf_counter()
            write(path, n, seed)
            print(f"\n[{part}] wrote {name} (seed {seed}) in {time.perf_counter() - t0:.1f} s")
            marker_only = "marker-only" in name
            topics = MARKER_TOPICS if marker_only else MARKER_TOPICS[:1]
            rows = run_case(f"[{part}] {name}", path, topics, 3 if marker_only else args.repeats, tmp)
            verdicts(f"[{part}] {name}", rows, marker_only)
            summary.append(f"[{part}] {name}: pbd {rows[0][1]:.2f} s wall, {rows[0][2]:.2f} s CPU, {rows[0][3]:.0f} MB")
            shutil.rmtree(path) if path.is_dir() else path.unlink()
        print("\n" + "\n".join(summary))


if __name__ == "__main__":
    main()
