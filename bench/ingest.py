"""Benchmark ``pbd ingest`` against the per-message loop a user would write.

Writes an MCAP of N ``geometry_msgs/PointStamped`` messages (ROS 2 CDR, zstd chunks, 4 marker topics,
written with ``mcap.writer.Writer``; payloads checked byte for byte against ``rosbags`` ``serialize_cdr``)
into a temporary folder, then times whole processes (wall clock, best of 3):

- ``pbd ingest FILE --store NEW_TMP_STORE``
- baseline A: ``rosbags.highlevel.AnyReader`` + ``deserialize`` per message, rows into lists, pyarrow Parquet
- baseline B: ``mcap.reader`` ``iter_messages`` + ``typestore.deserialize_cdr`` per message, same output

Both baselines and pbd write the same rows (marker, stamp_ns, x, y, z). Usage::

    .venv/bin/python bench/ingest.py            # 300,000 messages
    .venv/bin/python bench/ingest.py --quick    # 30,000 messages
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
PY = REPO / ".venv" / "bin" / "python"
PBD = REPO / ".venv" / "bin" / "pbd"
TOPICS = ("/mocap/m0", "/mocap/m1", "/mocap/m2", "/mocap/m3")

BASELINE_ANYREADER = """
import sys
from pathlib import Path
import pyarrow as pa, pyarrow.parquet as pq
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

