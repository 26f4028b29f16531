"""Sensor models: rates and noise within the paper's kind of set-up, dropouts in bursts, tracker noise sizes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.ingest.api import ingest_recording
from tasks.recording.load import load_recording
from tasks.store import Store
from tasks.synth.paths import truth_path
from tasks.synth.record import record_scene
from tasks.synth.sensors import (
    MOCAP_HZ_RANGE,
    MOCAP_NOISE_RANGE_M,
    WRIST_HZ_RANGE,
    SensorParams,
    continuous_quats,
    draw_sensor_params,
    dropout_mask,
    observe_tracker,
    sample_times,
)
from tests.synth.scenes import box_model, door_scene


def _runs(mask: np.ndarray) -> list[int]:
    """Lengths of the runs of True in ``mask``."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return [int(v) for v in edges[1::2] - edges[::2]]


def test_drawn_parameters_stay_in_their_ranges() -> None:
    draws = [draw_sensor_params(np.random.default_rng(s)) for s in range(200)]
    hz = np.array([d.mocap_hz for d in draws])
    assert MOCAP_HZ_RANGE[0] <= hz.min() and hz.max() <= MOCAP_HZ_RANGE[1]
    assert hz.max() - hz.min() > 100.0  # the seed really varies the rate
    noise = np.array([d.mocap_noise_m for d in draws])
    assert MOCAP_NOISE_RANGE_M[0] <= noise.min() and noise.max() <= MOCAP_NOISE_RANGE_M[1]
    wrist = np.array([d.wrist_hz for d in draws])
    assert WRIST_HZ_RANGE[0] <= wrist.min() and wrist.max() <= WRIST_HZ_RANGE[1]
    assert all(0.0 <= d.wrist_phase_s < 1.0 / d.wrist_hz for d in draws)
    assert all(0.0015 <= d.wrist_noise_m <= 0.0025 for d in draws)
    assert all(np.radians(0.7) <= d.wrist_noise_rad <= np.radians(1.3) for d in draws)


def test_dropouts_come_in_bursts_of_the_asked_mean_length_and_fraction() -> None:
    hz, fraction, burst_s = 200.0, 0.03, 0.1
    mask = dropout_mask(200_000, hz, fraction, burst_s, np.random.default_rng(0))
    assert mask.mean() == pytest.approx(fraction, rel=0.15)
    runs = _runs(mask)
    assert np.mean(runs) == pytest.approx(burst_s * hz, rel=0.15)  # 20 samples, not the 1.03 of independent drops
    assert not mask[0]


def test_sample_times_keep_the_rate_and_phase() -> None:
    t = sample_times(2.0, 120.0, 0.003)
    assert t[0] == 0.003 and t[-1] <= 2.0
    assert len(t) == 240
    np.testing.assert_allclose(np.diff(t), 1 / 120.0)


def test_tracker_noise_has_the_asked_size() -> None:
    rng = np.random.default_rng(1)
    n = 20_000
    quats = np.tile(Rotation.from_euler("x", 30, degrees=True).as_quat(), (n, 1))
    params = SensorParams(wrist_noise_m=0.002, wrist_noise_rad=np.radians(1.0))
    pos, got = observe_tracker(np.zeros((n, 3)), quats, params, rng)
    assert pos.std(axis=0) == pytest.approx([0.002] * 3, rel=0.05)
    angle = (Rotation.from_quat(got) * Rotation.from_quat(quats).inv()).magnitude()
    assert float(np.sqrt(np.mean(angle**2))) == pytest.approx(np.radians(1.0), rel=0.05)
    assert (np.sum(got[1:] * got[:-1], axis=1) > 0).all()


def test_continuous_quats_flips_signs_only() -> None:
    q = np.array([[0, 0, 0, 1.0], [0, 0, 0, -1.0], [0, 0, 0.1, -0.99]])
    out = continuous_quats(q)
    assert out.tolist() == [[0, 0, 0, 1.0], [0, 0, 0, 1.0], [0, 0, -0.1, 0.99]]


def test_a_recording_has_bursty_dropouts_and_its_rates(tmp_path: Path) -> None:
    path = record_scene(door_scene(11), tmp_path / "d.mcap", "mcap", box_model)
    truth = json.loads(truth_path(path).read_text())
    sensors = truth["sensors"]
    store = Store(tmp_path / "store")
    rec = load_recording(store, ingest_recording(path, store).recording_id)
    period_ns = 1e9 / sensors["mocap_hz"]
    n_all = int(np.floor(truth["recording"]["duration_s"] * sensors["mocap_hz"] + 1e-9)) + 1
    missing, runs = 0, []
    for track in rec.markers.values():
        k = np.round((track.stamps_ns - rec.start_ns) / period_ns).astype(int)
        np.testing.assert_allclose((track.stamps_ns - rec.start_ns) / period_ns, k, atol=1e-3)
        hidden = np.ones(n_all, dtype=bool)
        hidden[k] = False
        missing += int(hidden.sum())
        runs += _runs(hidden)
    assert 0 < missing < 0.1 * n_all * len(rec.markers)
    assert np.mean(runs) > 2.0  # bursts, not single lost samples
    wrist = rec.wrist
    assert wrist is not None
    assert 1e9 / np.median(np.diff(wrist.stamps_ns)) == pytest.approx(sensors["wrist_hz"], rel=1e-3)
    assert WRIST_HZ_RANGE[0] <= sensors["wrist_hz"] <= WRIST_HZ_RANGE[1]
    assert MOCAP_HZ_RANGE[0] <= sensors["mocap_hz"] <= MOCAP_HZ_RANGE[1]
