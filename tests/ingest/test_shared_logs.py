"""Ingest every real log under ../shared/logs and compare with what the reference readers saw (EXPECTED-*.jsonl).

For every line: topics, types and counts (and the log-time span) must match. Where the reference readers
(rosbags 0.11.9, mcap 1.6) raised an error or returned too little, ``OUTCOME`` says what we do instead:
``"data"`` = we read it and the counts are checked against the storage itself (sqlite3 tables, the MCAP
stream, metadata.yaml); ``"error: <regex>"`` = a clean ``RecordingError`` whose message matches. The
``_derived/`` files of EXPECTED-realworld are re-made here exactly as described (cut at 50/60/70 %, footer
removed) from the shared originals.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest
import yaml

from tasks.errors import RecordingError
from tasks.ingest.api import ingest_recording
from tasks.ingest.containers import read_recording
from tasks.ingest.selection import normalize_type
from tasks.store import Store
from tests.conftest import LOGS

# Paths where the reference readers failed or under-read, and what we do instead (see the module doc).
OUTCOME: dict[str, str] = {
    # reference: AnyReaderError "seems to be empty"
    "foxglove_rosbag/empty-file.bag": r"error: empty file \(0 bytes\)",
    # reference: no topics (no messages): we refuse an empty recording
    "foxglove_rosbag/no-messages.bag": "error: empty: no messages",
    "cnspy_rosbag2csv/empty_bag.bag": "error: empty: no messages",
    "HEAD/ros2bag/test/resources/empty_bag": "error: empty: no messages",
    "history/rosbag2_tests/resources/compressed_bag": "error: empty: no messages",
    # protobuf is not an encoding RECORDING.md lists: alone it is an error, next to JSON it is skipped
    "rerun/foxglove_log.mcap": "error: unknown message encoding 'protobuf'",
    "rerun/simple_protobuf_vec3.mcap": "error: unknown message encoding 'protobuf'",
    "rerun/simple-protobuf.mcap": "data",
    "lichtblick/example.mcap": "data",
    "mcap/testdata/db3/chatter.db3": "data",  # a lone rosbag2 sqlite3 file
    # rosbags: "Serialization format {'wrong_format'} is not supported" (mcap storage: the channels say so)
    "HEAD/rosbag2_tests/resources/mcap/wrong_rmw_test": "error: unknown message encoding 'wrong_format'",
    # sqlite3 storage: metadata.yaml says wrong_format but the topics table (the data) says cdr: we read it
    "HEAD/rosbag2_tests/resources/sqlite3/wrong_rmw_test": "data",
    "history/rosbag2_tests/resources/wrong_rmw_test": "error: unknown message encoding 'wrong_format'",
    # rosbags: "A metadata key is missing" (version 1 metadata uses topic_and_type): we read it
    "history/rosbag2_tests/resources/cdr_test": "data",
    "history/rosbag2_tests/resources/test": "data",
    # rosbags: cannot parse the service-event schema: we skip service events (warning) and read the topics
    "HEAD/rosbag2_tests/resources/mcap/bag_with_topics_and_service_events": "data",
    "HEAD/rosbag2_tests/resources/sqlite3/bag_with_topics_and_service_events": "data",
    # _derived: damaged copies
    "_derived/example-lz4.trunc50.bag": r"error: truncated at byte \d+",
    "_derived/tf_example.trunc60.bag": r"error: truncated at byte \d+",
    "_derived/nav2_turtlebot.nofooter.mcap": r"error: truncated at byte 505358 \(no footer\)",
    "_derived/nav2_turtlebot.trunc50.mcap": r"error: truncated at byte \d+",
    "_derived/simple-protobuf.trunc70.mcap": r"error: truncated at byte \d+",
    "_derived/tf_example.trunc50.db3": "error: corrupt sqlite3 storage",
}
FOLDER_WITHOUT_METADATA = "error: not a recording \\(a folder without metadata.yaml"
DERIVED = {
    "_derived/example-lz4.trunc50.bag": ("foxglove_rosbag/example-lz4.bag", 0.5),
    "_derived/tf_example.trunc60.bag": ("evo/test/data/tf_example.bag", 0.6),
    "_derived/nav2_turtlebot.trunc50.mcap": ("evo/test/data/nav2_turtlebot.mcap", 0.5),
    "_derived/simple-protobuf.trunc70.mcap": ("rerun/simple-protobuf.mcap", 0.7),
    "_derived/tf_example.trunc50.db3": ("evo/test/data/tf_example/tf_example.db3", 0.5),
    "_derived/nav2_turtlebot.nofooter.mcap": ("evo/test/data/nav2_turtlebot.mcap", -37),
}


MISSING = (
    None
    if LOGS.is_dir()
    else f"{LOGS}: the shared real logs are needed here (clone pbd beside ../shared, or set PBD_SHARED)"
)
"""Why the shared logs cannot be read, if they cannot: ``test_shared_logs_are_present`` fails with it, and the rest
of the suite still runs (a collection error would stop every test)."""


def _lines() -> list[tuple[str, dict[str, Any]]]:
    if MISSING is not None:
        return []
    out = []
    for name in ("EXPECTED-realworld.jsonl", "EXPECTED-rosbag2-conformance.jsonl"):
        for line in (LOGS / name).read_text().splitlines():
            d = json.loads(line)
            out.append((name, d))
    return out


LINES = _lines()


def _source(expected_file: str, d: dict[str, Any], tmp: Path) -> Path:
    p = d["path"]
    if p in DERIVED:
        src, cut = DERIVED[p]
        data = (LOGS / src).read_bytes()
        n = len(data) + cut if cut < 0 else int(len(data) * cut)
        out = tmp / Path(p).name
        out.write_bytes(data[:n])
        assert n == d["size"]
        return out
    if expected_file == "EXPECTED-realworld.jsonl":
        return LOGS / p
    return LOGS / ("mcap/conformance" if d["kind"] == "mcap" else "rosbag2") / p


def _truth(d: dict[str, Any], source: Path) -> tuple[dict[str, int], tuple[int, int] | None]:
    """Counts per topic and log-time span the storage itself holds, from the EXPECTED line.

    rosbags' counts, raised to what the sqlite3 tables / metadata.yaml hold where rosbags read fewer
    (QoS mismatch between metadata and data: rosbags silently returns no messages there).
    """
    ref = d.get("rosbags") or {}
    counts: dict[str, int] = {}
    span = None
    if d["kind"] == "mcap":
        topics = d.get("topics") or {}
        counts = {k: v["count"] for k, v in topics.items()}
        if d.get("time"):
            span = (d["time"]["start_ns"], d["time"]["end_ns"])
        return counts, span
    if "topics" in ref:
        counts = {k: v["count"] for k, v in ref["topics"].items()}
        if ref.get("time"):
            span = (ref["time"]["start_ns"], ref["time"]["end_ns"])
    sqlite = d.get("sqlite") or {}
    if "tables" in sqlite:  # a lone .db3 file
        sqlite = {source.name: sqlite}
    if source.is_dir() and (source / "metadata.yaml").is_file():  # only the storage files the bag lists
        info = yaml.safe_load((source / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        listed = {Path(r).name for r in info.get("relative_file_paths") or []}
        sqlite = {k: v for k, v in sqlite.items() if k in listed}
    if sqlite and all("topics" in v for v in sqlite.values()):
        sq: dict[str, int] = {}
        for v in sqlite.values():
            for k, t in v["topics"].items():
                sq[k] = sq.get(k, 0) + t["count"]
        if sum(sq.values()) > sum(counts.values()):
            counts = sq
            times = [v["time"] for v in sqlite.values() if v.get("time")]
            span = (min(t["start_ns"] for t in times), max(t["end_ns"] for t in times)) if times else None
    if source.is_dir() and (source / "metadata.yaml").is_file() and sum(counts.values()) == 0:
        info = yaml.safe_load((source / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        for e in info.get("topics_with_message_count") or []:
            meta = e.get("topic_metadata") or e.get("topic_and_type")
            counts[meta["name"]] = e["message_count"]
        span = None  # the reference saw no messages, so it has no time span to compare
    return counts, span


def _outcome(d: dict[str, Any], source: Path) -> str:
    p = d["path"]
    if p in OUTCOME:
        return OUTCOME[p]
    err = str((d.get("rosbags") or {}).get("error", ""))
    if source.is_dir() and not (source / "metadata.yaml").is_file():
        assert "Expected metadata file" in err
        return FOLDER_WITHOUT_METADATA
    if d["kind"] == "mcap" and "conformance" in str(source):  # schema encoding "c", message encoding "a"
        return "error: unknown message encoding 'a'" if d.get("stream_total_msgs") else "error: empty: no messages"
    assert not err, f"unexpected reference error without an OUTCOME entry: {err}"
    return "data"


def test_shared_logs_are_present() -> None:
    """The shared real logs are the ingest contract; without them nothing below checks it."""
    assert MISSING is None, MISSING
    assert len(LINES) > 100


@pytest.mark.parametrize(("expected_file", "d"), LINES, ids=[d["path"] for _, d in LINES])
def test_shared_log(expected_file: str, d: dict[str, Any], store: Store, tmp_path: Path) -> None:
    """Ingest one shared log: same topics, types, counts and span as the reference, or the clean error."""
    source = _source(expected_file, d, tmp_path)
    outcome = _outcome(d, source)
    if outcome.startswith("error: "):
        with pytest.raises(RecordingError, match=outcome.removeprefix("error: ")) as info:
            ingest_recording(source, store)
        assert str(source) in str(info.value)
        assert not store.recordings_dir.exists() or not any(store.recordings_dir.iterdir())
        assert not store.tmp_dir.exists() or not any(store.tmp_dir.iterdir())
        if d["kind"] == "mcap" and d.get("stream_total_msgs"):
            # the container itself reads fine: every message of the stream is there (even where the
            # summary lacks channels and a seeking reader fails, the "-chx" files without "-rch")
            raw = read_recording(source)
            assert raw.message_count == d["stream_total_msgs"]
            for name, t in (d.get("topics") or {}).items():
                assert raw.topics[name].count == t["count"]
        return
    counts, span = _truth(d, source)
    result = ingest_recording(source, store)
    info = json.loads((result.folder / "recording.json").read_text())
    got = {t["name"]: t["count"] for t in info["topics"]}
    if d["kind"] == "mcap":  # the reference lists the channels that have messages; we list every channel
        got = {k: v for k, v in got.items() if v}
    assert got == counts
    ref_topics = (d.get("rosbags") or {}).get("topics") or d.get("topics") or {}
    types = {t["name"]: t["type"] for t in info["topics"]}
    for name, t in ref_topics.items():
        assert types[name] == normalize_type(t["type"])
    if span is not None:
        assert (info["log_start_ns"], info["log_end_ns"]) == span
    assert info["id"] == result.recording_id
    assert info["schema_version"] == 1
    again = ingest_recording(source, store)
    assert (again.recording_id, again.created) == (result.recording_id, False)
    skipped = [w for w in result.warnings if "skipped" in w]
    if "service_events" in d["path"]:
        assert len(skipped) == 2
        assert all(re.search(r"_service_event: skipped \(service events", w) for w in skipped)
