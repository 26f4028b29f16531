"""Read the raw messages of a recording in any container of ``../shared/RECORDING.md``.

A ``RawRecording`` lists every topic with its type, message encoding, the message definition the recording
carries, and its raw payloads as ``Batch``es (nothing is decoded here). Containers:

- standalone MCAP: our streaming reader (``mcap_stream``), no seeking;
- ROS 1 bag (plain, bz2, lz4): ``rosbags.rosbag1.Reader`` (raw bytes, definitions from connection headers),
  after checking the bag is not cut short (its index sits at the end);
- rosbag2 folder: ``metadata.yaml`` plus sqlite3 storage (read with ``sqlite3`` directly, topics matched by
  name, not by QoS) or MCAP storage (our reader); file or message compression (zstd) is undone; the counts
  read are compared with the metadata's; a lone ``.db3`` file reads as a one-file rosbag2 without metadata.
"""

from __future__ import annotations

import contextlib
import sqlite3
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
import zstandard

from tasks.errors import RecordingError
from tasks.ingest.bag_stream import read_bag
from tasks.ingest.mcap_stream import Batch, McapContent, read_mcap

KNOWN_ENCODINGS = ("cdr", "ros1", "json")


def normalize_type(name: str) -> str:
    """``pkg/Type`` or ``pkg/msg/Type`` -> ``pkg/msg/Type`` (ROS 2 style); other names unchanged."""
    parts = [p for p in name.replace("::", "/").split("/") if p]
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return "/".join(parts) if parts else name


@dataclass
class RawTopic:
    """One topic's raw messages.

    ``encoding``: message encoding (``cdr``, ``ros1``, ``json``, or what the file says);
    ``schema_encoding``/``schema``: the message definition carried by the recording (``ros2msg``,
    ``ros2idl``, ``ros1msg``, ``jsonschema``; empty when the recording has none).
    """

    name: str
    msgtype: str
    encoding: str
    schema_encoding: str
    schema: str
    batches: list[Batch] = field(default_factory=list)
    expected: int | None = None
    """Message count promised by the container's metadata (rosbag2 ``metadata.yaml``), if any."""

    @property
    def count(self) -> int:
        """Messages read."""
        return sum(len(b) for b in self.batches)


@dataclass
class RawRecording:
    """A recording's topics and raw messages, plus what was lost to damage (``--recover``)."""

    path: Path
    container: str
    topics: dict[str, RawTopic]
    lost_messages: int = 0
    warnings: list[str] = field(default_factory=list)

    @property
    def message_count(self) -> int:
        """Messages read over all topics."""
        return sum(t.count for t in self.topics.values())


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


def read_recording(path: Path, *, recover: bool = False) -> RawRecording:
    """All topics and raw messages of the recording at ``path``; raises ``RecordingError`` on bad input."""
    kind = container_of(path)
    if kind == "mcap":
        return _read_mcap_file(path, recover)
    if kind == "bag":
        return _read_bag(path, recover)
    if kind == "db3":
        return _read_rosbag2_files(path, [path], recover)
    return _read_rosbag2(path, recover)


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
    orphans = set(content.batches) - set(content.channels)
    if orphans:
        msg = f"messages on channel id {min(orphans)} which the file never defines"
        raise RecordingError(path, msg)


def _read_mcap_file(path: Path, recover: bool) -> RawRecording:
    data = path.read_bytes()
    content = read_mcap(data, str(path), recover=recover)
    topics: dict[str, RawTopic] = {}
    _topics_from_mcap(content, path, topics, "")
    rec = RawRecording(path, "mcap", topics)
    if content.damage is not None:
        rec.lost_messages = content.lost_messages
        past = "the damage is past the data section"
        rec.warnings.append(
            _recovery_warning(rec, content.damage, content.damage_offset, past_data=content.past_data, past=past)
        )
    return rec


