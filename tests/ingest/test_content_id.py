"""The content id (RECORDING.md): SHA-256 of every byte, hashed on a thread beside the reading."""

from __future__ import annotations

import hashlib
import threading
from pathlib import Path

import numpy as np
import pytest

from tasks.errors import RecordingError
from tasks.ingest.api import ingest_recording
from tasks.ingest.content_id import HASH_BLOCK_BYTES, content_id_beside, recording_id_of
from tasks.recording.writer import RecordingWriter
from tasks.store import Store

STAMPS = 1_700_000_000_000_000_000 + np.arange(200, dtype=np.int64) * 10_000_000


def _recording(path: Path, kind: str = "mcap") -> Path:
    with RecordingWriter(path, kind) as w:
        w.add_points("/mocap/a", STAMPS, np.random.default_rng(5).normal(size=(200, 3)))
    return path


def test_the_id_is_the_sha256_of_the_bytes_and_changes_with_any_byte(tmp_path: Path) -> None:
    rec = _recording(tmp_path / "r.mcap")
    data = rec.read_bytes()
    assert recording_id_of(rec) == hashlib.sha256(data).hexdigest()[:16]
    big = tmp_path / "big.bin"  # several hash blocks, the last one short
    big.write_bytes(bytes(range(256)) * (3 * HASH_BLOCK_BYTES // 256 + 7))
    first = recording_id_of(big)
    assert first == hashlib.sha256(big.read_bytes()).hexdigest()[:16] == recording_id_of(big)
    flipped = bytearray(big.read_bytes())
    flipped[2 * HASH_BLOCK_BYTES + 3] ^= 1
    big.write_bytes(bytes(flipped))
    assert recording_id_of(big) != first


def test_a_folder_hashes_its_files_in_name_order(tmp_path: Path) -> None:
    bag = _recording(tmp_path / "bag2", "rosbag2")
    files = sorted((p for p in bag.rglob("*") if p.is_file()), key=lambda p: p.relative_to(bag).as_posix())
    h = hashlib.sha256()
    for f in files:
        h.update(f.read_bytes())
    assert recording_id_of(bag) == h.hexdigest()[:16]
    store = Store(tmp_path / "store")
    assert ingest_recording(bag, store).recording_id == h.hexdigest()[:16]


def test_the_id_hashed_beside_the_reading_is_the_same(tmp_path: Path) -> None:
    rec = _recording(tmp_path / "r.mcap")
    with content_id_beside(rec) as pending:
        got = pending.result()
    assert got == recording_id_of(rec)


def test_a_failed_read_abandons_the_hashing_and_leaves_no_thread(tmp_path: Path) -> None:
    big = tmp_path / "big.bin"
    big.write_bytes(b"\0" * (8 * HASH_BLOCK_BYTES))
    before = {t.name for t in threading.enumerate()}
    with pytest.raises(ValueError, match="read failed"), content_id_beside(big):
        raise ValueError("read failed")
    assert not [t for t in threading.enumerate() if t.name.startswith("pbd-content-id") and t.name not in before]


def test_a_hashing_error_reaches_the_caller(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="no such file"), content_id_beside(tmp_path / "gone.mcap") as pending:
        pending.result()


def test_an_id_the_caller_already_has_is_used_without_hashing(tmp_path: Path) -> None:
    """The flows remember content ids by file state and hand them to the ingest: the bytes are not hashed again,
    so the entry is stored under the id given (here one that is not the bytes' SHA-256, to show it)."""
    rec = _recording(tmp_path / "r.mcap")
    given = "0123456789abcdef"
    assert recording_id_of(rec) != given
    result = ingest_recording(rec, Store(tmp_path / "store"), known_id=given)
    assert result.recording_id == given
    assert Store(tmp_path / "store").has_recording(given)
