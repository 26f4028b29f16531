"""Flow ``reprocess-archive``: every recording under a folder, a bounded number at a time, then a summary
of what changed against the previous versions (new, unchanged, changed with the diff) and the report."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from prefect import flow
from prefect.task_runners import ThreadPoolTaskRunner

from flows.chain import ChainSettings, archive_names, run_chains
from flows.discover import find_recordings
from flows.stages.report import report_task
from flows.summary import RunSummary, summarise
from tasks.store import resolve_store_root

DEFAULT_WORKERS = 2
"""Recordings in flight at once by default (this machine has 2 cores; learning is CPU-bound)."""

MAX_THREADS = 32
"""Bound of the thread-pool task runner (Prefect's default is unbounded); ``workers`` bounds the real work."""


@flow(name="reprocess-archive", task_runner=ThreadPoolTaskRunner[Any](max_workers=MAX_THREADS), persist_result=False)  # type: ignore[arg-type]  # TaskRunner is invariant in its future type
def reprocess_archive(
    archive: str,
    *,
    store: str | None = None,
    params: dict[str, Any] | None = None,
    seed: int = 0,
    workers: int = DEFAULT_WORKERS,
    report: bool = True,
) -> RunSummary:
    """Process every ``*.mcap``, ``*.bag`` and rosbag2 folder under ``archive`` (``workers`` at a time).

    Each recording's descriptor is named by its path under ``archive`` (``archive_names``).
    """
    root = str(resolve_store_root(store).resolve())
    folder = Path(archive)
    sources = find_recordings(folder)
    settings = ChainSettings(root, dict(params or {}), seed)
    entries = run_chains(sources, settings, workers=workers, names=archive_names(folder, sources))
    html = report_task(root, f"reprocess-archive {Path(archive).name}", entries) if report else None
    return summarise(entries, html)
