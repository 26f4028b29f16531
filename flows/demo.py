"""Flow ``pbd-demo``: the sample recordings of the paper's four tasks (made when missing by
``tasks.synth.samples.ensure_sample_recordings``) through the whole pipeline, then the report."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from prefect import flow, task
from prefect.cache_policies import NO_CACHE
from prefect.client.schemas.objects import State

from flows.chain import ChainSettings, run_chains
from flows.reprocess_archive import DEFAULT_WORKERS, MAX_THREADS
from flows.stages.report import report_task
from flows.summary import RunSummary, finish
from flows.task_runner import LocalThreadPoolTaskRunner
from tasks.store import resolve_store_root
from tasks.synth.samples import ensure_sample_recordings

DEFAULT_SAMPLES = "data/recordings"
"""Folder of the sample recordings (made there when missing)."""


@task(name="sample-recordings", cache_policy=NO_CACHE, persist_result=False)
def sample_recordings_task(folder: str) -> list[str]:
    """Paths of the sample recordings under ``folder``, written when missing (the folder is the cache)."""
    made = ensure_sample_recordings(Path(folder))
    paths = made.values() if isinstance(made, Mapping) else made
    return sorted(str(p) for p in paths)


@flow(name="pbd-demo", task_runner=LocalThreadPoolTaskRunner(max_workers=MAX_THREADS), persist_result=False)  # type: ignore[arg-type]  # TaskRunner is invariant in its future type
def demo(
    store: str | None = None,
    samples: str = DEFAULT_SAMPLES,
    workers: int = DEFAULT_WORKERS,
) -> RunSummary | State[Any]:
    """Make the sample recordings under ``samples`` if missing, process each, write the report.

    Descriptors are named by the recordings' meta (``<action>-<object>``), one per task.
    """
    root = str(resolve_store_root(store).resolve())
    sources = [Path(p) for p in sample_recordings_task(str(Path(samples).resolve()))]
    entries = run_chains(sources, ChainSettings(root), workers=workers)
    html = report_task(root, "pbd demo: the four sample tasks", entries)
    return finish(entries, html)
