"""What a flow run returns: counts by status and where the descriptors and the report are.

A run's summary travels in its final state's data, in memory (the flows do not persist results). When the
server answers the final state's proposal with the state it already holds (a retried request after SQLite
reported "database is locked", PrefectHQ/prefect#18934, answered REJECT because the run is already final), the
state the engine hands back carries the message but not the data. ``finish`` therefore also keeps the summary
in this process under the flow run's id, and ``summary_of`` reads it from there when the state lacks it.
"""

from __future__ import annotations

import threading
from collections import Counter, OrderedDict
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypedDict, cast
from uuid import UUID

from prefect.client.schemas.objects import State
from prefect.context import FlowRunContext
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


KEPT_RUNS = 64
"""Summaries kept in this process for runs nobody has read yet (one per flow run; a worker runs a few at once)."""

_kept: OrderedDict[UUID, RunSummary] = OrderedDict()
_kept_lock = threading.Lock()


def _keep(summary: RunSummary) -> None:
    """Keep the current flow run's summary in this process (no-op outside a flow run)."""
    context = FlowRunContext.get()
    if context is None or context.flow_run is None:
        return
    with _kept_lock:
        _kept[context.flow_run.id] = summary
        while len(_kept) > KEPT_RUNS:
            _kept.popitem(last=False)


def _kept_for(state: State[Any]) -> RunSummary | None:
    """The summary ``finish`` kept for the flow run ``state`` belongs to, if this process ran it."""
    run_id = state.state_details.flow_run_id if state.state_details else None
    if run_id is None:
        return None
    with _kept_lock:
        return _kept.pop(run_id, None)


def finish(entries: Sequence[EntryResult], report_html: str | None) -> RunSummary | State[Any]:
    """What a flow returns: the summary, or a Failed state holding it when any recording failed (the others'
    results stay in the store, the summary and the report). The summary is also kept for ``summary_of``."""
    summary = summarise(entries, report_html)
    _keep(summary)
    failed = [e for e in entries if e.status == "failed"]
    if not failed:
        return summary
    first = failed[0]
    msg = f"{len(failed)} of {len(entries)} recordings failed; first: {Path(first.source).name}: {first.error}"
    return Failed(message=msg, data=summary)


def summary_of(state: State[Any]) -> RunSummary:
    """The run summary a flow run's final state holds (Completed or Failed), or that ``finish`` kept in this
    process for that run; ``FlowError`` when neither has one."""
    kept = _kept_for(state)
    value = state.result(raise_on_failure=False)
    if isinstance(value, dict) and "counts" in value:
        return cast(RunSummary, value)
    if kept is not None:
        return kept
    msg = f"flow run ended {state.name}: {state.message or value}"
    raise FlowError(msg)
