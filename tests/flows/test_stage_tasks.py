"""The stage task wrappers: cache keys over content ids, results persisted under the store."""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from prefect import flow

from flows.caching import on_store, results_dir
from flows.stages import ingest as ingest_module
from tasks.report.refs import RecordingRef
from tests.flows.recordings import write_door_recording

CallCounter = Counter[str]


def count_calls(monkeypatch: pytest.MonkeyPatch, module: Any, name: str, counter: CallCounter) -> None:
    """Wrap ``module.name`` so each real call is counted in ``counter[name]`` (the real function still runs)."""
    real: Callable[..., Any] = getattr(module, name)
    lock = threading.Lock()

    def counted(*args: Any, **kwargs: Any) -> Any:
        with lock:
            counter[name] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)


@flow(persist_result=False)
def ingest_twice(source: str, store_root: str) -> list[RecordingRef]:
    """Ingest the same recording twice in one flow run."""
    task = on_store(ingest_module.ingest_task, store_root)
    return [task(source, store_root), task(source, store_root)]


def test_ingest_task_is_cached_on_the_recording_content(
    prefect_harness: None, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    calls: CallCounter = Counter()
    count_calls(monkeypatch, ingest_module, "ingest_recording", calls)
    source = write_door_recording(tmp_path / "door.bag", fmt="bag")
    store = tmp_path / "store"
    first, second = ingest_twice(str(source), str(store))
    assert calls["ingest_recording"] == 1
    assert first == second
    assert (store / "recordings" / first.recording_id / "recording.json").is_file()
    assert any(p.name.startswith("ingest-") for p in results_dir(store).iterdir())
    # the same bytes under another name are the same recording: still a cache hit
    copy = tmp_path / "copy.bag"
    copy.write_bytes(source.read_bytes())
    third, _ = ingest_twice(str(copy), str(store))
    assert calls["ingest_recording"] == 1
    assert third.recording_id == first.recording_id
