"""Results a run knows before it submits anything: a stage's persisted result under its cache key, and a
descriptor that is already the latest version of its name.

A task run whose result is cached still costs a round of Prefect work (a task run created, its cache key
computed, its record read, three state changes sent to the server and written there): about 15 ms of this
process's CPU and 30 ms of the server's per task run, eight per recording. On an unchanged archive of 200
recordings that is 1,600 task runs doing nothing. ``flows.chain`` looks each stage up here first, with the very
cache key the task would compute, and submits a recording's tasks only when some stage of it is not known.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

from prefect import Task
from prefect.filesystems import LocalFileSystem
from prefect.results import ResultStore
from prefect.settings import get_current_settings
from prefect.utilities.callables import get_call_parameters

from flows.caching import results_dir
from schemas.descriptor import Descriptor
from tasks.report.refs import DescriptorRef
from tasks.store import Store


class NotKnownError(Exception):
    """A stage's result is not known without running it (no record under its key, or not readable)."""


class KnownResults:
    """Cached stage results of one store (``<store>/prefect-results``), read as the tasks would read them."""

    def __init__(self, store_root: str) -> None:
        self.store = Store(store_root)
        storage = LocalFileSystem(basepath=str(results_dir(store_root)))
        self.results = ResultStore(result_storage=storage, cache_result_in_memory=False)
        self.refresh = bool(get_current_settings().tasks.refresh_cache)

    def cached(self, task: Task[..., Any], *args: Any, **kwargs: Any) -> Any:
        """The result ``task.submit(*args, **kwargs)`` would return from its cache; ``NotKnownError`` when it would
        run. The parameters are bound as Prefect binds them (defaults applied), so the key is the task's key."""
        if task.cache_key_fn is None or task.refresh_cache or self.refresh:
            raise NotKnownError(task.name)
        key = task.cache_key_fn(None, get_call_parameters(task.fn, args, kwargs))  # type: ignore[arg-type]
        if key is None or not (Path(self.results.result_storage.basepath) / key).is_file():  # type: ignore[union-attr]
            raise NotKnownError(task.name)
        try:  # a record being written by another run, or from an older code: the task decides
            record = self.results.read(key)
        except Exception as err:
            raise NotKnownError(task.name) from err
        if record.expiration is not None and record.expiration <= dt.datetime.now(dt.UTC):
            raise NotKnownError(task.name)
        return record.result

    def unchanged(self, descriptor: Descriptor) -> DescriptorRef:
        """The stored version ``descriptor`` is, when it is already the latest of its name with its object model
        stored (what ``store_descriptor_task`` would return without writing); ``NotKnownError`` otherwise."""
        entries = self.store.versions(descriptor.name)
        if not entries or entries[-1].id != descriptor.id:
            raise NotKnownError("store-descriptor")
        version = entries[-1].version
        path = self.store.descriptor_path(descriptor.name, version)
        if self.store.descriptor_path(descriptor.name, version + 1).exists():  # an orphan the next write adopts
            raise NotKnownError("store-descriptor")
        sha = descriptor.object.model_sha256
        if sha and not (self.store.models_dir / f"{sha}.parquet").is_file():
            raise NotKnownError("store-descriptor")
        return DescriptorRef(descriptor.name, version, descriptor.id, str(path), created=False)
