"""The flows run in-process against the session's Prefect harness: caching, naming, reports, artifacts."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from prefect import flow, get_client
from prefect.client.schemas.objects import State
from prefect.states import Failed
from prefect.utilities.engine import propose_state_sync

from flows.caching import results_dir
from flows.content_ids import MEMO_FILENAME
from flows.process_recording import process_recording
from flows.reprocess_archive import reprocess_archive
from flows.stages import ingest as ingest_module
from flows.stages import learn as learn_module
from flows.stages import simulate as simulate_module
from flows.summary import RunSummary, finish, summary_of
from tasks.report.refs import EntryResult
from tasks.store import Store
from tasks.synth.record import synthesize
from tests.flows.recordings import write_door_recording
from tests.flows.test_stage_tasks import CallCounter, count_calls


@pytest.fixture
def archive(tmp_path: Path) -> Path:
    """Two door demonstrations (MCAP and rosbag2) without object models or scene instance (learning is quick, no
    simulation), and a simulated sliding-door demonstration (``pbd synth``: object model, grasp, simulation)."""
    folder = tmp_path / "archive"
    folder.mkdir()
    write_door_recording(folder / "door-a.mcap", "mcap", 1.2, seed=1, with_model=False)
    write_door_recording(folder / "nested" / "door-b", "rosbag2", 0.9, seed=2, with_model=False)
    synthesize("sliding-door", 3, folder / "slide.mcap")
    return folder


STAGES = ("ingest_recording", "segment_recording", "fit_segments", "plan_recording_grasp", "simulate_descriptor")
"""The stage functions the task wrappers call, in pipeline order."""


def runs(calls: CallCounter) -> list[int]:
    """How often each of ``STAGES`` ran."""
    return [calls[s] for s in STAGES]


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> CallCounter:
    """Counts of real stage executions inside the task wrappers."""
    counter: CallCounter = Counter()
    count_calls(monkeypatch, ingest_module, "ingest_recording", counter)
    for stage in STAGES[1:4]:
        count_calls(monkeypatch, learn_module, stage, counter)
    count_calls(monkeypatch, simulate_module, "simulate_descriptor", counter)
    return counter


@pytest.mark.slow
def test_unchanged_archive_does_no_stage_work_and_a_change_reruns_what_follows_it(
    prefect_harness: None, archive: Path, tmp_path: Path, calls: CallCounter
) -> None:
    store = tmp_path / "store"
    first = reprocess_archive(str(archive), store=str(store), workers=2)
    # the doors' recordings name no scene instance: not simulated; the synthesised sliding door is
    assert runs(calls) == [3, 3, 3, 3, 1]
    assert first["counts"] == {"new": 3, "changed": 0, "unchanged": 0, "failed": 0}
    # both doors are open-door by their meta: within one run each gets its path
    names = ["open-door--door-a@v1", "open-door--nested-door-b@v1", "slide-sliding-door@v1"]
    assert [e["descriptor"] for e in first["entries"]] == names
    assert [e["simulation_success"] for e in first["entries"]] == [None, None, True]
    assert first["report"] is not None and Path(first["report"]).is_file()
    figures = sorted((store / "reports" / "figures").iterdir())

    again_state = reprocess_archive(str(archive), store=str(store), workers=2, return_state=True)
    again = summary_of(again_state)
    assert runs(calls) == [3, 3, 3, 3, 1]  # all cached
    assert stage_states(again_state) == {}  # every result known: not one stage task submitted
    assert again["counts"] == {"new": 0, "changed": 0, "unchanged": 3, "failed": 0}
    assert Path(again["report"] or "").parent != Path(first["report"]).parent  # a report per run
    assert sorted((store / "reports" / "figures").iterdir()) == figures  # no figure drawn again

    changed = reprocess_archive(str(archive), store=str(store), params={"min_rotation_rad": 1.0}, workers=1)
    # ingest cached, learning re-ran, only the descriptor that changed is simulated again
    assert runs(calls) == [3, 6, 6, 6, 1]
    statuses = {Path(e["source"]).name: e["status"] for e in changed["entries"]}
    # the 0.9 rad door is now below the smallest rotation kept: its chain changes, the 1.2 rad one does not
    assert statuses == {"door-a.mcap": "unchanged", "door-b": "changed", "slide.mcap": "unchanged"}
    diff = next(e["diff"] for e in changed["entries"] if e["status"] == "changed")
    assert any(line.startswith("  removed primitive 0: rotation") for line in diff)
    assert [v.version for v in Store(store).versions("open-door--nested-door-b")] == [1, 2]

    regrasped_state = reprocess_archive(
        str(archive), store=str(store), params={"min_rotation_rad": 1.0}, grasp={"steps": 200}, workers=1,
        return_state=True,
    )  # fmt: skip
    assert runs(calls)[:4] == [3, 6, 6, 9]  # segment and fit cached: the grasp and what follows re-ran
    assert summary_of(regrasped_state)["counts"]["failed"] == 0
    states = stage_states(regrasped_state)  # the graph shows it: segment and fit Cached, grasp Completed
    assert states["segment"] == states["fit"] == Counter({"Cached": 3})
    assert states["grasp"] == Counter({"Completed": 3})


def stage_states(state: State[Any]) -> dict[str, Counter[str]]:
    """Per stage task (the report left out): the final state names of its task runs in the archive's sub-flow
    run, read from the server once the task run events have arrived."""
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import FlowRunFilter, FlowRunFilterId, FlowRunFilterParentFlowRunId

    parent = state.state_details.flow_run_id
    with get_client(sync_client=True) as client:
        (sub,) = client.read_flow_runs(
            flow_run_filter=FlowRunFilter(parent_flow_run_id=FlowRunFilterParentFlowRunId(any_=[parent]))
        )
        for _ in range(60):  # task run states reach the server as events, a moment after the flow returns
            tasks = client.read_task_runs(flow_run_filter=FlowRunFilter(id=FlowRunFilterId(any_=[sub.id])))
            if all(t.state is not None and t.state.is_final() for t in tasks):
                break
            time.sleep(0.5)
    out: dict[str, Counter[str]] = {}
    for t in tasks:
        stage = t.name.rsplit("-", 1)[0]
        if stage != "report" and t.state is not None:
            out.setdefault(stage, Counter())[t.state.name] += 1
    return out


def test_process_recording_names_by_meta_and_leaves_artifacts(prefect_harness: None, tmp_path: Path) -> None:
    from prefect.client.orchestration import get_client

    source = write_door_recording(tmp_path / "demo.bag", "bag", 1.1)  # with an object model: a grasp is planned
    store = tmp_path / "store"
    summary = process_recording(str(source), store=str(store))
    (entry,) = summary["entries"]
    assert entry["descriptor"] == "open-door@v1"  # <action>-<object> from /demo/meta
    desc = Store(store).load("open-door@latest")
    assert [p.kind for p in desc.chain] == ["rotation"]
    assert abs(desc.chain[0].extent - 1.1) < 0.05
    assert desc.object.model_sha256 is not None
    assert (Store(store).models_dir / f"{desc.object.model_sha256}.parquet").is_file()  # stored with it
    with get_client(sync_client=True) as client:
        md = client.read_latest_artifacts()
    by_key = {a.key: a for a in md}
    assert "open-door@v1" in str(by_key["pbd-run-summary"].data)
    assert "open-door@v1" in str(by_key["pbd-run-table"].data)
    report = Path(summary["report"] or "")
    assert report.is_file()
    figures = store / "reports" / "figures"
    if desc.grasp is not None:
        assert len(list(figures.glob("*/descriptor-grasp.png"))) == 1
    assert len(list(figures.glob("*/descriptor-axes.mcap"))) == 1
    assert "../figures/" in report.read_text()
    assert f"({report.resolve().as_uri()})" in str(by_key["pbd-report"].data)


def test_an_unknown_parameter_fails_every_recording_and_the_run(
    prefect_harness: None, archive: Path, tmp_path: Path
) -> None:
    state = reprocess_archive(
        str(archive), store=str(tmp_path / "store"), params={"no_such": 1}, report=False, return_state=True
    )
    assert state.is_failed()
    assert state.message is not None and state.message.startswith("3 of 3 recordings failed")
    summary = summary_of(state)
    assert summary["counts"]["failed"] == 3
    assert all("unknown learning parameter(s) no_such" in (e["error"] or "") for e in summary["entries"])


@pytest.mark.slow
def test_cache_survives_a_new_process_and_prefect_home(prefect_harness: None, archive: Path, tmp_path: Path) -> None:
    store = tmp_path / "store"
    reprocess_archive(str(archive), store=str(store), report=False)
    before = {p.name: p.stat().st_mtime_ns for p in results_dir(store).iterdir() if p.name != MEMO_FILENAME}
    env = {k: v for k, v in os.environ.items() if not k.startswith("PREFECT_")}
    env["PREFECT_HOME"] = str(tmp_path / "another-prefect-home")
    cmd = [sys.executable, "-m", "flows.cli", "archive", str(archive), "--store", str(store), "--json", "--no-report"]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=240, check=False)
    assert out.returncode == 0, out.stderr[-2000:]
    summary = json.loads(out.stdout)
    assert summary["counts"]["unchanged"] == 3, summary
    after = {p.name: p.stat().st_mtime_ns for p in results_dir(store).iterdir() if p.name != MEMO_FILENAME}
    assert after == before  # no stage ran: no result record was written or rewritten


@flow(name="pbd-test-one-failed-recording", persist_result=False)
def one_failed_recording() -> RunSummary | State[Any]:
    """A run whose one recording failed: a Failed state holding the summary."""
    return finish([EntryResult(source="takes/take-1.mcap", error="truncated chunk")], None)


def test_a_run_keeps_its_summary_when_the_server_answers_with_its_own_state(prefect_harness: None) -> None:
    state = one_failed_recording(return_state=True)
    run_id = state.state_details.flow_run_id
    assert run_id is not None
    with get_client(sync_client=True) as client:  # a retried final proposal: the run is already final on the server
        answer = propose_state_sync(client, Failed(message=state.message), flow_run_id=run_id)
    assert answer is not state and answer.is_failed() and answer.message == state.message
    summary = summary_of(answer)
    assert summary["counts"]["failed"] == 1 and summary["entries"][0]["error"] == "truncated chunk"
