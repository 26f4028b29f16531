"""The run report: HTML with the plots a person reads, the axes MCAP beside it, the markdown summary."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from schemas.descriptor import Descriptor, Grasp, ObjectRef, Primitive
from tasks.errors import StoreError
from tasks.ingest.api import ingest_recording
from tasks.report.build import write_report
from tasks.report.markdown import summary_markdown
from tasks.report.refs import DescriptorRef, EntryResult, RecordingRef, SimulationRef
from tasks.store import Store
from tests.flows.recordings import HINGE, write_door_recording

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _door_descriptor(recording_id: str, extent: float) -> Descriptor:
    chain = (
        Primitive("rotation", tuple(HINGE), (0.0, 0.0, 1.0), extent, 0.5, 2.5, ("/mocap/door_0",), {"rms_m": 4e-4}),
    )
    grasp = Grasp("barrett", (0.4, -0.1), (0.8, -0.08, 1.2), (0.0, 0.0, 0.0, 1.0), {"epsilon": 0.08})
    return Descriptor("open-door", "open", ObjectRef("door"), grasp, chain, recording_id=recording_id)


def _entry(store: Store, tmp_path: Path, extent: float) -> EntryResult:
    source = write_door_recording(tmp_path / f"door-{extent}.mcap", angle_rad=extent)
    ing = ingest_recording(source, store)
    put = store.put_descriptor(_door_descriptor(ing.recording_id, extent))
    trace = tmp_path / f"trace-{extent}.npz"
    times = np.linspace(0.0, 2.0, 50)
    np.savez(trace, times_s=times, values=(extent * times / 2)[None, :], targets=np.array([extent]),
             names=np.array(["hinge"]), units=np.array(["rad"]))  # fmt: skip
    sim = SimulationRef(put.id, "door", True, (extent,), (extent,), ("hinge",), str(trace), "reached the extent")
    return EntryResult(
        source=str(source),
        recording=RecordingRef(ing.recording_id, str(source)),
        descriptor=DescriptorRef(put.name, put.version, put.id, str(put.path), put.created),
        simulation=sim,
        diff={
            "changed": [{"index_a": 0, "index_b": 0, "kind": "rotation", "axis_angle_deg": 0.5, "axis_offset_mm": 2.0}],
            "lines": ["open-door -> open-door: different", "  rotation 0->0: axis angle 0.500 deg, extent +0.1 rad"],
        }
        if put.version > 1
        else None,
        extra={"chain": "rotation"},
    )


def test_report_has_every_plot_and_the_axes_mcap(store: Store, tmp_path: Path) -> None:
    first = _entry(store, tmp_path, 1.2)
    second = _entry(store, tmp_path, 1.3)  # same name, different content: version 2, "changed"
    assert (first.status, second.status) == ("new", "changed")
    paths = write_report(store, "run-1", "test run", [first, second])
    assert paths.html == store.reports_dir / "run-1" / "report.html"
    page = paths.html.read_text()
    images = re.findall(r"<img src='([^']+)'>", page)
    names = sorted(Path(src).name for src in images)
    kinds = ("trajectories", "timeline", "models", "grasp")
    assert names == sorted([*(f"descriptor-{k}.png" for k in kinds for _ in (1, 2)), "diff-diff.png",
                            *(f"simulation-{k}.png" for k in ("extent", "joint-trace") for _ in (1, 2))])  # fmt: skip
    for src in images:
        assert src.startswith("../figures/")
        assert (paths.folder / src).read_bytes()[:8] == PNG_MAGIC
    assert "open-door@v1 → open-door@v2" in paths.markdown
    assert "rotation 0-&gt;0: axis angle 0.500 deg" in page
    assert "1 new, 1 changed, 0 unchanged, 0 failed" in paths.markdown
    assert len(paths.mcaps) == 2
    reader = make_reader(io.BytesIO(paths.mcaps[0].read_bytes()))
    ((schema, _channel, message),) = list(reader.iter_messages())
    assert schema is not None and schema.name == "foxglove.SceneUpdate"
    entity = json.loads(message.data)["entities"][0]
    assert entity["arrows"][0]["pose"]["position"] == {"x": 0.5, "y": 0.0, "z": 1.0}
    assert (
        message.log_time
        == json.loads((store.recording_dir(first.recording.recording_id) / "recording.json").read_text())["start_ns"]
    )  # type: ignore[union-attr]
    assert not list(store.tmp_dir.iterdir())  # the staging folder was renamed into place


def test_a_second_report_draws_no_figure_again(store: Store, tmp_path: Path) -> None:
    """Each version's figures are drawn once: another run's report of the same entries links the same files."""
    entry = _entry(store, tmp_path, 1.2)
    write_report(store, "run-a", "first", [entry])
    figures = store.reports_dir / "figures"
    drawn = {p: p.stat().st_mtime_ns for p in figures.rglob("*.png")}
    second = write_report(store, "run-b", "again", [entry])
    assert {p: p.stat().st_mtime_ns for p in figures.rglob("*.png")} == drawn
    assert len(drawn) == 6
    assert all((second.folder / src).is_file() for src in re.findall(r"<img src='([^']+)'>", second.html.read_text()))


def test_report_refuses_to_overwrite_a_run(store: Store, tmp_path: Path) -> None:
    entry = _entry(store, tmp_path, 1.2)
    write_report(store, "run-2", "first", [entry])
    with pytest.raises(StoreError, match="a report for this run already exists"):
        write_report(store, "run-2", "again", [entry])


def test_report_lists_a_failed_recording(store: Store) -> None:
    failed = EntryResult(source="/archive/broken.mcap", error="ingest: truncated at byte 10")
    paths = write_report(store, "run-3", "with a failure", [failed])
    assert "failed: ingest: truncated at byte 10" in paths.html.read_text()
    md = summary_markdown("with a failure", [failed], None)
    assert "| broken.mcap | - | - | failed: ingest: truncated at byte 10 | - | - |" in md
    assert "- /archive/broken.mcap: ingest: truncated at byte 10" in md


def test_summary_markdown_escapes_file_names_and_errors() -> None:
    hostile = EntryResult(
        source="/archive/x | y ![img](evil.png) <b>_z_.mcap",
        error="bad `code` [link](u)\n| forged | row |",
    )
    md = summary_markdown("hostile names", [hostile], None)
    row = next(line for line in md.splitlines() if line.startswith("| x"))
    assert row == (
        r"| x \| y \!\[img\](evil.png) \<b\>\_z\_.mcap | - | - | failed: bad \`code\` \[link\](u) \| forged \| "
        r"row \| | - | - |"
    )
    assert md.count("\n| ") == 3  # header, rule and this row: the line break in the error made no row of its own
