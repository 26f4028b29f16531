"""Flow ``reprocess-archive``: every recording under a folder, a bounded number at a time, then a summary
of what changed against the previous versions (new, unchanged, changed with the diff) and the report.

With ``address`` (``tcp://HOST:PORT``) the stage tasks run on that Dask cluster (a sub-flow with prefect-dask's
``DaskTaskRunner``); without it on threads of this process. The run ends Failed when any recording failed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from prefect import flow
from prefect.client.schemas.objects import State
from prefect.states import Failed

from flows.address import check_address, dask_runner
from flows.chain import ChainSettings, run_chains
from flows.discover import find_recordings
from flows.stages.report import report_task
from flows.summary import RunSummary, finish, summary_of
from flows.task_runner import LocalThreadPoolTaskRunner
from tasks.store import resolve_store_root

DEFAULT_WORKERS = 2
"""Recordings in flight at once by default (this machine has 2 cores; learning is CPU-bound)."""

MAX_THREADS = 32
"""Bound of the thread-pool task runner (Prefect's default is unbounded); ``workers`` bounds the real work."""


THREADS: Any = LocalThreadPoolTaskRunner(max_workers=MAX_THREADS)
"""The archive run's default task runner (typed Any: a TaskRunner is invariant in its future type)."""


@flow(name="reprocess-archive-run", task_runner=THREADS, persist_result=False)
def archive_run(
    archive: str,
    root: str,
    settings: ChainSettings,
    workers: int,
    report: bool,
) -> RunSummary | State[Any]:
    """The archive's recordings through the chain on this flow's task runner, then the report."""
    folder = Path(archive)
    sources = find_recordings(folder)
    entries = run_chains(sources, settings, workers=workers, root=folder)
    html = report_task(root, f"reprocess-archive {folder.name}", entries) if report else None
    return finish(entries, html)


@flow(name="reprocess-archive", persist_result=False)
def reprocess_archive(
    archive: str,
    *,
    store: str | None = None,
    params: dict[str, Any] | None = None,
    grasp: dict[str, Any] | None = None,
    seed: int = 0,
    workers: int = DEFAULT_WORKERS,
    report: bool = True,
    address: str | None = None,
) -> RunSummary | State[Any]:
    """Process every ``*.mcap``, ``*.bag`` and rosbag2 folder under ``archive`` (``workers`` at a time).

    ``params``: learning parameters (``LearnParams``); ``grasp``: the grasp planner's (``PlannerParams``);
    ``address``: a Dask scheduler to run the tasks on. Each recording's descriptor is named by
    ``flows.chain.run_names``.
    """
    root = str(resolve_store_root(store).resolve())
    find_recordings(Path(archive))  # a missing folder fails here, in one line
    settings = ChainSettings(root, dict(params or {}), seed, grasp=dict(grasp or {}))
    run = archive_run
    if address:
        check_address(address)
        run = archive_run.with_options(task_runner=dask_runner(address))
    state: State[Any] = run(archive, root, settings, workers, report, return_state=True)
    summary = summary_of(state)  # FlowError (this run fails with its message) when the run ended without one
    return Failed(message=state.message, data=summary) if state.is_failed() else summary
