"""The command line's conventions: version, verbosity, JSON, listing, diffs of a name's versions, the Dask
address check, the naming rule and the run summary of a failed flow run."""

from __future__ import annotations

import dataclasses
import json
import os
import stat
from pathlib import Path

import pytest
from prefect.states import Completed, Failed

from flows.address import check_address
from flows.chain import run_names
from flows.cli import build_parser, main, set_log_levels
from flows.cli_args import ParameterError
from flows.commands.diff import refs
from flows.commands.ls import listing
from flows.stages.learn import learn_params_of, planner_params_of
from flows.summary import FlowError, summary_of
from tasks.errors import DescriptorError
from tasks.learn.api import name_from_meta
from tasks.simulate.instance import descriptor_instance
from tasks.store import FILE_MODE, Store, write_bytes_atomic
from tests.flows.local_server import free_port
from tests.simulate.objects import DoorSpec


@pytest.fixture
def two_versions(store: Store) -> Store:
    """``open-test-door`` v1 (1.0 rad, seed 1) and v2 (1.2 rad, seed 2)."""
    for extent, seed in ((1.0, 1), (1.2, 2)):
        desc = DoorSpec().descriptor(extent)
        store.put_descriptor(dataclasses.replace(desc, extra_provenance={"seed": seed}))
    return store


def test_version_is_printed(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith("pbd ")


@pytest.mark.parametrize(("flags", "level"), [(["-q"], "ERROR"), ([], "WARNING"), (["-v"], "INFO"), (["-vv"], "DEBUG")])
def test_verbosity_sets_prefects_console_level(monkeypatch: pytest.MonkeyPatch, flags: list[str], level: str) -> None:
    monkeypatch.delenv("PREFECT_LOGGING_HANDLERS_CONSOLE_LEVEL", raising=False)
    monkeypatch.delenv("PREFECT_LOGGING_LEVEL", raising=False)
    monkeypatch.delenv("PREFECT_SERVER_LOGGING_LEVEL", raising=False)
    set_log_levels(build_parser().parse_args(["ls", *flags]))
    assert os.environ["PREFECT_LOGGING_HANDLERS_CONSOLE_LEVEL"] == level


def test_ls_lists_names_then_versions(two_versions: Store, capsys: pytest.CaptureFixture[str]) -> None:
    root = str(two_versions.root)
    assert main(["ls", "--store", root]) == 0
    header, row = capsys.readouterr().out.splitlines()
    assert header.split("\t") == ["name", "versions", "latest", "id", "created"]
    assert row.split("\t")[:3] == ["open-test-door", "2", "open-test-door@v2"]
    assert main(["ls", "open-test-door", "--store", root, "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [(r["ref"], r["seed"]) for r in rows] == [("open-test-door@v1", 1), ("open-test-door@v2", 2)]
    with pytest.raises(DescriptorError, match="no-such: no such descriptor name"):
        listing(two_versions, "no-such")


def test_diff_of_a_name_shows_old_and_new_values(two_versions: Store, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["diff", "open-test-door", "--store", str(two_versions.root)]) == 1  # different
    out = capsys.readouterr().out
    assert out.splitlines()[1] == "  compared: open-test-door@v1 -> open-test-door@v2"
    assert "rotation 0->0: extent 1.0000 -> 1.2000 rad" in out
    assert "parameter seed: 1 -> 2" in out
    assert main(["diff", "open-test-door@v1", "open-test-door@v2", "--store", str(two_versions.root), "--json"]) == 1
    values = json.loads(capsys.readouterr().out)["values"]
    assert values["primitives"][0]["extent"] == [1.0, 1.2]
    assert values["parameters"] == {"seed": [1, 2]}


def test_diff_of_a_name_needs_two_versions(store: Store) -> None:
    with pytest.raises(DescriptorError, match="no-such: no such descriptor name"):
        refs(store, "no-such", None)
    store.put_descriptor(DoorSpec().descriptor(1.0))
    with pytest.raises(DescriptorError, match="open-test-door: only one version"):
        refs(store, "open-test-door", None)


def test_a_bad_dask_address_is_one_line() -> None:
    with pytest.raises(ParameterError, match=r"--address 'http://x': expected tcp://HOST:PORT"):
        check_address("http://x")
    closed = f"tcp://127.0.0.1:{free_port()}"
    with pytest.raises(ParameterError, match=rf"--address {closed}: no Dask scheduler answers there"):
        check_address(closed)


def test_unknown_stage_parameters_are_named() -> None:
    with pytest.raises(ParameterError, match=r"unknown grasp parameter\(s\) no_such \(known: "):
        planner_params_of({"no_such": 1})
    with pytest.raises(ParameterError, match=r"unknown learning parameter\(s\) x"):
        learn_params_of({"x": 1})
    assert planner_params_of({"steps": 300}).steps == 300


def test_one_naming_rule_and_unique_names_within_a_run(tmp_path: Path) -> None:
    assert name_from_meta({"action": "open", "object": "micro wave"}, "x/take-1.mcap") == "open-micro-wave"
    assert name_from_meta({}, "x/take-1.bag") == "take-1"
    assert name_from_meta({}, None) is None
    a, b, c = tmp_path / "k" / "a.mcap", tmp_path / "b.bag", tmp_path / "c.mcap"
    meta = {"action": "open", "object": "door"}
    names = run_names([a, b, c], {a: meta, b: meta, c: {"action": "slide", "object": "drawer"}}, tmp_path)
    assert names == {a: "open-door--k-a", b: "open-door--b", c: "slide-drawer"}


def test_the_scene_instance_comes_from_provenance_else_the_recording() -> None:
    assert descriptor_instance({"scene": {"name": "microwave", "seed": 1}}, None) == ("microwave", 1)
    assert descriptor_instance({}, {"scene": "door", "seed": 4}) == ("door", 4)
    assert descriptor_instance({}, None) == (None, None)


def test_a_failed_run_holds_its_summary() -> None:
    summary = {"counts": {"failed": 1}, "entries": [], "report": None}
    assert summary_of(Failed(message="1 of 1 recordings failed", data=summary)) == summary
    assert summary_of(Completed(data=summary)) == summary
    with pytest.raises(FlowError, match="flow run ended Failed: boom"):
        summary_of(Failed(message="boom"))


def test_store_files_honour_the_umask(tmp_path: Path) -> None:
    mask = os.umask(0o022)
    os.umask(mask)
    path = tmp_path / "x.json"
    write_bytes_atomic(path, b"{}")
    assert stat.S_IMODE(path.stat().st_mode) == FILE_MODE == 0o666 & ~mask
