"""What a flow run returns: counts by status and where the descriptors and the report are."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypedDict, cast

from prefect.client.schemas.objects import State
from prefect.states import Failed

from tasks.errors import PbdError
from tasks.report.refs import EntryResult


class FlowError(PbdError):
    """A flow run ended without a summary (it failed before processing any recording)."""


class RunSummary(TypedDict):
    """A flow run's outcome (JSON-ready): counts by status, one row per recording, the report path."""

    counts: dict[str, int]
    entries: list[dict[str, Any]]
    report: str | None


def summarise(entries: Sequence[EntryResult], report_html: str | None) -> RunSummary:
    """Counts of new / unchanged / changed / failed and a row per recording."""
    counts = Counter(e.status for e in entries)
    rows = []
    for e in entries:
        d = e.descriptor
        sim = e.simulation
        rows.append(
            {
                "source": e.source,
                "status": e.status,
                "descriptor": d.ref if d else None,
                "id": d.id if d else None,
                "path": d.path if d else None,
                "previous": d.previous if d else None,
                "simulation_success": sim.success if sim and sim.skipped is None else None,
                "simulation_skipped": sim.skipped if sim else None,
                "simulation_reached": [a / t if t else None for a, t in zip(sim.achieved, sim.target, strict=False)]
                if sim and sim.skipped is None
                else None,
                "simulation_detail": sim.detail if sim else None,
                "chain": e.extra.get("chain"),
                "diff": (e.diff or {}).get("lines"),
                "error": e.error,
            }
        )
    return {
        "counts": {k: counts.get(k, 0) for k in ("new", "changed", "unchanged", "failed")},
        "entries": rows,
        "report": report_html,
    }


def finish(entries: Sequence[EntryResult], report_html: str | None) -> RunSummary | State[Any]:
    """What a flow returns: the summary, or a Failed state holding it when any recording failed (the others'
    results stay in the store, the summary and the report)."""
    summary = summarise(entries, report_html)
    failed = [e for e in entries if e.status == "failed"]
    if not failed:
        return summary
    first = failed[0]
    msg = f"{len(failed)} of {len(entries)} recordings failed; first: {Path(first.source).name}: {first.error}"
    return Failed(message=msg, data=summary)


def summary_of(state: State[Any]) -> RunSummary:
    """The run summary a flow run's final state holds (Completed or Failed); ``FlowError`` when it holds none."""
    value = state.result(raise_on_failure=False)
    if isinstance(value, dict) and "counts" in value:
        return cast(RunSummary, value)
    msg = f"flow run ended {state.name}: {state.message or value}"
    raise FlowError(msg)
