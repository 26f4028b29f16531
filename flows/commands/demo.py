"""``pbd demo``: make the sample recordings if missing, run the whole pipeline flow over them, print where the
descriptors and the report are and whether each task succeeded in simulation.

Needs no Prefect server: without ``PREFECT_API_URL`` Prefect starts a temporary one in this process.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from flows.demo import demo
from flows.progress import listening
from flows.runtime import cli_settings
from tasks.store import resolve_store_root


def run(args: argparse.Namespace) -> int:
    """Run the demo flow; 0 when every sample recording was processed."""

    store = resolve_store_root(args.store).resolve()
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with cli_settings(), Progress(*columns) as progress:
        bar = progress.add_task("starting Prefect (ephemeral server)", total=None)

        def on_progress(done: int, total: int, label: str) -> None:
            progress.update(bar, total=total, completed=done, description=f"sample tasks ({label or 'queued'})")

        with listening(on_progress):
            summary = demo(store=str(store), samples=str(args.samples.resolve()), workers=args.workers)

    console = Console()
    table = Table(title=f"pbd demo - store {store}")
    for col in ("recording", "descriptor", "chain", "simulation (extent reached)"):
        table.add_column(col)
    for row in summary["entries"]:
        table.add_row(Path(row["source"]).name, row["descriptor"] or "-", row.get("chain") or "-", _simulation(row))
    console.print(table)
    console.print(f"descriptors: {store / 'descriptors'}")
    console.print(f"report:      {summary['report']}")
    sys.stdout.flush()
    return 0 if summary["counts"]["failed"] == 0 else 1


def _simulation(row: dict[str, Any]) -> str:
    """The simulation cell: success or failure, then the share of each primitive's extent the robot reached."""
    if row["error"] is not None:
        return f"[red]failed: {row['error']}[/red]"
    if row["simulation_success"] is None:
        return f"not simulated ({row['simulation_skipped'] or 'no scene'})"
    reached = " / ".join(f"{r:.0%}" for r in row.get("simulation_reached") or [] if r is not None)
    verdict = "[green]success[/green]" if row["simulation_success"] else "[red]failed[/red]"
    detail = "" if row["simulation_success"] or not row.get("simulation_detail") else f": {row['simulation_detail']}"
    return f"{verdict} {reached}{detail}" if reached else f"{verdict}{detail}"
