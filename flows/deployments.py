"""The served deployments: ``reprocess-archive/nightly`` (cron, archive path as parameter) and
``process-recording/on-demand``. ``prefect.yaml`` describes the same two for work pools and workers."""

from __future__ import annotations

from typing import cast

from prefect.deployments.runner import RunnerDeployment
from prefect.types.entrypoint import EntrypointType

from flows.process_recording import process_recording
from flows.reprocess_archive import DEFAULT_WORKERS, reprocess_archive

NIGHTLY_CRON = "0 3 * * *"
"""Default schedule of the nightly reprocessing: 03:00 every day."""

TIMEZONE = "UTC"


def build_deployments(
    archive: str,
    store: str,
    *,
    cron: str = NIGHTLY_CRON,
    workers: int = DEFAULT_WORKERS,
    address: str | None = None,
) -> list[RunnerDeployment]:
    """The two deployments with their default parameters (absolute paths, so runs find them from anywhere);
    ``address``: the Dask scheduler the nightly run's tasks go to (None: threads of the serving process)."""
    nightly = reprocess_archive.to_deployment(
        name="nightly",
        cron=cron,
        parameters={"archive": archive, "store": store, "workers": workers, "address": address},
        description="Reprocess every recording under the archive folder; report what changed.",
        tags=["pbd"],
        entrypoint_type=EntrypointType.MODULE_PATH,
    )
    on_demand = process_recording.to_deployment(
        name="on-demand",
        parameters={"store": store},
        description="Process one recording: ingest, learn, store, simulate, report.",
        tags=["pbd"],
        entrypoint_type=EntrypointType.MODULE_PATH,
    )
    return [cast(RunnerDeployment, nightly), cast(RunnerDeployment, on_demand)]
