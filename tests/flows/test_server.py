"""The README's path on a real Prefect server (SQLite, 127.0.0.1, temporary PREFECT_HOME):
``prefect server start`` → ``pbd serve`` → ``prefect deployment run 'reprocess-archive/nightly' --param archive=...``.

Every process is started here and stopped here by its id, ``pbd serve`` before the server.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tasks.store import Store
from tests.flows.local_server import (
    BIN,
    LocalServer,
    deployment_id,
    flow_runs,
    free_port,
    local_server,
    start,
    stop,
)
from tests.flows.recordings import write_door_recording

pytestmark = [pytest.mark.server, pytest.mark.slow]

PBD = (sys.executable, "-m", "flows.cli")
"""The pbd command line of this checkout."""


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
        argv = [*PBD, "serve", "--store", str(store), "--archive", str(default_archive)]
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
    desc = store.load("open-door@v1")  # named by the recording's meta
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


def _run_deployment(served: Served, name: str, *params: str) -> subprocess.CompletedProcess[str]:
    argv = [str(BIN / "prefect"), "deployment", "run", name, "--watch", "--watch-timeout", "180"]
    for p in params:
        argv += ["--param", p]
    return subprocess.run(argv, env=served.server.env, capture_output=True, text=True, timeout=240, check=False)


def test_a_failed_recording_fails_the_deployment_run(served: Served, tmp_path: Path) -> None:
    missing = str(tmp_path / "missing.mcap")
    out = _run_deployment(served, "process-recording/on-demand", f"recording={missing}")
    assert out.returncode != 0
    runs = flow_runs(served.server.api_url, deployment_id(served.server.api_url, "process-recording", "on-demand"))
    (ours,) = [r for r in runs if r["parameters"].get("recording") == missing]  # type: ignore[union-attr]
    assert ours["state_type"] == "FAILED"
    assert "1 of 1 recordings failed; first: missing.mcap: ingest: " in str(ours["state"])


def test_the_nightly_deployment_takes_a_dask_address(served: Served, tmp_path: Path) -> None:
    archive = tmp_path / "a"
    archive.mkdir()
    closed = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there: the run fails naming the address
    out = _run_deployment(served, "reprocess-archive/nightly", f"archive={archive}", f"address={closed}")
    assert out.returncode != 0
    runs = flow_runs(served.server.api_url, deployment_id(served.server.api_url, "reprocess-archive", "nightly"))
    (ours,) = [r for r in runs if r["parameters"].get("address") == closed]  # type: ignore[union-attr]
    assert ours["state_type"] == "FAILED"
    assert f"--address {closed}: no Dask scheduler answers there" in str(ours["state"])


def test_the_cli_exits_1_when_a_recording_fails(served: Served, tmp_path: Path) -> None:
    archive = tmp_path / "mixed"
    archive.mkdir()
    write_door_recording(archive / "door.mcap", "mcap", 1.2, with_model=False)
    (archive / "cut.mcap").write_bytes((archive / "door.mcap").read_bytes()[:200])
    argv = [*PBD, "archive", str(archive), "--store", str(tmp_path / "store"), "--no-report"]
    out = subprocess.run(argv, env=served.server.env, capture_output=True, text=True, timeout=240, check=False)
    assert out.returncode == 1, out.stderr[-2000:]
    assert out.stderr.splitlines()[-1].startswith(f"pbd archive: {archive / 'cut.mcap'}: ingest: ")
    assert "1 new, 0 changed, 0 unchanged, 1 failed" in out.stdout
