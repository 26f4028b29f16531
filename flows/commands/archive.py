"""``pbd archive DIR``: the reprocessing flow over every recording in DIR, with a progress bar.

With ``--address tcp://HOST:PORT`` the tasks run on an existing Dask cluster (prefect-dask's DaskTaskRunner);
without it they run concurrently on this machine, ``--workers`` recordings at a time.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from flows.cli_args import parse_params
from flows.discover import find_recordings
from flows.progress import listening
from flows.reprocess_archive import reprocess_archive
from flows.runtime import cli_settings
from tasks.store import resolve_store_root


def _print_summary(summary: dict[str, Any]) -> None:
    console = Console()
    table = Table(title="reprocess-archive")
    for col in ("recording", "status", "descriptor", "id", "simulation"):
        table.add_column(col)
    for row in summary["entries"]:
        sim = row["simulation_success"]
        sim_text = "-" if sim is None else ("success" if sim else "failed")
        if row.get("simulation_skipped"):
            sim_text = "not simulated"
        table.add_row(
            Path(row["source"]).name,
            row["status"] if row["error"] is None else f"failed: {row['error']}",
            row["descriptor"] or "-",
            (row["id"] or "-")[:12],
            sim_text,
        )
    console.print(table)
    counts = summary["counts"]
    console.print(
        f"{counts['new']} new, {counts['changed']} changed, {counts['unchanged']} unchanged, {counts['failed']} failed"
    )
    if summary["report"]:
        console.print(f"report: {summary['report']}")


def run(args: argparse.Namespace) -> int:
    """Run ``reprocess-archive`` over ``args.dir``; exit 0 once the run completed (recordings that failed are listed
    in the summary with their error), 2 for bad arguments (DESCRIPTOR.md)."""

    params = parse_params(args.param)
    find_recordings(args.dir)  # fail fast, before Prefect starts, on a missing folder
    flow = reprocess_archive
    if args.address:
        from prefect_dask.task_runners import DaskTaskRunner  # noqa: PLC0415

        flow = flow.with_options(task_runner=DaskTaskRunner(address=args.address))  # type: ignore[arg-type]
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with cli_settings(), Progress(*columns, transient=args.json, disable=args.json) as progress:
        bar = progress.add_task("starting Prefect", total=None)

        def on_progress(done: int, total: int, label: str) -> None:
            progress.update(bar, total=total, completed=done, description=f"recordings ({label or 'queued'})")

        with listening(on_progress):
            summary = flow(
                archive=str(args.dir.resolve()),
                store=str(resolve_store_root(args.store).resolve()),
                params=params,
                seed=args.seed,
                workers=args.workers,
                report=not args.no_report,
            )
    if args.json:
        sys.stdout.write(json.dumps(summary, indent=2) + "\n")
    else:
        _print_summary(dict(summary))
    return 0  # DESCRIPTOR.md: the run completed; recordings that failed are listed in the summary