def _recovery_warning(
    rec: RawRecording, damage: str, offset: int | None, *, past_data: bool, past: str, detail: str = ""
) -> str:
    """The ``--recover`` warning: what was wrong, what was kept and (a lower bound of) what was lost; ``past``
    says where damage that cost nothing lies, ``detail`` adds to the loss."""
    kept = rec.message_count
    if past_data:
        return f"{rec.path}: {damage}; recovered all {kept} messages ({past})"
    return (
        f"{rec.path}: {damage}; recovered {kept} messages before byte {offset}, lost at least {rec.lost_messages} "
        f"(estimated; whatever was recorded after the damage cannot be counted{detail})"
    )


# -- ROS 1 bag --------------------------------------------------------------------------------------
def _read_bag(path: Path, recover: bool) -> RawRecording:
    content = read_bag(path.read_bytes(), str(path), recover=recover)
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
    rec = RawRecording(path, "bag", topics)
    if content.damage is not None:
        rec.lost_messages = content.lost_messages
        past = "the damage is past the last chunk, in the index"
        announced = (
            f"; the bag header announces {content.chunk_count} chunks, {content.chunks_read} were read whole"
            if content.chunk_count
            else ""
        )
        rec.warnings.append(
            _recovery_warning(
                rec, content.damage, content.damage_offset, past_data=content.past_data, past=past, detail=announced
            )
        )
    return rec


# -- rosbag2 ----------------------------------------------------------------------------------------
def _metadata(path: Path) -> dict[str, Any]:
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


def _read_rosbag2(path: Path, recover: bool) -> RawRecording:
    info = _metadata(path)
    storage = str(info.get("storage_identifier", ""))
    rel = info.get("relative_file_paths") or [f.get("path") for f in info.get("files") or []]
    files = [path / str(r) for r in rel if r]
    if not files:
        raise RecordingError(path, "empty: metadata.yaml lists no storage files")
    for f in files:
        if not f.is_file() and (path / f.name).is_file():
            files[files.index(f)] = path / f.name  # old metadata lists paths with the folder name
        elif not f.is_file():
            msg = f"storage file {f.name} listed in metadata.yaml is missing"
            raise RecordingError(path, msg)
    expected: dict[str, tuple[str, str, int]] = {}
    for entry in info.get("topics_with_message_count") or []:
        meta = entry.get("topic_metadata") or entry.get("topic_and_type") or {}
        name = str(meta.get("name", ""))
        expected[name] = (
            normalize_type(str(meta.get("type", ""))),
            str(meta.get("serialization_format", "cdr")),
            int(entry.get("message_count", 0)),
        )
    mode = str(info.get("compression_mode", "") or "").upper()
    fmt = str(info.get("compression_format", "") or "")
    if mode and fmt and fmt != "zstd":
        msg = f"unknown compression format {fmt!r}"
        raise RecordingError(path, msg)
    with contextlib.ExitStack() as stack:
        plain: list[Path] = []
        for f in files:
            if mode == "FILE" or f.suffix == ".zstd":
                tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="pbd-ingest-")))
                out = tmp / f.name.removesuffix(".zstd")
                out.write_bytes(_unzstd(f.read_bytes(), f))
                plain.append(out)
            else:
                plain.append(f)
        if storage == "mcap" or all(p.suffix == ".mcap" for p in plain):
            rec = _read_rosbag2_mcap(path, plain, recover)
        elif storage in ("sqlite3", "") or all(p.suffix == ".db3" for p in plain):
            rec = _read_rosbag2_files(path, plain, recover)
        else:
            msg = f"unknown rosbag2 storage {storage!r}"
            raise RecordingError(path, msg)
    rec.container = "rosbag2"
    if expected:  # metadata.yaml counts every topic: the loss is exact, not the storage reader's estimate
        rec.lost_messages = 0
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
            rec.warnings.append(f"{path}: topic {name}: {msg}; recovered those, lost {count - topic.count}")
    return rec


def _unzstd(data: bytes, where: Path) -> bytes:
    try:
        return bytes(zstandard.ZstdDecompressor().decompressobj().decompress(data))
    except zstandard.ZstdError as err:
        msg = f"zstd data does not decompress ({err})"
        raise RecordingError(where, msg) from err


