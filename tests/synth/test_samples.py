"""The demo's sample recordings: one small MCAP per built-in scene, written once, and a learning stage that
recovers each true chain from them (scored with ``tasks.synth.score``)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

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


FLOAT_ABS_TOL = 1e-9
"""Float fields of a committed sample may differ from a fresh one by this much (m, rad, s): numpy and scipy
releases round the last bit of some poses differently (2026-12-01: 9-18 messages a sample, by 1e-16)."""


def _decoded(path: Path) -> list[tuple[str, int, object]]:
    """(topic, log time ns, decoded ROS 2 message) of every message of an MCAP, in log-time order."""
    with path.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(c.topic, m.log_time, d) for _, c, m, d in reader.iter_decoded_messages(log_time_order=True)]


def _close(a: object, b: object) -> bool:
    """Whether two decoded messages (or fields) are equal, floats within ``FLOAT_ABS_TOL``."""
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=0.0, abs_tol=FLOAT_ABS_TOL)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b, strict=True))
    slots = getattr(a, "__slots__", None)
    if slots is not None and type(a).__name__ == type(b).__name__:
        return all(_close(getattr(a, k), getattr(b, k)) for k in slots)
    return a == b


def _close_json(a: object, b: object) -> bool:
    """Whether two parsed JSON values are equal, floats within ``FLOAT_ABS_TOL`` (numpy releases differ in the
    last bits of a float)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close_json(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close_json(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) or isinstance(b, float):
        return isinstance(a, int | float) and isinstance(b, int | float) and math.isclose(a, b, abs_tol=FLOAT_ABS_TOL)
    return a == b


def test_committed_samples_are_what_synth_makes_now(samples: list[Path]) -> None:
    """``data/recordings`` holds the demo's samples; a scene or synth change must come with them re-made
    (``rm data/recordings/* && .venv/bin/pbd demo``), or the demo would run on stale recordings. The same messages
    on the same topics at the same times, their floats equal to within ``FLOAT_ABS_TOL``."""
    committed = Path(__file__).resolve().parents[2] / "data" / "recordings"
    for path in samples:
        kept = committed / path.name
        assert kept.is_file(), f"{kept} is missing"
        fresh, old = _decoded(path), _decoded(kept)
        assert [(t, s) for t, s, _ in old] == [(t, s) for t, s, _ in fresh], f"{kept} is stale: other messages"
        stale = [(t, s) for (t, s, a), (_, _, b) in zip(old, fresh, strict=True) if not _close(a, b)]
        assert not stale, f"{kept} is stale: {len(stale)} messages differ, first {stale[0]}"
        kept_truth, fresh_truth = (json.loads(truth_path(q).read_text()) for q in (kept, path))
        assert _close_json(kept_truth, fresh_truth), f"{truth_path(kept)} is stale"


def test_a_sample_moved_by_a_millimetre_is_stale(samples: list[Path]) -> None:
    """The tolerance of ``_close`` is far below what a scene or synth change moves."""

    def wrist(path: Path) -> object:
        return next(m for t, _, m in _decoded(path) if t == "/wrist/pose")

    message, moved = wrist(samples[0]), wrist(samples[0])  # decoded twice: two objects
    assert _close(message, moved)
    moved.pose.position.x += 0.001  # type: ignore[attr-defined]
    assert not _close(message, moved)
