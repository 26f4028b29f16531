"""Read the raw messages of a recording in any container of ``../shared/RECORDING.md``.

A ``RawRecording`` lists every topic with its type, message encoding, the message definition the recording
carries, and its raw payloads as ``Batch``es (nothing is decoded here). Containers:

- standalone MCAP: our streaming reader (``mcap_stream``), memory bounded by one chunk;
- ROS 1 bag (plain, bz2, lz4): our streaming reader (``bag_stream``; definitions from connection headers);
- rosbag2 folder: ``metadata.yaml`` (storage files confined to the folder) plus sqlite3 storage
  (``rosbag2_sqlite``: topics matched by name, not by QoS, rows queried by topic) or MCAP storage (our
  reader); file or message compression (zstd) is undone; the counts read are compared with the metadata's; a
  lone ``.db3`` file reads as a one-file rosbag2 without metadata.

Only the payloads of the topics ``want`` asks for are kept; every topic is counted.
"""

from __future__ import annotations

import contextlib
import tempfile
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any

import zstandard

from tasks.errors import RecordingError, bounded
from tasks.ingest.bag_stream import read_bag
from tasks.ingest.batch import Batch
from tasks.ingest.mcap_stream import McapContent, read_mcap
from tasks.ingest.raw import RawRecording, RawTopic
from tasks.ingest.rosbag2_sqlite import read_sqlite_files
from tasks.ingest.selection import Want, keep_all, normalize_type

KNOWN_ENCODINGS = ("cdr", "ros1", "json")


def container_of(path: Path) -> str:
    """``mcap``, ``bag``, ``rosbag2`` or ``db3``, from the path and the first bytes; raises RecordingError."""
    if path.is_dir():
        return "rosbag2"
    if not path.exists():
        raise RecordingError(path, "no such file or folder")
    with path.open("rb") as fh:
        head = fh.read(16)
    if not head:
        raise RecordingError(path, "empty file (0 bytes)")
    if head.startswith(b"\x89MCAP"):
        return "mcap"
    if head.startswith(b"#ROSBAG V2.0"):
        return "bag"
    if head.startswith(b"#ROSBAG"):
        return "bag"
    if head.startswith(b"SQLite format 3"):
        return "db3"
    suffix = path.suffix.lower()
    what = "not a recording" + (f" (a {suffix} file without the {suffix[1:]} magic)" if suffix else "")
    raise RecordingError(path, what)


def read_recording(path: Path, *, recover: bool = False, want: Want = keep_all) -> RawRecording:
    """Every topic of the recording at ``path`` with its message count, and the raw messages of the topics
    ``want`` asks for; raises ``RecordingError`` on bad input."""
    kind = container_of(path)
    if kind == "mcap":
        return _read_mcap_file(path, recover, want)
    if kind == "bag":
        return _read_bag(path, recover, want)
    if kind == "db3":
        return read_sqlite_files(path, [path], recover, want)
    return _read_rosbag2(path, recover, want)


# -- MCAP -------------------------------------------------------------------------------------------
def _topics_from_mcap(content: McapContent, path: Path, topics: dict[str, RawTopic], encoding_hint: str) -> None:
    for cid, ch in sorted(content.channels.items()):
        schema = content.schemas.get(ch.schema_id)
        msgtype = normalize_type(schema.name) if schema else ""
        enc = ch.message_encoding or encoding_hint
        topic = topics.get(ch.topic)
        if topic is None:
            topic = RawTopic(
                ch.topic,
                msgtype,
                enc,
                schema.encoding if schema else "",
                schema.data.decode("utf-8", errors="replace") if schema else "",
            )
            topics[ch.topic] = topic
        elif topic.msgtype != msgtype:
            msg = f"two channels with types {topic.msgtype} and {msgtype}"
            raise RecordingError(path, msg, ch.topic)
        topic.batches.extend(content.batches.get(cid, []))
        topic.seen += content.counts.get(cid, 0)
    orphans = set(content.counts) - set(content.channels)
    if orphans:
        msg = f"messages on channel id {min(orphans)} which the file never defines"
        raise RecordingError(path, msg)


def _read_mcap_file(path: Path, recover: bool, want: Want) -> RawRecording:
    content = read_mcap(path, recover=recover, want=want)
    topics: dict[str, RawTopic] = {}
    _topics_from_mcap(content, path, topics, "")
    rec = RawRecording(path, "mcap", topics, log_range=content.log_range)
    if content.damage is not None:
        rec.lost_messages = content.lost_messages
        past = "the damage is past the data section"
        basis = (
            "the cut chunk's size in its header over the mean message size"
            if content.cut_chunk is not None
            else "the record the damage cut"
        )
        rec.warnings.append(
            _recovery_warning(rec, content.damage, past_data=content.past_data, past=past, estimated=False, basis=basis)
        )
    return rec