def _unzstd_batch(batch: Batch, where: Path) -> Batch:
    payloads = [_unzstd(bytes(batch.payload(i)), where) for i in range(len(batch))]
    return Batch.from_payloads(payloads, batch.log_ns.tolist())


def _read_rosbag2_mcap(path: Path, files: list[Path], recover: bool) -> RawRecording:
    topics: dict[str, RawTopic] = {}
    rec = RawRecording(path, "rosbag2", topics)
    for f in files:
        data = f.read_bytes()
        content = read_mcap(data, str(f), recover=recover)
        _topics_from_mcap(content, f, topics, "cdr")
        if content.damage is not None:
            rec.warnings.append(f"{f}: {content.damage}")
            rec.lost_messages += content.lost_messages  # replaced by the exact loss where metadata.yaml counts
    return rec


@contextlib.contextmanager
def _sqlite_open(db: Path) -> Iterator[sqlite3.Connection]:
    uri = f"file:{db.resolve()}?mode=ro&immutable=1"
    try:
        con = sqlite3.connect(uri, uri=True)
    except sqlite3.Error as err:
        msg = f"cannot open sqlite3 storage ({err})"
        raise RecordingError(db, msg) from err
    try:
        yield con
    finally:
        con.close()


def _read_rosbag2_files(path: Path, files: list[Path], recover: bool) -> RawRecording:
    """The topics and messages of sqlite3 storage files; with ``recover``, the messages a damaged file yields
    before the damage are kept (with a warning) instead of an error."""
    topics: dict[str, RawTopic] = {}
    payloads: dict[str, list[bytes]] = {}
    stamps: dict[str, list[int]] = {}
    warnings: list[str] = []
    for db in files:
        if db.suffix != ".db3":
            msg = f"unexpected storage file {db.name} for sqlite3 storage"
            raise RecordingError(path, msg)
        with _sqlite_open(db) as con:
            try:
                tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
                if "topics" not in tables or "messages" not in tables:
                    raise RecordingError(db, "not a recording (sqlite3 file without rosbag2 tables)")
                defs: dict[str, tuple[str, str]] = {}
                if "message_definitions" in tables:
                    for typ, enc, text in con.execute(
                        "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"
                    ):
                        defs[normalize_type(str(typ))] = (str(enc), str(text or ""))
                ids: dict[int, str] = {}
                for tid, name, typ, fmt in con.execute("SELECT id, name, type, serialization_format FROM topics"):
                    msgtype = normalize_type(str(typ))
                    ids[int(tid)] = str(name)
                    if name not in topics:
                        enc, text = defs.get(msgtype, ("", ""))
                        if enc in ("unknown", "") or not text:
                            enc, text = "", ""
                        topics[name] = RawTopic(str(name), msgtype, str(fmt), enc, text)
                        payloads[name] = []
                        stamps[name] = []
            except sqlite3.Error as err:
                msg = f"corrupt sqlite3 storage ({err})"
                raise RecordingError(db, msg) from err
            kept = 0
            try:
                for tid, ts, data in con.execute("SELECT topic_id, timestamp, data FROM messages ORDER BY id"):
                    name = ids.get(int(tid))
                    if name is None:
                        msg = f"message on topic id {tid} which the topics table does not define"
                        raise RecordingError(db, msg)
                    payloads[name].append(bytes(data))
                    stamps[name].append(int(ts))
                    kept += 1
            except sqlite3.Error as err:
                msg = f"corrupt sqlite3 storage ({err})"
                if not recover:
                    raise RecordingError(db, msg) from err
                warnings.append(f"{db}: {msg}; recovered the {kept} messages before the damage")
    for name, topic in topics.items():
        if payloads[name]:
            topic.batches.append(Batch.from_payloads(payloads[name], stamps[name]))
    return RawRecording(path, "rosbag2", topics, warnings=warnings)
