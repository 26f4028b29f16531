"""rosbag2 inputs that cannot hurt: storage confined to the bag folder, damaged sqlite as one line, and
``--recover`` on truncated sqlite3 storage with the exact loss from metadata.yaml (rosbags' rosbag2 Writer)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from tasks.errors import RecordingError
from tasks.ingest.api import ingest_recording
from tasks.recording.load import load_recording
from tasks.recording.writer import RecordingWriter
from tasks.store import Store

T0 = 1_700_000_000_000_000_000
N = 3000  # per topic: enough rows for interior pages in the messages b-tree
STAMPS = T0 + np.arange(N, dtype=np.int64) * 1_000_000
XYZ = np.random.default_rng(8).normal(size=(2, N, 3))


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("r2") / "bag"
    with RecordingWriter(path, "rosbag2") as w:
        for k in range(2):
            w.add_points(f"/mocap/m{k}", STAMPS, XYZ[k])
    return path


def _copy(bag: Path, to: Path) -> tuple[Path, Path]:
    shutil.copytree(bag, to)
    return to, next(to.glob("*.db3"))


def _edit_metadata(folder: Path, paths: list[str]) -> None:
    meta = folder / "metadata.yaml"
    doc = yaml.safe_load(meta.read_text())
    doc["rosbag2_bagfile_information"]["relative_file_paths"] = paths
    meta.write_text(yaml.safe_dump(doc))


def test_storage_outside_the_folder_is_refused(bag: Path, tmp_path: Path) -> None:
    elsewhere = tmp_path / "elsewhere.db3"
    shutil.copy(next(bag.glob("*.db3")), elsewhere)
    store = Store(tmp_path / "store")
    for k, rel in enumerate([str(elsewhere), "../elsewhere.db3", "sub/../../elsewhere.db3"]):
        folder, _ = _copy(bag, tmp_path / f"abs{k}")
        _edit_metadata(folder, [rel])
        with pytest.raises(RecordingError, match=r"metadata.yaml: storage path .* leaves the bag folder"):
            ingest_recording(folder, store)
    folder, db = _copy(bag, tmp_path / "link")
    db.unlink()
    db.symlink_to(elsewhere)
    with pytest.raises(RecordingError, match="is a link leading out of the bag folder"):
        ingest_recording(folder, store)
    assert not (store.root / "recordings").exists() or not any((store.root / "recordings").iterdir())


def test_byte_flipped_sqlite_is_one_line_or_the_data(bag: Path, tmp_path: Path) -> None:
    """16 seeded flips over the storage file: a RecordingError naming the folder or file, never another
    exception; with ``recover`` also never another exception."""
    rng = np.random.default_rng(30)
    data = next(bag.glob("*.db3")).read_bytes()
    errors = 0
    for j, pos in enumerate(rng.integers(0, len(data), 16).tolist()):
        folder, db = _copy(bag, tmp_path / f"flip{j}")
        damaged = bytearray(data)
        damaged[pos] ^= 0xFF
        db.write_bytes(bytes(damaged))
        for recover in (False, True):
            try:
                ingest_recording(folder, Store(tmp_path / f"s{j}{recover}"), recover=recover)
            except RecordingError as err:
                assert str(folder) in str(err) and "\n" not in str(err) and len(str(err)) < 600
                errors += 1
    assert errors < 32  # most flips land in blobs or unused bytes


@pytest.mark.parametrize("fraction", [0.3, 0.55, 0.9])
def test_recover_reads_the_intact_rows_of_a_truncated_sqlite(bag: Path, fraction: float, tmp_path: Path) -> None:
    folder, db = _copy(bag, tmp_path / "cut")
    data = db.read_bytes()
    db.write_bytes(data[: int(len(data) * fraction)])
    store = Store(tmp_path / "store")
    with pytest.raises(RecordingError, match="corrupt sqlite3 storage"):
        ingest_recording(folder, store)
    result = ingest_recording(folder, store, recover=True)
    rec = load_recording(store, result.recording_id)
    kept = 0
    for k in range(2):
        m = rec.markers[f"/mocap/m{k}"]
        idx = np.searchsorted(STAMPS, m.stamps_ns)
        np.testing.assert_array_equal(STAMPS[idx], m.stamps_ns)  # every row kept is a row written, intact
        np.testing.assert_array_equal(XYZ[k][idx], m.points)
        kept += len(m.stamps_ns)
    assert kept > 2 * N * fraction * 0.5  # most rows of the pages that are there
    assert result.lost_messages == 2 * N - kept  # exact: metadata.yaml counts every topic
    assert any("read it page by page" in w for w in result.warnings)


def test_recover_estimates_the_loss_of_a_lone_truncated_db3(bag: Path, tmp_path: Path) -> None:
    """Without metadata.yaml the page count in the file's header gives the loss, within 10 %."""
    data = next(bag.glob("*.db3")).read_bytes()
    db = tmp_path / "lone.db3"
    db.write_bytes(data[: len(data) // 2])
    store = Store(tmp_path / "store")
    result = ingest_recording(db, store, recover=True)
    kept = sum(len(m.stamps_ns) for m in load_recording(store, result.recording_id).markers.values())
    assert abs(result.lost_messages - (2 * N - kept)) <= 0.1 * (2 * N - kept)


def test_malformed_metadata_and_unopenable_storage_are_one_line(bag: Path, tmp_path: Path) -> None:
    folder, _ = _copy(bag, tmp_path / "odd")
    meta = folder / "metadata.yaml"
    doc = yaml.safe_load(meta.read_text())
    doc["rosbag2_bagfile_information"]["topics_with_message_count"] = [7]
    meta.write_text(yaml.safe_dump(doc))
    with pytest.raises(RecordingError, match=r"metadata.yaml: malformed metadata.yaml \(AttributeError"):
        ingest_recording(folder, Store(tmp_path / "store"))
    folder, _ = _copy(bag, tmp_path / "long")
    _edit_metadata(folder, ["x" * 5000 + ".db3"])
    with pytest.raises(RecordingError, match=r"storage file x{77}\.\.\. listed in metadata.yaml cannot be opened"):
        ingest_recording(folder, Store(tmp_path / "store"))


def test_recover_of_a_file_without_its_topics_table_is_one_line(bag: Path, tmp_path: Path) -> None:
    data = next(bag.glob("*.db3")).read_bytes()
    db = tmp_path / "stub.db3"
    db.write_bytes(data[:60])  # the sqlite header, cut before the page size
    with pytest.raises(RecordingError, match=r"stub\.db3: corrupt sqlite3 storage .*nothing to recover"):
        ingest_recording(db, Store(tmp_path / "store"), recover=True)
