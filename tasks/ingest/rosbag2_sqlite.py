"""rosbag2 sqlite3 storage: topics and definitions from their tables, messages queried by topic.

Only the rows of topics whose payloads are wanted are read (the others are counted with one ``GROUP BY``; sqlite
never reads a blob it is not asked for). Any sqlite or decoding failure is one ``RecordingError``. With
``recover``, a truncated or damaged file is read page by page instead (``sqlite_pages``): every intact row of the
messages table is kept, and the loss is estimated from the page count in the file's header (``metadata.yaml``,
when there is one, then gives the exact loss).
"""

from __future__ import annotations

import contextlib
import sqlite3
import struct
import tempfile
import urllib.parse
from collections.abc import Iterator
from pathlib import Path

from tasks.errors import RecordingError
from tasks.ingest.batch import Batch
from tasks.ingest.raw import RawRecording, RawTopic
from tasks.ingest.selection import SMALL_PAYLOAD_BYTES, Keep, Want, keep_all, normalize_type
from tasks.ingest.sqlite_pages import HEADER_PAGES_BYTES, MessageRows, patched_prefix, scan_message_rows

_SQL_ERRORS = (sqlite3.Error, ValueError, TypeError, OverflowError)
"""What a damaged sqlite file can raise while read (malformed pages, wrong column types, bad text)."""


@contextlib.contextmanager
def _sqlite_open(db: Path) -> Iterator[sqlite3.Connection]:
    uri = f"file:{urllib.parse.quote(str(db.resolve()))}?mode=ro&immutable=1"
    try:
        con = sqlite3.connect(uri, uri=True)
    except sqlite3.Error as err:
        msg = f"cannot open sqlite3 storage ({err})"
        raise RecordingError(db, msg) from err
    con.text_factory = lambda b: b.decode("utf-8", errors="replace")
    try:
        yield con
    finally:
        con.close()


def _topic_tables(con: sqlite3.Connection, db: Path) -> dict[int, RawTopic]:
    """The topics table (with the definitions of ``message_definitions``), by topic id."""
    tables = {str(r[0]) for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    if "topics" not in tables or "messages" not in tables:
        raise RecordingError(db, "not a recording (sqlite3 file without rosbag2 tables)")
    defs: dict[str, tuple[str, str]] = {}
    if "message_definitions" in tables:
        for typ, enc, text in con.execute(
            "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"
        ):
            defs[normalize_type(str(typ))] = (str(enc), str(text or ""))
    topics: dict[int, RawTopic] = {}
    for tid, name, typ, fmt in con.execute("SELECT id, name, type, serialization_format FROM topics"):
        msgtype = normalize_type(str(typ))
        enc, text = defs.get(msgtype, ("", ""))
        if enc in ("unknown", "") or not text:
            enc, text = "", ""
        topics[int(tid)] = RawTopic(str(name), msgtype, str(fmt), enc, text)
    return topics


def _query_rows(con: sqlite3.Connection, keep: dict[int, Keep], rows: MessageRows) -> None:
    """Counts of every topic, and the rows of the wanted ones (SMALL: the first, then the small ones)."""
    for tid, n, lo, hi in con.execute(
        "SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages GROUP BY topic_id"
    ):
        rows.count(int(tid), int(n), int(lo), int(hi))
    wanted = [t for t, k in keep.items() if k is not Keep.NONE]
    if not wanted:
        return
    marks = ",".join("?" * len(wanted))
    small = [t for t in wanted if keep[t] is Keep.SMALL]
    firsts: dict[int, int] = {}
    for t in small:
        got = con.execute("SELECT MIN(id) FROM messages WHERE topic_id = ?", (t,)).fetchone()
        if got and got[0] is not None:
            firsts[t] = int(got[0])
    sql = (
        "SELECT id, topic_id, timestamp, data FROM messages WHERE topic_id IN ("
        + marks
        + ") AND (topic_id NOT IN ("
        + (",".join("?" * len(small)) or "NULL")
        + ") OR length(data) <= ? OR id IN ("
        + (",".join("?" * len(firsts)) or "NULL")
        + ")) ORDER BY id"
    )
    args = [*wanted, *small, SMALL_PAYLOAD_BYTES, *firsts.values()]
    for rid, tid, ts, data in con.execute(sql, args):
        rows.add(int(rid), int(tid), int(ts), bytes(data))


def _read_one(db: Path, recover: bool, want: Want, warnings: list[str]) -> tuple[dict[int, RawTopic], MessageRows]:
    """Topics and rows of one storage file (see the module docstring for ``recover``)."""
    failure: BaseException | None = None
    with _sqlite_open(db) as con:
        try:
            topics = _topic_tables(con, db)
            keep = {t: want(topic.name, topic.msgtype) for t, topic in topics.items()}
            rows = MessageRows(set(topics))
            _query_rows(con, keep, rows)
        except _SQL_ERRORS as err:
            failure = err
    if failure is None:
        return topics, rows
    msg = f"corrupt sqlite3 storage ({str(failure)[:100]})"
    if not recover:
        raise RecordingError(db, msg) from failure
    lost_too = f"{msg}; its topics table is lost too, nothing to recover"
    try:
        with tempfile.TemporaryDirectory(prefix="pbd-sqlite-") as tmp:
            head = Path(tmp) / "head.db3"
            patched_prefix(db, head, HEADER_PAGES_BYTES)
            with _sqlite_open(head) as con:
                topics = _topic_tables(con, db)
        keep = {t: want(topic.name, topic.msgtype) for t, topic in topics.items()}
        rows = scan_message_rows(db, set(topics), keep)
    except (*_SQL_ERRORS, OSError, IndexError, struct.error) as err:
        raise RecordingError(db, lost_too) from err
    lost = f", about {rows.lost_estimate} lost (from the page count in its header)" if rows.lost_estimate else ""
    warnings.append(f"{db}: {msg}; read it page by page: recovered {rows.total} intact messages{lost}")
    return topics, rows


def read_sqlite_files(path: Path, files: list[Path], recover: bool, want: Want = keep_all) -> RawRecording:
    """The topics and messages of sqlite3 storage files (topics matched by name across files)."""
    topics: dict[str, RawTopic] = {}
    parts: dict[str, list[tuple[list[int], list[int], list[bytes]]]] = {}
    warnings: list[str] = []
    log_range: tuple[int, int] | None = None
    lost = 0
    for db in files:
        if db.suffix != ".db3":
            msg = f"unexpected storage file {db.name} for sqlite3 storage"
            raise RecordingError(path, msg)
        by_id, rows = _read_one(db, recover, want, warnings)
        unknown = set(rows.counts) - set(by_id)
        if unknown:
            msg = f"message on topic id {min(unknown)} which the topics table does not define"
            raise RecordingError(db, msg)
        lost += rows.lost_estimate
        for tid, t in by_id.items():
            topic = topics.setdefault(t.name, t)
            topic.seen += rows.counts.get(tid, 0)
            got = rows.rows.get(tid)
            if got is not None:
                parts.setdefault(t.name, []).append(got)
        if rows.log_range is not None:
            lo, hi = rows.log_range
            log_range = (lo, hi) if log_range is None else (min(log_range[0], lo), max(log_range[1], hi))
    for name, chunks in parts.items():  # each file's rows are in id order; files follow in their order
        stamps = [s for c in chunks for s in c[1]]
        payloads = [p for c in chunks for p in c[2]]
        topics[name].batches.append(Batch.from_payloads(payloads, stamps))
    return RawRecording(path, "rosbag2", topics, lost_messages=lost, warnings=warnings, log_range=log_range)
