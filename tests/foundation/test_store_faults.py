"""Fault injection at every step of the store's write protocols (ingest, learn and transfer, report).

Each protocol runs with ``$PBD_FAULT_STEP`` naming one of its steps (``tasks.atomic.checkpoint``): killed there
(a forked child that dies with ``os._exit``, as after ``kill -9``) or failed there with ``OSError(ENOSPC)``.
After the fault the store reads cleanly; a failed write is one ``StoreError`` naming the path and the cause;
the next clean run repairs what a kill left and stores exactly one new version: no name is blocked.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from schemas.descriptor import Descriptor, ObjectRef, Primitive
from tasks.atomic import FAULT_KILL_EXIT, FAULT_MODE_ENV, FAULT_STEP_ENV, WRITE_STEPS
from tasks.errors import StoreError
from tasks.ingest.api import ingest_recording
from tasks.recording.load import load_recording
from tasks.recording.writer import RecordingWriter
from tasks.report.build import write_report
from tasks.store import DESCRIPTOR_STEPS, MODEL_STEPS, STAGE_STEPS, Store

T0 = 1_700_000_000_000_000_000
MODEL = np.random.default_rng(5).normal(size=(200, 3))


def _descriptor(extent: float) -> Descriptor:
    chain = (Primitive("rotation", (0.0, 0.0, 0.5), (0.0, 0.0, 1.0), extent),)
    return Descriptor("open-door", "open", ObjectRef("door"), None, chain, code_version="x")


def _ingest(store: Store, folder: Path) -> None:
    """What ``pbd ingest`` writes: a recording folder staged and renamed into place."""
    ingest_recording(_recording(folder), store)


def _learn_writes(store: Store, folder: Path) -> None:
    """What ``pbd learn`` and ``pbd transfer`` write: the object model, then the descriptor version."""
    del folder
    store.put_model(MODEL)
    store.put_descriptor(_descriptor(1.5))


def _report(store: Store, folder: Path) -> None:
    """What a flow's report writes: files staged in a folder renamed into ``reports/``."""
    del folder
    write_report(store, "run-1", "faults", [])


def _recording(folder: Path) -> Path:
    path = folder / "demo.mcap"
    if not path.exists():
        stamps = T0 + np.arange(60, dtype=np.int64) * 10_000_000
        with RecordingWriter(path, "mcap") as w:
            w.add_points("/mocap/m0", stamps, np.random.default_rng(1).normal(size=(60, 3)))
    return path


PROTOCOLS: dict[str, tuple[tuple[str, ...], Callable[[Store, Path], None]]] = {
    "ingest": (STAGE_STEPS, _ingest),
    "learn": (("stage.created", *MODEL_STEPS, *DESCRIPTOR_STEPS), _learn_writes),
    "report": (("stage.created", *WRITE_STEPS, "stage.publishing", "stage.published"), _report),
}
CASES = [(name, step) for name, (steps, _) in PROTOCOLS.items() for step in steps]
LAST_STEPS = {"stage.published", "model.linked", "descriptor.index.linked"}
"""Steps after which the protocol's artefact is complete (a fault there fails the call, the store has it)."""


def _prepare(store: Store) -> None:
    store.put_descriptor(_descriptor(1.0))  # v1, so the protocol under test writes v2


def _readable(store: Store) -> None:
    """Whatever a fault left, readers see whole artefacts only."""
    entries = store.versions("open-door")
    assert [e.version for e in entries] == list(range(1, len(entries) + 1))
    for e in entries:
        assert store.load(f"open-door@v{e.version}").id == e.id
    if store.recordings_dir.is_dir():
        for rec in store.recordings_dir.iterdir():
            assert store.has_recording(rec.name), rec
            assert load_recording(store, rec.name).markers["/mocap/m0"].points.shape == (60, 3)
    if store.reports_dir.is_dir():
        for report in store.reports_dir.iterdir():
            assert {p.name for p in report.iterdir()} == {"report.html", "summary.md"}


def _leftovers(store: Store) -> list[str]:
    """Temporary files and folders anywhere in the store (lock files are not leftovers)."""
    found = [p for p in store.root.rglob("*") if p.name.endswith(".tmp")]
    if store.tmp_dir.is_dir():
        found += list(store.tmp_dir.iterdir())
    return sorted(str(p.relative_to(store.root)) for p in found)


def _rerun(name: str, store: Store, tmp_path: Path) -> None:
    """Run the protocol again without a fault; it completes and leaves exactly one new version, nothing else."""
    run = PROTOCOLS[name][1]
    if name == "report" and (store.reports_dir / "run-1").exists():
        with pytest.raises(StoreError, match="a report for this run already exists"):
            run(store, tmp_path)
    else:
        run(store, tmp_path)
    _readable(store)
    if name == "learn":
        entries = store.versions("open-door")
        assert [round(store.load(f"open-door@v{e.version}").chain[0].extent, 3) for e in entries] == [1.0, 1.5]
        assert store.model_path(store.put_model(MODEL)[0]).is_file()
    _staged_once_more(store)
    assert _leftovers(store) == []
    assert not store.quarantine_dir.exists()  # every kill left whole files: adopted, not quarantined


