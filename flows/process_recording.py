"""Flow ``process-recording``: one recording through ingest, segment, fit, grasp, store, simulate, and report."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from prefect import flow
from prefect.client.schemas.objects import State

from flows.chain import ChainSettings, run_chains
from flows.stages.report import report_task
from flows.summary import RunSummary, finish
from flows.task_runner import LocalThreadPoolTaskRunner
from tasks.store import resolve_store_root


@flow(name="process-recording", task_runner=LocalThreadPoolTaskRunner(max_workers=4), persist_result=False)  # type: ignore[arg-type]  # TaskRunner is invariant in its future type
def process_recording(
    recording: str,
    *,
    store: str | None = None,
    params: dict[str, Any] | None = None,
    name: str | None = None,
    seed: int = 0,
    report: bool = True,
    grasp: dict[str, Any] | None = None,
) -> RunSummary | State[Any]:
    """Ingest → segment → fit → grasp → store → simulate → report for the recording at ``recording`` (file or
    rosbag2 folder); ends Failed when the recording fails."""
    root = str(resolve_store_root(store).resolve())
    settings = ChainSettings(root, dict(params or {}), seed, name, grasp=dict(grasp or {}))
    entries = run_chains([Path(recording)], settings, workers=1)
    html = report_task(root, f"process-recording {Path(recording).name}", entries) if report else None
    return finish(entries, html)
