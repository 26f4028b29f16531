"""``flows.content_ids``: a recording's content id remembered under its file state, never for other bytes."""

from __future__ import annotations

import os
import sqlite3
import time
from pathlib import Path

from flows.caching import results_dir
from flows.content_ids import MEMO_FILENAME, SETTLE_S, content_id, state_key
from tasks.ingest.api import recording_id_of


def _remembered(store: Path) -> dict[str, str]:
    with sqlite3.connect(results_dir(store) / MEMO_FILENAME) as db:
        return dict(db.execute("SELECT state, id FROM ids").fetchall())


def test_an_unchanged_file_is_remembered_and_a_rewritten_one_is_not(tmp_path: Path) -> None:
    store = tmp_path / "store"
    rec = tmp_path / "a.mcap"
    rec.write_bytes(b"first content " * 1000)
    assert state_key(rec) is None  # just written: may still be being written
    assert content_id(store, rec) == recording_id_of(rec)
    assert not (results_dir(store) / MEMO_FILENAME).exists() or _remembered(store) == {}

    time.sleep(SETTLE_S + 0.1)
    first = content_id(store, rec)
    assert _remembered(store) == {state_key(rec): first}

    stat = rec.stat()
    rec.write_bytes(b"other content " * 1000)  # same size, then the old mtime put back (cp -p, rsync -t do this)
    os.utime(rec, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    time.sleep(SETTLE_S + 0.1)
    second = content_id(store, rec)
    assert second == recording_id_of(rec) != first  # the ctime moved: not taken for the remembered bytes


def test_a_folder_recording_changes_with_any_of_its_files(tmp_path: Path) -> None:
    store = tmp_path / "store"
    bag = tmp_path / "bag2"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (bag / "bag2_0.mcap").write_bytes(b"x" * 4096)
    time.sleep(SETTLE_S + 0.1)
    first = content_id(store, bag)
    assert first == recording_id_of(bag) and len(_remembered(store)) == 1
    (bag / "bag2_1.mcap").write_bytes(b"y" * 10)
    time.sleep(SETTLE_S + 0.1)
    assert content_id(store, bag) == recording_id_of(bag) != first
