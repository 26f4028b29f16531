"""Prefect wrapper of ingest (``tasks.ingest.api.ingest_recording``): a cached, retried task over references.

The cache key is the recording's content id (``recording_id_of``: SHA-256 of its bytes, remembered under the
file's state by ``flows.content_ids`` so that an unchanged file is not read again), the content ids of
the topic map and object model files if given, ``recover``, and the code version of the ingest modules.
The result is a ``RecordingRef`` (the id and the source path); the data stays in the store's Parquet.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from prefect import task
from prefect.context import TaskRunContext

from flows.caching import RETRIED, stage_key
from flows.content_ids import content_id, remembered_id
from tasks.errors import PbdError
from tasks.ingest.api import ingest_recording
from tasks.report.refs import RecordingRef
from tasks.store import Store

INGEST_MODULES = ("tasks.ingest", "tasks.recording", "schemas")
"""Modules whose source is the ingest stage's code version."""


def _file_id(path: str | None) -> str | None:
    """SHA-256 (16 hex) of a small side file's bytes, None when not given."""
    if path is None:
        return None
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def ingest_cache_key(context: TaskRunContext, parameters: dict[str, Any]) -> str | None:
    """Cache key of an ingest run; None (no caching) when the source cannot be read: the task reports why."""
    del context
    try:
        recording_id = content_id(parameters["store_root"], Path(parameters["source"]))
        refs = {"recording": recording_id, "topics": _file_id(parameters.get("topics")),
                "object_model": _file_id(parameters.get("object_model"))}  # fmt: skip
    except (OSError, PbdError):
        return None
    return stage_key("ingest", INGEST_MODULES, refs, {"recover": bool(parameters.get("recover", False))})


@task(
    name="ingest",
    cache_key_fn=ingest_cache_key,
    persist_result=True,
    **RETRIED,
)
def ingest_task(
    source: str,
    store_root: str,
    topics: str | None = None,
    recover: bool = False,
    object_model: str | None = None,
) -> RecordingRef:
    """Ingest one recording (file or rosbag2 folder) into the store; a no-op when it is already there."""
    result = ingest_recording(
        Path(source),
        Store(store_root),
        topics=Path(topics) if topics else None,
        recover=recover,
        object_model=Path(object_model) if object_model else None,
        known_id=remembered_id(store_root, Path(source)),  # remembered when the cache key was made
    )
    return RecordingRef(result.recording_id, source, result.lost_messages, tuple(result.warnings))
