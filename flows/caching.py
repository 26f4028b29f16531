"""Cache keys, result storage and retry rules shared by the Prefect task wrappers in ``flows/stages/<stage>.py``.

A stage's cache key is built from references only: the content ids of its inputs (recording id, descriptor
id), its parameters (canonical JSON) and an explicit code version over the stage's modules
(``tasks.code_version.code_version``), never from a hash of arrays. Prefect's ``TASK_SOURCE`` policy hashes a
task's body only, so it would miss a change in a helper module; the explicit version covers every module.

Results are persisted under the store (``<store>/prefect-results``), not under ``PREFECT_HOME``: the cache
survives new processes, a new Prefect home and a different server.
"""

from __future__ import annotations

import errno
import hashlib
import importlib.util
import sqlite3
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from schemas.descriptor import canonical_json
from tasks.code_version import code_version
from tasks.errors import PbdError

if TYPE_CHECKING:
    from prefect import Task
    from prefect.client.schemas.objects import State, TaskRun

RESULTS_DIRNAME = "prefect-results"
"""Folder under the store root that holds Prefect's persisted task results and cache records."""

TRANSIENT_ERRNOS = frozenset(
    {errno.EAGAIN, errno.EBUSY, errno.EINTR, errno.EIO, errno.ETIMEDOUT, errno.ENFILE, errno.EMFILE, errno.ESTALE}
)
"""OS error numbers worth a retry: contention, interrupted calls, exhausted descriptors, flaky network mounts."""

RETRIES = 2
"""Retries of a stage task after a transient IO error (never after a PbdError or a bug)."""

RETRY_DELAY_S = 1.0
"""Pause before a retry, seconds."""

STAGE_TIMEOUT_S = 1800.0
"""Longest wait for one stage of one recording, seconds (``flows.chain.collect``): a grasp plan takes up to ~20 s
and a long recording's segmentation minutes on two busy cores, so half an hour means a hung run (a deadlocked
worker, a stuck mount). Prefect's own task timeouts cannot stop a task in a worker thread."""

T = TypeVar("T")


def results_dir(store_root: str | Path) -> Path:
    """Absolute folder of the persisted Prefect results of a store (``<store>/prefect-results``)."""
    return (Path(store_root) / RESULTS_DIRNAME).resolve()


def on_store(task: Task[Any, T], store_root: str | Path) -> Task[Any, T]:
    """``task`` with its results (and cache records) persisted in the store's ``prefect-results`` folder."""
    return task.with_options(result_storage=results_dir(store_root), persist_result=True)


def stage_key(stage: str, modules: tuple[str, ...], refs: Mapping[str, Any], params: Mapping[str, Any]) -> str:
    """Cache key of one stage run: ``<stage>-<32 hex>`` over the code version, input ids and parameters.

    ``refs`` holds content ids (strings) of the inputs, ``params`` the stage's parameters (JSON values).
    A module that is not there (a stage not built yet) is left out of the code version.
    """
    present = tuple(m for m in modules if importlib.util.find_spec(m) is not None)
    body = {"stage": stage, "code": code_version(*present), "refs": dict(refs), "params": dict(params)}
    digest = hashlib.sha256(canonical_json(body).encode()).hexdigest()[:32]
    return f"{stage}-{digest}"


def is_transient_io_error(err: BaseException) -> bool:
    """True for IO errors that may pass on a second try (contention, timeouts, locked SQLite, flaky mounts)."""
    if isinstance(err, PbdError):
        return False
    if isinstance(err, TimeoutError | ConnectionError | BlockingIOError | InterruptedError):
        return True
    if isinstance(err, sqlite3.OperationalError):
        return "locked" in str(err) or "busy" in str(err)
    if isinstance(err, FileNotFoundError | PermissionError | IsADirectoryError | NotADirectoryError):
        return False
    return isinstance(err, OSError) and err.errno in TRANSIENT_ERRNOS


def retry_on_transient_io(task: Task[Any, Any], task_run: TaskRun, state: State[Any]) -> bool:
    """Prefect ``retry_condition_fn``: retry only when the failure is a transient IO error."""
    del task, task_run
    err = state.result(raise_on_failure=False)
    return isinstance(err, BaseException) and is_transient_io_error(err)


RETRIED: dict[str, Any] = {
    "retries": RETRIES,
    "retry_delay_seconds": RETRY_DELAY_S,
    "retry_condition_fn": retry_on_transient_io,
}
"""The retry options of every stage task (``@task(..., **RETRIED)``): retried only after a transient IO error."""
