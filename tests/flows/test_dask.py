"""``pbd archive DIR --address tcp://HOST:PORT``: the tasks run on an existing Dask cluster (loopback)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from distributed import LocalCluster

from flows.cli import main
from tasks.store import Store
from tests.flows.recordings import write_door_recording


@pytest.fixture
def dask_cluster() -> Iterator[LocalCluster]:
    """A Dask LocalCluster on 127.0.0.1 (threads in this process, so its workers share the harness API URL)."""
    with LocalCluster(
        n_workers=1,
        threads_per_worker=2,
        processes=False,
        protocol="tcp",
        host="127.0.0.1",
        scheduler_port=0,
        dashboard_address=None,
    ) as cluster:
        yield cluster


def test_archive_runs_on_a_dask_cluster(
    prefect_harness: None, dask_cluster: LocalCluster, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dask_address = str(dask_cluster.scheduler_address)
    assert dask_address.startswith("tcp://127.0.0.1:")
    archive = tmp_path / "archive"
    archive.mkdir()
    write_door_recording(archive / "door-1.mcap", "mcap", 1.0, with_model=False)
    write_door_recording(archive / "door-2.bag", "bag", 1.3, with_model=False)
    store = tmp_path / "store"
    code = main(["archive", str(archive), "--store", str(store), "--address", dask_address, "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0, summary
    assert summary["counts"]["new"] == 2
    extents = [Store(store).load(f"open-door--{n}@v1").chain[0].extent for n in ("door-1", "door-2")]
    assert extents == pytest.approx([1.0, 1.3], abs=0.05)
    ran_on_dask = set(dask_cluster.scheduler.task_prefixes)
    stages = {"ingest_task", "segment_task", "fit_task", "grasp_task", "simulate_task", "diff_task"}
    assert stages <= ran_on_dask, ran_on_dask