def _recovery_warning(
    rec: RawRecording, damage: str, *, past_data: bool, past: str, estimated: bool, basis: str
) -> str:
    """The ``--recover`` warning: what was wrong and where, what was kept, and what was lost: ``estimated``
    (from ``basis``, what the file says) or a lower bound; ``past`` says where damage that cost nothing lies."""
    kept = rec.message_count
    if past_data:
        return f"{rec.path}: {damage}; recovered all {kept} messages ({past})"
    if estimated:
        return (
            f"{rec.path}: {damage}; recovered {kept} messages, lost about {rec.lost_messages} (estimated from {basis})"
        )
    return (
        f"{rec.path}: {damage}; recovered {kept} messages, lost at least {rec.lost_messages} "
        f"(a lower bound: {basis}; what was recorded after the damage cannot be counted)"
    )


# -- ROS 1 bag --------------------------------------------------------------------------------------
def _read_bag(path: Path, recover: bool, want: Want) -> RawRecording:
    content = read_bag(path, recover=recover, want=want)
    topics: dict[str, RawTopic] = {}
    for cid, conn in sorted(content.connections.items()):
        topic = topics.get(conn.topic)
        if topic is None:
            topic = RawTopic(conn.topic, conn.msgtype, "ros1", "ros1msg", conn.msgdef)
            topics[conn.topic] = topic
        elif topic.msgtype != conn.msgtype:
            msg = f"two connections with types {topic.msgtype} and {conn.msgtype}"
            raise RecordingError(path, msg, conn.topic)
        batch = content.batch(cid)
        if batch is not None:
            topic.batches.append(batch)
        topic.seen += content.counts.get(cid, 0)
    log_range = None if content.log_lo is None or content.log_hi is None else (content.log_lo, content.log_hi)
    rec = RawRecording(path, "bag", topics, log_range=log_range)
    if content.damage is not None:
        rec.lost_messages = content.lost_messages
        past = "the damage is past the last chunk, in the index"
        if content.lost_estimated:
            basis = f"the bytes up to the index at byte {content.index_pos} the bag header gives"
        else:
            basis = "the cut chunk's size in its header over the mean message size, one per chunk never reached"
        rec.warnings.append(
            _recovery_warning(
                rec,
                content.damage,
                past_data=content.past_data,
                past=past,
                estimated=content.lost_estimated,
                basis=basis,
            )
        )
    return rec


# -- rosbag2 ----------------------------------------------------------------------------------------
def _metadata(path: Path) -> dict[str, Any]:
    import yaml  # noqa: PLC0415 (imported on first use: only for rosbag2 folders)

    meta_path = path / "metadata.yaml"
    if not meta_path.is_file():
        files = sorted(p.name for p in path.iterdir()) if path.is_dir() else []
        hint = "; ingest its storage files one by one" if any(f.endswith((".db3", ".mcap")) for f in files) else ""
        msg = f"not a recording (a folder without metadata.yaml{hint})"
        raise RecordingError(path, msg)
    try:
        doc = yaml.safe_load(meta_path.read_text())
    except (OSError, yaml.YAMLError) as err:
        msg = f"unreadable metadata.yaml ({err})"
        raise RecordingError(meta_path, msg) from err
    info = doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    if not isinstance(info, dict):
        raise RecordingError(meta_path, "not a rosbag2 metadata file (no rosbag2_bagfile_information)")
    return info


def _storage_files(path: Path, rel: list[Any]) -> list[Path]:
    """The storage files metadata.yaml lists, each confined to the bag folder: an absolute path, a ``..`` or a
    symbolic link leading out of the folder is refused (``RecordingError``)."""
    root = path.resolve()
    meta_path = path / "metadata.yaml"
    files: list[Path] = []
    for r in rel:
        text = str(r)
        shown = text if len(text) <= 80 else text[:77] + "..."
        pure = PurePosixPath(text)
        if pure.is_absolute() or PureWindowsPath(text).is_absolute() or ".." in pure.parts or "\x00" in text:
            msg = f"storage path {shown!r} leaves the bag folder (absolute and '..' paths are refused)"
            raise RecordingError(meta_path, msg)
        f = path / pure
        try:
            if not f.is_file() and (path / pure.name).is_file():
                f = path / pure.name  # old metadata lists paths with the folder name
            missing = not f.is_file()
            outside = not missing and not f.resolve().is_relative_to(root)
        except (OSError, RuntimeError) as err:  # a name too long, a link loop
            msg = f"storage file {shown} listed in metadata.yaml cannot be opened ({err})"
            raise RecordingError(meta_path, msg) from err
        if missing:
            msg = f"storage file {shown} listed in metadata.yaml is missing"
            raise RecordingError(path, msg)
        if outside:
            msg = f"storage file {shown} is a link leading out of the bag folder (refused)"
            raise RecordingError(meta_path, msg)
        files.append(f)
    return files


