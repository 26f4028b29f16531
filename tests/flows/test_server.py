"""The README's path on a real Prefect server (SQLite, 127.0.0.1, temporary PREFECT_HOME):
``prefect server start`` → ``pbd serve`` → ``prefect deployment run 'reprocess-archive/nightly' --param archive=...``.

Every process is started here and stopped here by its id, ``pbd serve`` before the server.
"""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tasks.store import Store
from tests.flows.local_server import BIN, LocalServer, deployment_id, flow_runs, local_server, start, stop
from tests.flows.recordings import write_door_recording

pytestmark = [pytest.mark.server, pytest.mark.slow]


@dataclass
class Served:
    """A server with ``pbd serve`` running against it."""

    server: LocalServer
    store: Path
    archive: Path


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    """Server, then ``pbd serve`` (default archive: an empty folder); stopped in reverse order."""
    tmp = tmp_path_factory.mktemp("served")
    store, default_archive = tmp / "store", tmp / "empty-archive"
    default_archive.mkdir()
    with local_server(tmp / "prefect-home") as server:
        log = tmp / "serve.log"
        argv = [str(BIN / "pbd"), "serve", "--store", str(store), "--archive", str(default_archive)]
        serve = start(argv, server.env, log)
        try:
            deployment_id(server.api_url, "reprocess-archive", "nightly")
            deployment_id(server.api_url, "process-recording", "on-demand")
            yield Served(server, store, default_archive)
        finally:
            stop(serve)  # serve before the server


def test_deployment_run_processes_the_archive(served: Served, tmp_path: Path) -> None:
    archive = tmp_path / "nightly-archive"
    archive.mkdir()
    write_door_recording(archive / "door.mcap", "mcap", 1.2, with_model=False)
    argv = [
        str(BIN / "prefect"), "deployment", "run", "reprocess-archive/nightly",
        "--param", f"archive={archive}", "--watch", "--watch-timeout", "180",
    ]  # fmt: skip
    out = subprocess.run(argv, env=served.server.env, capture_output=True, text=True, timeout=240, check=False)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    assert "Completed" in out.stdout + out.stderr
    store = Store(served.store)
    desc = store.load("door@v1")  # named by the recording's path under the archive
    assert [p.kind for p in desc.chain] == ["rotation"]
    assert abs(desc.chain[0].extent - 1.2) < 0.05
    assert len(list(store.reports_dir.glob("*/report.html"))) == 1


def test_the_nightly_schedule_creates_runs(served: Served) -> None:
    import time

    dep = deployment_id(served.server.api_url, "reprocess-archive", "nightly")
    deadline = time.monotonic() + 60
    scheduled: list[dict[str, object]] = []
    while time.monotonic() < deadline and not scheduled:
        scheduled = [r for r in flow_runs(served.server.api_url, dep) if r.get("auto_scheduled")]
        time.sleep(1)
    assert scheduled, "the scheduler created no run for the nightly cron"
    starts = sorted(str(r["expected_start_time"]) for r in scheduled)
    assert all("T03:00:00" in s for s in starts)  # 03:00 UTC, the default cron
    # scheduled runs carry the deployment's default archive, given to ``pbd serve --archive``
    assert all(r["parameters"]["archive"] == str(served.archive) for r in scheduled)  # type: ignore[index]
