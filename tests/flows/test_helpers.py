"""Flow helpers that need no Prefect server: recording discovery, cache keys, retry rule, --param parsing."""

from __future__ import annotations

import errno
import json
import sqlite3
from pathlib import Path

import pytest

from flows.caching import is_transient_io_error, results_dir, stage_key
from flows.cli_args import ParameterError, parse_params
from flows.discover import find_recordings
from tasks.errors import RecordingError, StoreError


def test_find_recordings_lists_files_and_rosbag2_folders(tmp_path: Path) -> None:
    (tmp_path / "a.mcap").write_bytes(b"x")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.bag").write_bytes(b"x")
    bag2 = tmp_path / "sub" / "c_rosbag2"
    bag2.mkdir()
    (bag2 / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (bag2 / "c_0.mcap").write_bytes(b"x")  # storage file of the rosbag2: not a recording of its own
    (tmp_path / "notes.txt").write_text("not a recording")
    found = find_recordings(tmp_path)
    assert found == [tmp_path / "a.mcap", tmp_path / "sub" / "b.bag", bag2]


def test_find_recordings_refuses_a_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="not a folder of recordings"):
        find_recordings(tmp_path / "missing")


def test_stage_key_changes_with_refs_and_params_only() -> None:
    base = stage_key("learn", ("tasks.store",), {"recording": "ab" * 8}, {"t0": 0.05})
    assert base == stage_key("learn", ("tasks.store",), {"recording": "ab" * 8}, {"t0": 0.05})
    assert base.startswith("learn-")
    assert len(base) == len("learn-") + 32
    assert base != stage_key("learn", ("tasks.store",), {"recording": "cd" * 8}, {"t0": 0.05})
    assert base != stage_key("learn", ("tasks.store",), {"recording": "ab" * 8}, {"t0": 0.1})
    assert base != stage_key("learn", ("tasks.store", "tasks.errors"), {"recording": "ab" * 8}, {"t0": 0.05})


def test_results_dir_is_under_the_store(tmp_path: Path) -> None:
    assert results_dir(tmp_path / "store") == (tmp_path / "store" / "prefect-results").resolve()


@pytest.mark.parametrize(
    ("err", "transient"),
    [
        (TimeoutError("slow disk"), True),
        (ConnectionResetError("peer"), True),
        (OSError(errno.EIO, "input/output error"), True),
        (OSError(errno.EAGAIN, "try again"), True),
        (sqlite3.OperationalError("database is locked"), True),
        (FileNotFoundError(errno.ENOENT, "gone"), False),
        (PermissionError(errno.EACCES, "denied"), False),
        (OSError(errno.ENOSPC, "disk full"), False),
        (StoreError("x", "refusing to overwrite"), False),
        (ValueError("a bug"), False),
    ],
)
def test_only_transient_io_errors_are_retried(err: BaseException, transient: bool) -> None:
    assert is_transient_io_error(err) is transient


def test_parse_params_reads_json_values() -> None:
    assert parse_params(["k=3", "t0=0.1", "k2=auto", "flag=true"]) == {"k": 3, "t0": 0.1, "k2": "auto", "flag": True}


def test_parse_params_refuses_missing_equals() -> None:
    with pytest.raises(ParameterError, match="expected KEY=VALUE"):
        parse_params(["t0"])


def test_retry_condition_reads_the_failed_state() -> None:
    from prefect.states import Failed

    from flows.caching import retry_on_transient_io

    assert retry_on_transient_io(None, None, Failed(data=TimeoutError("nfs timeout")))  # type: ignore[arg-type]
    assert not retry_on_transient_io(None, None, Failed(data=StoreError("x", "bad")))  # type: ignore[arg-type]


def test_pbd_archive_refuses_a_missing_folder_before_starting_prefect(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from flows.cli import main

    assert main(["archive", str(tmp_path / "missing"), "--store", str(tmp_path / "store")]) == 2
    assert "not a folder of recordings" in capsys.readouterr().err


def test_pbd_archive_refuses_a_malformed_param(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from flows.cli import main

    assert main(["archive", str(tmp_path), "--param", "t0"]) == 2
    assert "--param 't0': expected KEY=VALUE" in capsys.readouterr().err


@pytest.mark.slow
def test_pbd_demo_runs_the_four_paper_tasks_and_each_succeeds_in_simulation(
    prefect_harness: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``pbd demo`` over the committed sample recordings: the whole pipeline, each task executed in the scene
    instance it was recorded in, a table with the chain and the extent reached, and the report."""
    from flows.cli import main

    samples = Path(__file__).resolve().parents[2] / "data" / "recordings"
    store = tmp_path / "store"
    assert main(["demo", "--store", str(store), "--samples", str(samples)]) == 0
    out = capsys.readouterr().out
    for name, chain in (
        ("unscrew-bottle@v1", "rotation"),
        ("open-door@v1", "rotation"),
        ("open-microwave@v1", "rotation"),
        ("translation", "translation"),
    ):
        assert name in out and chain in out, out
    assert out.count("success 1") + out.count("success 9") == 4, out  # every task reached >= 90 % and succeeded
    assert "4 new, 0 changed, 0 unchanged, 0 failed" in out, out
    assert len(list((store / "reports").glob("*/report.html"))) == 1
    assert sorted(p.name for p in (store / "descriptors").iterdir()) == [
        "open-door",
        "open-microwave",
        "slide-sliding-door",
        "unscrew-bottle",
    ]
    for name in sorted(p.name for p in (store / "descriptors").iterdir()):  # by name alone: the instance it came from
        capsys.readouterr()
        assert main(["simulate", f"{name}@latest", "--store", str(store), "--json"]) == 0, name
        assert json.loads(capsys.readouterr().out)["success"] is True, name
