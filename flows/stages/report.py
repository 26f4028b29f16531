"""Prefect wrapper of the report: writes ``<store>/reports/<run id>/`` and the run's artifacts.

Not cached: every run gets its own report (whose figures are drawn once per content, ``tasks.report.build``).
Leaves on the flow run a table artifact (one row per recording), a markdown artifact that stands on its own
(counts, the table, failures, what changed) and a link artifact to the HTML report.
"""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from pathlib import Path

from prefect import task
from prefect.artifacts import create_link_artifact, create_markdown_artifact, create_table_artifact
from prefect.cache_policies import NO_CACHE
from prefect.runtime import flow_run

from tasks.report.build import write_report
from tasks.report.markdown import summary_rows
from tasks.report.refs import EntryResult
from tasks.store import Store

ARTIFACT_KEY = "pbd-run-summary"
REPORT_LINK_KEY = "pbd-report"
TABLE_KEY = "pbd-run-table"


@task(name="report", cache_policy=NO_CACHE, persist_result=False)
def report_task(store_root: str, title: str, entries: Sequence[EntryResult], run_id: str | None = None) -> str:
    """Write the run's HTML report and Prefect artifacts; returns the path of ``report.html``.

    ``run_id`` names the report folder; by default the id of the flow run.
    """
    run_id = run_id or str(flow_run.get_id() or uuid.uuid4())
    paths = write_report(Store(store_root), run_id, title, list(entries))
    create_markdown_artifact(markdown=paths.markdown, key=ARTIFACT_KEY, description=title)
    create_table_artifact(table=summary_rows(entries), key=TABLE_KEY, description=title)
    create_link_artifact(link=Path(paths.html).resolve().as_uri(), link_text="HTML report", key=REPORT_LINK_KEY)
    return str(paths.html)
