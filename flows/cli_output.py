"""How the flow commands show a run: a progress bar on stderr, the summary as a table (rich on a terminal,
tab-separated plain text when stdout is a pipe or a file, never cut to the terminal's width), one line per
failed recording on stderr, and the exit code (0 all processed, 1 some recordings failed)."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from flows.progress import listening
from flows.summary import RunSummary

COLUMNS = ("recording", "status", "descriptor", "id", "chain", "simulation")
"""Columns of the run table."""


@contextmanager
def progress_bar(what: str, *, hidden: bool) -> Iterator[None]:
    """A progress bar of the run's recordings on stderr (none when ``hidden`` or stderr is not a terminal)."""
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    console = Console(stderr=True)
    with Progress(*columns, console=console, transient=True, disable=hidden or not console.is_terminal) as bar:
        task = bar.add_task("starting Prefect", total=None)

        def on_progress(done: int, total: int, label: str) -> None:
            bar.update(task, total=total, completed=done, description=f"{what} ({label or 'queued'})")

        with listening(on_progress):
            yield


def simulation_text(row: dict[str, Any]) -> str:
    """The simulation cell: success or failure and the share of each primitive's extent reached."""
    if row["error"] is not None:
        return "-"
    if row["simulation_success"] is None:
        return f"not simulated ({row['simulation_skipped'] or 'no scene'})"
    reached = " / ".join(f"{r:.0%}" for r in row.get("simulation_reached") or [] if r is not None)
    verdict = "success" if row["simulation_success"] else "failed"
    detail = "" if row["simulation_success"] or not row.get("simulation_detail") else f": {row['simulation_detail']}"
    return f"{verdict} {reached}{detail}" if reached else f"{verdict}{detail}"


def rows_of(summary: RunSummary) -> list[tuple[str, ...]]:
    """One row of ``COLUMNS`` per recording."""
    return [
        (
            Path(row["source"]).name,
            row["status"],
            row["descriptor"] or "-",
            (row["id"] or "-")[:12],
            row.get("chain") or "-",
            simulation_text(row),
        )
        for row in summary["entries"]
    ]


def print_run(summary: RunSummary, title: str, command: str) -> int:
    """Print the run's table and counts on stdout and each failure on stderr; the exit code (1: some failed)."""
    rows = rows_of(summary)
    if sys.stdout.isatty():
        table = Table(title=title)
        for col in COLUMNS:
            table.add_column(col)
        for r in rows:
            table.add_row(*r)
        Console().print(table)
    else:
        sys.stdout.write("\t".join(COLUMNS) + "\n" + "".join("\t".join(r) + "\n" for r in rows))
    counts = summary["counts"]
    done = f"{counts['new']} new, {counts['changed']} changed, {counts['unchanged']} unchanged"
    sys.stdout.write(f"{done}, {counts['failed']} failed\n")
    if summary["report"]:
        sys.stdout.write(f"report: {summary['report']}\n")
    sys.stdout.flush()
    return print_failures(summary, command)


def print_failures(summary: RunSummary, command: str) -> int:
    """One line per failed recording on stderr; 1 when any failed, else 0."""
    failed = [row for row in summary["entries"] if row["status"] == "failed"]
    for row in failed:
        sys.stderr.write(f"pbd {command}: {row['source']}: {row['error']}\n")
    return 1 if failed else 0
