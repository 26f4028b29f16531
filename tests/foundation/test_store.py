"""The artefact store: versions, no overwrite, references, concurrent writers."""

from __future__ import annotations

import multiprocessing as mp
from pathlib import Path

import numpy as np
import pytest

from tasks.errors import DescriptorError, StoreError
from tasks.store import Store, write_bytes_atomic
from tests.foundation.test_descriptor import make_descriptor


def test_same_content_is_not_a_new_version(store: Store) -> None:
    first = store.put_descriptor(make_descriptor())
    again = store.put_descriptor(make_descriptor())
    changed = store.put_descriptor(make_descriptor(extent=0.8))
    assert (first.version, first.created) == (1, True)
    assert (again.version, again.created) == (1, False)
    assert (changed.version, changed.created) == (2, True)
    assert [e.version for e in store.versions("open-microwave")] == [1, 2]


def test_references_resolve(store: Store) -> None:
    a = store.put_descriptor(make_descriptor())
    b = store.put_descriptor(make_descriptor(extent=0.9))
    assert store.resolve("open-microwave@v1") == a.path
    assert store.resolve("open-microwave@latest") == b.path
    assert store.resolve(a.id[:8]) == a.path
    assert store.load(str(b.path)).id == b.id
    with pytest.raises(DescriptorError, match=r"versions 1\.\.2, not 7"):
        store.resolve("open-microwave@v7")
    with pytest.raises(DescriptorError, match="no descriptor named"):
        store.resolve("nothing@latest")
    with pytest.raises(DescriptorError, match="no descriptor with id starting"):
        store.resolve("deadbeef")
    with pytest.raises(DescriptorError, match="not a file"):
        store.resolve("no/such/file.json")


def test_atomic_write_refuses_overwrite(tmp_path: Path) -> None:
    target = tmp_path / "a.json"
    write_bytes_atomic(target, b"1")
    with pytest.raises(StoreError, match="refusing to overwrite"):
        write_bytes_atomic(target, b"2")
    assert target.read_bytes() == b"1"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


def test_model_round_trip(store: Store) -> None:
    pts = np.random.default_rng(0).normal(size=(100, 3))
    sha, _ = store.put_model(pts)
    sha2, _ = store.put_model(pts)
    assert sha == sha2
    np.testing.assert_allclose(store.load_model(sha), pts.astype(np.float32), rtol=0)
    with pytest.raises(StoreError, match="not in the store"):
        store.load_model("f" * 64)


def _put_many(root: str, worker: int) -> None:
    store = Store(root)
    for i in range(5):
        store.put_descriptor(make_descriptor(extent=0.1 + 0.01 * (worker * 5 + i)))


def test_concurrent_writers_get_distinct_versions(tmp_path: Path) -> None:
    root = str(tmp_path / "store")
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_put_many, args=(root, w)) for w in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    store = Store(root)
    entries = store.versions("open-microwave")
    assert [e.version for e in entries] == list(range(1, 21))
    assert len({e.id for e in entries}) == 20
    for e in entries:
        assert store.load(f"open-microwave@v{e.version}").id == e.id


def test_unreadable_model_and_non_files_are_one_error(store: Store, tmp_path: Path) -> None:
    sha, path = store.put_model(np.zeros((4, 3)))
    path.unlink()
    path.write_bytes(b"not parquet")
    with pytest.raises(StoreError, match=r"\.parquet: unreadable object model \(ArrowInvalid\)"):
        store.load_model(sha)
    (tmp_path / "folder.json").mkdir()
    with pytest.raises(DescriptorError, match=r"folder.json: not a regular file \(a folder, a FIFO or a device\)"):
        store.load(str(tmp_path / "folder.json"))


def test_a_failed_write_leaves_no_temporary_file(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(StoreError, match=r"/file: cannot write: File exists$"):
        write_bytes_atomic(blocker / "a.json", b"1")
    assert [p.name for p in tmp_path.iterdir()] == ["file"]