rows = {"marker": [], "stamp_ns": [], "x": [], "y": [], "z": []}
with AnyReader([Path(sys.argv[1])], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
    for conn, _t, raw in reader.messages():
        msg = reader.deserialize(raw, conn.msgtype)
        rows["marker"].append(conn.topic)
        rows["stamp_ns"].append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        rows["x"].append(msg.point.x)
        rows["y"].append(msg.point.y)
        rows["z"].append(msg.point.z)
table = pa.table(rows).sort_by([("marker", "ascending"), ("stamp_ns", "ascending")])
pq.write_table(table, sys.argv[2])
print(table.num_rows)
"""

BASELINE_MCAP = """
import sys
import pyarrow as pa, pyarrow.parquet as pq
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore

typestore = get_typestore(Stores.ROS2_HUMBLE)
rows = {"marker": [], "stamp_ns": [], "x": [], "y": [], "z": []}
with open(sys.argv[1], "rb") as fh:
    for schema, channel, message in make_reader(fh).iter_messages():
        msg = typestore.deserialize_cdr(message.data, "geometry_msgs/msg/PointStamped")
        rows["marker"].append(channel.topic)
        rows["stamp_ns"].append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        rows["x"].append(msg.point.x)
        rows["y"].append(msg.point.y)
        rows["z"].append(msg.point.z)
table = pa.table(rows).sort_by([("marker", "ascending"), ("stamp_ns", "ascending")])
pq.write_table(table, sys.argv[2])
print(table.num_rows)
"""


def write_mcap(path: Path, n: int) -> None:
    """N PointStamped messages round-robin over TOPICS at 360 Hz per topic, zstd chunks."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    msgtype = "geometry_msgs/msg/PointStamped"
    frame = b"world\x00"
    t0 = 1_700_000_000_000_000_000
    stamps = t0 + np.arange(n, dtype=np.int64) * (1_000_000_000 // (360 * len(TOPICS)))
    xyz = np.random.default_rng(0).normal(size=(n, 3))
    # CDR layout: encapsulation, sec, nanosec, frame id (len incl. NUL), pad to 8 (from after encapsulation), xyz
    head_len = 4 + 4 + 4 + 4 + len(frame)
    pad = (-(head_len - 4)) % 8
    payload = np.zeros((n, head_len + pad + 24), dtype=np.uint8)
    payload[:, 1] = 1
    payload[:, 4:8] = (stamps // 1_000_000_000).astype("<i4").view(np.uint8).reshape(n, 4)
    payload[:, 8:12] = (stamps % 1_000_000_000).astype("<u4").view(np.uint8).reshape(n, 4)
    payload[:, 12:16] = np.array([len(frame)], dtype="<u4").view(np.uint8)
    payload[:, 16 : 16 + len(frame)] = np.frombuffer(frame, dtype=np.uint8)
    payload[:, head_len + pad :] = xyz.astype("<f8").view(np.uint8).reshape(n, 24)
    Msg = store.types[msgtype]
    for i in range(3):  # our bytes are exactly what the rosbags serializer writes
        sec, nsec = divmod(int(stamps[i]), 1_000_000_000)
        header = store.types["std_msgs/msg/Header"](
            stamp=store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id="world"
        )
        point = store.types["geometry_msgs/msg/Point"](x=xyz[i, 0], y=xyz[i, 1], z=xyz[i, 2])
        ref = bytes(store.serialize_cdr(Msg(header=header, point=point), msgtype))
        assert ref == payload[i].tobytes(), "hand-built CDR differs from rosbags serialize_cdr"
    msgdef, _ = store.generate_msgdef(msgtype, ros_version=2)
    with path.open("wb") as fh:
        writer = Writer(fh, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="pbd-bench")
        sid = writer.register_schema("geometry_msgs/msg/PointStamped", "ros2msg", msgdef.encode())
        cids = [writer.register_channel(t, "cdr", sid) for t in TOPICS]
        rows = payload.tobytes()
        size = payload.shape[1]
        for i in range(n):
            t = int(stamps[i])
            writer.add_message(cids[i % len(TOPICS)], t, rows[i * size : (i + 1) * size], t, i)
        writer.finish()


def timed(cmd: list[str], repeats: int, fresh: list[str] | None = None) -> tuple[float, float, str]:
    """Best wall-clock and best CPU (user + sys) seconds of ``repeats`` runs of ``cmd``.

    ``fresh``: arguments appended with ``{TMP}`` replaced by a new temporary folder for each run (so every
    ``pbd ingest`` writes into an empty store). CPU time is reported too because the machine is shared:
    wall clock includes waiting for a core, CPU time does not.
    """
    best = float("inf")
    best_cpu = float("inf")
    out = ""
    for _ in range(repeats):
        with tempfile.TemporaryDirectory(prefix="pbd-bench-") as tmp:
            full = cmd + ([a.replace("{TMP}", tmp) for a in fresh] if fresh else [])
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            proc = subprocess.run(full, capture_output=True, text=True, check=False)
            dt = time.perf_counter() - t0
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if proc.returncode != 0:
            sys.exit(f"failed: {' '.join(full)}\n{proc.stderr}")
        best = min(best, dt)
        best_cpu = min(best_cpu, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime))
        out = proc.stdout.strip()
    return best, best_cpu, out


def main() -> None:
    """Write the MCAP, time pbd ingest and both baselines, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="30,000 messages instead of 300,000")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    n = 30_000 if args.quick else 300_000
    with tempfile.TemporaryDirectory(prefix="pbd-bench-ingest-") as tmp_s:
        tmp = Path(tmp_s)
        mcap = tmp / "points.mcap"
        t0 = time.perf_counter()
        write_mcap(mcap, n)
        print(
            f"wrote {n:,} PointStamped ({mcap.stat().st_size / 1e6:.1f} MB, zstd) in {time.perf_counter() - t0:.1f} s"
        )
        (tmp / "a.py").write_text(BASELINE_ANYREADER)
        (tmp / "b.py").write_text(BASELINE_MCAP)
        ours, ours_cpu, ours_out = timed([str(PBD), "ingest", str(mcap), "--store"], args.repeats, ["{TMP}/store"])
        base_a, cpu_a, rows_a = timed([str(PY), str(tmp / "a.py"), str(mcap)], args.repeats, ["{TMP}/out.parquet"])
        base_b, cpu_b, rows_b = timed([str(PY), str(tmp / "b.py"), str(mcap)], args.repeats, ["{TMP}/out.parquet"])
        if int(rows_a) != n or int(rows_b) != n:
            sys.exit(f"baselines wrote {rows_a} / {rows_b} rows, expected {n}")
        load = os.getloadavg()[0]
        print(f"pbd ingest printed recording id {ours_out}; load average {load:.1f} on {os.cpu_count()} cores")
        print()
        head = f"process ({n:,} PointStamped, best of {args.repeats})"
        print(f"| {head:<58} | {'wall s':>7} | {'CPU s':>6} | {'msgs/s (wall)':>13} |")
        print(f"|{'-' * 60}|{'-' * 9}|{'-' * 8}|{'-' * 15}|")
        for name, sec, cpu in (
            ("pbd ingest (bulk numpy decode)", ours, ours_cpu),
            ("baseline A: rosbags AnyReader + deserialize per message", base_a, cpu_a),
            ("baseline B: mcap reader + deserialize_cdr per message", base_b, cpu_b),
        ):
            print(f"| {name:<58} | {sec:7.2f} | {cpu:6.2f} | {n / sec:13,.0f} |")
        print()
        print(
            f"speed-up over the faster baseline: {min(base_a, base_b) / ours:.1f}x wall clock, "
            f"{min(cpu_a, cpu_b) / ours_cpu:.1f}x CPU time (target >= 5x, aim 20x)"
        )
        print(f"wall clock: {base_a / ours:.1f}x over baseline A, {base_b / ours:.1f}x over baseline B")


if __name__ == "__main__":
    main()