def _staged_once_more(store: Store) -> None:
    """A later staging sweeps what a dead writer staged (nobody else is staging now)."""
    with store.staging("probe"):
        pass


@pytest.mark.parametrize(("name", "step"), CASES)
def test_a_kill_at_any_step_is_repaired_by_the_next_run(name: str, step: str, tmp_path: Path) -> None:
    store = Store(tmp_path / "store")
    _prepare(store)
    _recording(tmp_path)
    run = PROTOCOLS[name][1]
    pid = os.fork()
    if pid == 0:  # the child: run the protocol, die at the step
        os.environ[FAULT_STEP_ENV] = step
        os.environ[FAULT_MODE_ENV] = "kill"
        try:
            run(store, tmp_path)
        finally:
            os._exit(0)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == FAULT_KILL_EXIT  # it did reach the step
    _readable(store)
    _rerun(name, store, tmp_path)


@pytest.mark.parametrize(("name", "step"), CASES)
def test_no_space_at_any_step_is_one_error_naming_the_path(
    name: str, step: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    store = Store(tmp_path / "store")
    _prepare(store)
    _recording(tmp_path)
    before = sorted(str(p.relative_to(store.root)) for p in store.root.rglob("*") if p.is_file())
    monkeypatch.setenv(FAULT_STEP_ENV, step)
    monkeypatch.setenv(FAULT_MODE_ENV, "enospc")
    with pytest.raises(StoreError, match=r"^/\S+: (cannot write: )?No space left on device$") as info:
        PROTOCOLS[name][1](store, tmp_path)
    assert str(info.value).startswith(str(store.root))
    assert _leftovers(store) == []
    _readable(store)
    after = sorted(str(p.relative_to(store.root)) for p in store.root.rglob("*") if p.is_file())
    new = [p for p in after if p not in before and not p.endswith(".lock")]
    if step.startswith("descriptor."):  # the model was stored whole before the descriptor's protocol began
        new = [p for p in new if not p.startswith("models/")]
    if step not in LAST_STEPS:
        assert new == []  # nothing left behind
    monkeypatch.delenv(FAULT_STEP_ENV)
    _rerun(name, store, tmp_path)


def test_an_orphan_version_is_adopted_once_and_a_broken_one_quarantined(store: Store) -> None:
    _prepare(store)
    folder = store.descriptor_dir("open-door")
    (folder / "v2.json").write_text(_descriptor(2.0).to_json())  # whole, valid, not in the index
    (folder / "v3.json").write_text('{"truncated": ')  # a broken one after it
    (folder / ".v4.json.abc.tmp").write_text("half")
    assert [e.version for e in store.versions("open-door")] == [1]
    put = store.put_descriptor(_descriptor(3.0))
    assert (put.version, put.created) == (3, True)
    assert [round(store.load(f"open-door@v{n}").chain[0].extent, 1) for n in (1, 2, 3)] == [1.0, 2.0, 3.0]
    assert [p.name.split(".")[:3] for p in store.quarantine_dir.rglob("*.json.*")] == [["v3", "json", "orphan"]]
    assert not (folder / ".v4.json.abc.tmp").exists()


def test_a_corrupt_index_is_one_error_to_readers_and_rebuilt_by_the_next_write(store: Store) -> None:
    _prepare(store)
    store.put_descriptor(_descriptor(2.0))
    index = store.descriptor_dir("open-door") / "index.json"
    index.write_text("[{")
    with pytest.raises(StoreError, match=r"index.json: corrupt index \(JSONDecodeError\); the next write"):
        store.versions("open-door")
    index.write_text(
        '[{"version": 2, "id": "x", "created": "", "recording": null, "parameters": {}, "code_version": ""}]'
    )
    with pytest.raises(StoreError, match=r"corrupt index \(versions not 1..N in order\)"):
        store.versions("open-door")
    put = store.put_descriptor(_descriptor(2.0))
    assert (put.version, put.created) == (2, False)  # v1 and v2 adopted from their files; same content as v2
    assert [e.version for e in store.versions("open-door")] == [1, 2]


@pytest.mark.parametrize(("mode", "cause"), [("EROFS", "Read-only file system"), ("EACCES", "Permission denied")])
def test_a_read_only_store_is_one_error_naming_the_path(
    store: Store, mode: str, cause: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    _prepare(store)
    monkeypatch.setenv(FAULT_STEP_ENV, "descriptor.version.written")
    monkeypatch.setenv(FAULT_MODE_ENV, mode)
    with pytest.raises(StoreError, match=rf"open-door/v2\.json: cannot write: {cause}$"):
        store.put_descriptor(_descriptor(2.0))
    assert [e.version for e in store.versions("open-door")] == [1]
    assert _leftovers(store) == []


def test_the_cause_of_a_pyarrow_write_error_is_its_detail() -> None:
    from tasks.atomic import os_error_text

    err = OSError(28, "Error writing bytes to file. Detail: [errno 28] No space left on device")
    assert os_error_text(err) == "No space left on device"
    assert os_error_text(OSError("no strerror")) == "OSError"