def _expected_counts(info: dict[str, Any]) -> dict[str, tuple[str, str, int]]:
    """(type, serialization format, message count) per topic, from metadata.yaml."""
    expected: dict[str, tuple[str, str, int]] = {}
    for entry in info.get("topics_with_message_count") or []:
        meta = entry.get("topic_metadata") or entry.get("topic_and_type") or {}
        name = str(meta.get("name", ""))
        expected[name] = (
            normalize_type(str(meta.get("type", ""))),
            str(meta.get("serialization_format", "cdr")),
            int(entry.get("message_count", 0)),
        )
    return expected


def _read_rosbag2(path: Path, recover: bool, want: Want) -> RawRecording:
    info = _metadata(path)
    try:
        storage = str(info.get("storage_identifier", ""))
        rel = info.get("relative_file_paths") or [f.get("path") for f in info.get("files") or []]
        rel = [r for r in rel if r] if isinstance(rel, list) else [rel]
        expected = _expected_counts(info)
        mode = str(info.get("compression_mode", "") or "").upper()
        fmt = str(info.get("compression_format", "") or "")
    except (AttributeError, TypeError, ValueError, OverflowError) as err:
        msg = f"malformed metadata.yaml ({type(err).__name__}: {str(err)[:80]})"
        raise RecordingError(path / "metadata.yaml", msg) from err
    files = _storage_files(path, rel)
    if not files:
        raise RecordingError(path, "empty: metadata.yaml lists no storage files")
    if mode and fmt and fmt != "zstd":
        msg = f"unknown compression format {fmt[:40]!r}"
        raise RecordingError(path, msg)
    with contextlib.ExitStack() as stack:
        plain: list[Path] = []
        for f in files:
            if mode == "FILE" or f.suffix == ".zstd":
                tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="pbd-ingest-")))
                out = tmp / f.name.removesuffix(".zstd")
                _unzstd_file(f, out)
                plain.append(out)
            else:
                plain.append(f)
        if storage == "mcap" or all(p.suffix == ".mcap" for p in plain):
            rec = _read_rosbag2_mcap(path, plain, recover, want)
        elif storage in ("sqlite3", "") or all(p.suffix == ".db3" for p in plain):
            rec = read_sqlite_files(path, plain, recover, want)
        else:
            msg = f"unknown rosbag2 storage {storage[:40]!r}"
            raise RecordingError(path, msg)
    rec.container = "rosbag2"
    if expected:  # metadata.yaml counts every topic: the loss is exact, not the storage reader's estimate
        rec.lost_messages = 0
    short: list[str] = []
    for name, (msgtype, fmt_, count) in expected.items():
        topic = rec.topics.get(name)
        if topic is None:
            topic = RawTopic(name, msgtype, fmt_, "", "")
            rec.topics[name] = topic
        topic.expected = count
        if mode == "MESSAGE":
            topic.batches = [_unzstd_batch(b, path) for b in topic.batches]
        if topic.count < count:
            msg = f"metadata.yaml promises {count} messages, the storage holds {topic.count}"
            if not recover:
                raise RecordingError(path, msg, name)
            rec.lost_messages += count - topic.count
            short.append(f"{name} lost {count - topic.count} of {count}")
    if short:
        rec.warnings.append(f"{path}: {bounded(short)} (exact: metadata.yaml counts every topic)")
    return rec


def _unzstd_file(src: Path, out: Path) -> None:
    """Decompress a zstd storage file to ``out`` in a stream (memory holds one block, not the file)."""
    try:
        with src.open("rb") as fin, out.open("wb") as fout:
            zstandard.ZstdDecompressor().copy_stream(fin, fout)
    except zstandard.ZstdError as err:
        msg = f"zstd data does not decompress ({err})"
        raise RecordingError(src, msg) from err


def _unzstd(data: bytes, where: Path) -> bytes:
    try:
        return bytes(zstandard.ZstdDecompressor().decompressobj().decompress(data))
    except zstandard.ZstdError as err:
        msg = f"zstd data does not decompress ({err})"
        raise RecordingError(where, msg) from err


def _unzstd_batch(batch: Batch, where: Path) -> Batch:
    payloads = [_unzstd(bytes(batch.payload(i)), where) for i in range(len(batch))]
    return Batch.from_payloads(payloads, batch.log_ns.tolist())


def _read_rosbag2_mcap(path: Path, files: list[Path], recover: bool, want: Want) -> RawRecording:
    topics: dict[str, RawTopic] = {}
    rec = RawRecording(path, "rosbag2", topics)
    for f in files:
        content = read_mcap(f, recover=recover, want=want)
        _topics_from_mcap(content, f, topics, "cdr")
        if content.log_range is not None:
            lo, hi = content.log_range
            rec.log_range = (
                (lo, hi) if rec.log_range is None else (min(rec.log_range[0], lo), max(rec.log_range[1], hi))
            )
        if content.damage is not None:
            rec.warnings.append(f"{f}: {content.damage}")
            rec.lost_messages += content.lost_messages  # replaced by the exact loss where metadata.yaml counts
    return rec
