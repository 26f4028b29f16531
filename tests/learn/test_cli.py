"""``pbd learn`` end to end: a recording written by the real writer, ingested, learned, stored, printed."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from flows.cli import main
from tasks.store import Store
from tests.learn.synthetic import make_demo, write_recording


@pytest.fixture(scope="module")
def door_mcap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rec") / "door.mcap"
    write_recording(make_demo("door", np.random.default_rng(11), hz=60.0), path)
    return path


def test_learn_stores_a_version_once_and_prints_the_chain(
    door_mcap: Path, store: Store, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "door.json"
    assert main(["learn", str(door_mcap), "--store", str(store.root), "--out", str(out)]) == 0
    first = capsys.readouterr().out.splitlines()
    assert first[0].startswith("open-door@v1 ")
    assert "(new version, 2 primitives)" in first[0]
    assert first[1].strip().startswith("0: rotation")
    assert first[2].strip().startswith("1: rotation")
    doc = json.loads(out.read_text())
    assert doc["name"] == "open-door"
    assert doc["provenance"]["parameters"]["classifier"] == "bic"
    assert main(["learn", str(door_mcap), "--store", str(store.root)]) == 0
    again = capsys.readouterr().out.splitlines()
    assert again[0].startswith("open-door@v1 ") and "(unchanged" in again[0]
    assert [e.version for e in store.versions("open-door")] == [1]
    # the ingested id works as RECORDING too, and other parameters make a new version
    rec_id = store.versions("open-door")[0].recording
    assert rec_id is not None
    code = main(["learn", rec_id, "--store", str(store.root), "--segmenter", "spectral", "--classifier", "eigen",
                 "--k", "7", "--t0", "0.05"])  # fmt: skip
    assert code == 0
    assert capsys.readouterr().out.startswith("open-door@v2 ")


def test_learn_refuses_to_overwrite_out(
    door_mcap: Path, store: Store, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "exists.json"
    out.write_text("{}")
    assert main(["learn", str(door_mcap), "--store", str(store.root), "--out", str(out)]) == 2
    assert "refusing to overwrite an existing file" in capsys.readouterr().err
    assert out.read_text() == "{}"


def test_learn_bad_recording_exits_2(store: Store, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["learn", str(tmp_path / "missing.mcap"), "--store", str(store.root)]) == 2
    assert "no such file or folder, nor an ingested recording id" in capsys.readouterr().err


def test_learn_still_recording_exits_2_naming_the_markers(
    store: Store, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tasks.recording.writer import RecordingWriter

    path = tmp_path / "still.mcap"
    stamps = 1_700_000_000_000_000_000 + np.arange(200, dtype=np.int64) * 10_000_000
    with RecordingWriter(path, "mcap") as w:
        w.add_points("/mocap/box_0", stamps, np.random.default_rng(0).normal(0.0, 0.0003, (200, 3)))
    assert main(["learn", str(path), "--store", str(store.root)]) == 2
    assert "every marker is still (/mocap/box_0)" in capsys.readouterr().err
