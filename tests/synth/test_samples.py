"""The demo's sample recordings: one small MCAP per built-in scene, written once, and a learning stage that
recovers each true chain from them (scored with ``tasks.synth.score``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tasks.ingest.api import ingest_recording
from tasks.learn.api import learn_chain
from tasks.learn.params import LearnParams
from tasks.recording.load import load_recording
from tasks.scenes.catalog import SCENE_NAMES
from tasks.store import Store
from tasks.synth.paths import truth_path
from tasks.synth.samples import MAX_SAMPLE_BYTES, ensure_sample_recordings, sample_seed
from tasks.synth.score import score_chain


@pytest.fixture(scope="module")
def samples(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """The sample recordings written into an empty folder."""
    return ensure_sample_recordings(tmp_path_factory.mktemp("samples"))


def test_one_small_recording_per_scene_with_its_truth(samples: list[Path]) -> None:
    assert [p.name for p in samples] == [f"{name}.mcap" for name in SCENE_NAMES]
    for path in samples:
        assert 50_000 < path.stat().st_size < MAX_SAMPLE_BYTES
        truth = json.loads(truth_path(path).read_text())
        assert truth["scene"] == path.stem
        assert truth["seed"] == sample_seed(path.stem)


def test_written_only_when_missing(samples: list[Path]) -> None:
    folder = samples[0].parent
    stamps = {p: p.stat().st_mtime_ns for p in samples}
    truth = truth_path(samples[1])
    text = truth.read_text()
    truth.unlink()
    assert ensure_sample_recordings(folder) == samples
    assert {p: p.stat().st_mtime_ns for p in samples} == stamps
    assert truth.read_text() == text  # the lost truth file came back from an identical re-run
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith(".")) == []


def test_learning_recovers_every_sample_chain(samples: list[Path], tmp_path: Path) -> None:
    store = Store(tmp_path / "store")
    for path in samples:
        truth = json.loads(truth_path(path).read_text())
        rec = load_recording(store, ingest_recording(path, store).recording_id)
        chain = learn_chain(rec, LearnParams(), np.random.default_rng(0)).chain
        score = score_chain([p.to_dict() for p in chain], truth)
        assert score.kinds_right, (path.name, score.learned, score.truth)
        for err in score.errors:
            assert err.direction_deg < 2.0, (path.name, err)
            assert err.position_mm is None or err.position_mm < 5.0, (path.name, err)
            assert abs(err.extent_error) < (2.0 if err.kind == "rotation" else 3.0), (path.name, err)
            # the learned span lies inside the true motion (a slow start may read as still, never the reverse)
            assert err.t_start_s is not None and err.t_start_s > -0.3, (path.name, err)
            assert err.t_end_s is not None and err.t_end_s < 0.3, (path.name, err)


def test_committed_samples_are_what_synth_makes_now(samples: list[Path]) -> None:
    """``data/recordings`` holds the demo's samples; a scene or synth change must come with them re-made
    (``rm data/recordings/* && .venv/bin/pbd demo``), or the demo would run on stale recordings."""
    committed = Path(__file__).resolve().parents[2] / "data" / "recordings"
    for path in samples:
        kept = committed / path.name
        assert kept.is_file(), f"{kept} is missing"
        assert kept.read_bytes() == path.read_bytes(), f"{kept} is stale: re-make the sample recordings"
        assert truth_path(kept).read_text() == truth_path(path).read_text(), f"{truth_path(kept)} is stale"
