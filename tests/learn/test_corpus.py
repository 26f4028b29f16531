"""The measuring corpora of ``bench/learn_corpus``: truths agree with the generated motion, resampling keeps the
motion, and cases round-trip through the real writer and ingest."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.learn_corpus.case import Case, resample, write_case
from bench.learn_corpus.real import STURM_RADIUS_M, fit_circle_3d, real_cases, turning_points
from bench.learn_corpus.rotations import matrix_from_axis_angle
from bench.learn_corpus.score import score
from bench.learn_corpus.stress import DEV_SEEDS, stress_case
from tasks.ingest.api import ingest_recording
from tasks.recording.load import load_recording
from tasks.store import Store
from tests.conftest import REAL, SHARED


def _at(case: Case, name: str, t: float) -> np.ndarray:
    """Position of stream ``name`` (marker or rigid body) at ``t`` s, linearly interpolated."""
    ts, xyz = case.markers[name] if name in case.markers else case.poses[name][:2]
    ok = np.isfinite(xyz).all(axis=1)
    return np.array([np.interp(t, ts[ok], xyz[ok, k]) for k in range(3)])


def _same_truth(a: Case, b: Case) -> bool:
    return len(a.truth) == len(b.truth) and all(
        p.kind == q.kind and np.array_equal(p.dir, q.dir) and p.extent == q.extent and p.t_start == q.t_start
        for p, q in zip(a.truth, b.truth, strict=True)
    )


@pytest.mark.parametrize("index", range(40))
def test_truth_moves_the_carrier_marker(index: int) -> None:
    case = stress_case(DEV_SEEDS[0], index, clean=True)
    for p in case.truth:
        name = p.radius_marker or next(iter(case.markers | case.poses))
        if p.kind == "translation" and p.radius_marker is None:
            continue
        start, end = _at(case, name, p.t_start), _at(case, name, p.t_end)
        assert p.pos is not None
        moved = matrix_from_axis_angle(p.dir, p.extent) @ (start - p.pos) + p.pos
        rel = start - p.pos
        assert np.linalg.norm(rel - np.dot(rel, p.dir) * p.dir) == pytest.approx(p.radius_m, abs=2e-3)
        assert np.linalg.norm(moved - end) < 2e-3 + 0.02 * p.extent * (p.radius_m or 0.0)


def test_clean_case_differs_from_noisy_only_by_noise() -> None:
    noisy, clean = stress_case(DEV_SEEDS[0], 3), stress_case(DEV_SEEDS[0], 3, clean=True)
    assert _same_truth(noisy, clean) and list(noisy.markers) == list(clean.markers)
    name = next(iter(noisy.markers))
    diff = np.nanstd(noisy.markers[name][1] - clean.markers[name][1], axis=0)
    assert 0 < diff.max() < 3 * noisy.noise_m


def test_resample_keeps_truth_and_motion() -> None:
    case = stress_case(DEV_SEEDS[0], 5, clean=True)
    for hz in (10.0, 100.0):
        again = resample(case, hz)
        assert _same_truth(again, case) and again.hz == hz
        name, (t, xyz) = next(iter(again.markers.items()))
        ok = np.isfinite(xyz).all(axis=1)
        assert np.allclose(np.diff(t), 1.0 / hz)
        expected = np.stack([_at(case, name, float(s)) for s in t[ok][:: max(1, ok.sum() // 20)]])
        assert np.abs(xyz[ok][:: max(1, ok.sum() // 20)] - expected).max() < 0.03


def test_resample_keeps_gaps() -> None:
    t = np.arange(0.0, 2.0, 0.01)
    xyz = np.column_stack([t, 0 * t, 0 * t])
    xyz[80:120] = np.nan
    case = Case("gap", {"m": (t, xyz)}, {}, None, (), 0.0, 100.0)
    t2, xyz2 = resample(case, 30.0).markers["m"]
    lost = ~np.isfinite(xyz2).all(axis=1)
    assert lost.any() and np.all((t2[lost] > 0.79) & (t2[lost] < 1.2))
    assert np.allclose(xyz2[~lost, 0], t2[~lost])


def test_write_case_round_trips_through_ingest(tmp_path: Path, store: Store) -> None:
    case = next(c for i in range(40) if (c := stress_case(DEV_SEEDS[0], i)).poses and c.wrist is not None)
    path = tmp_path / "case.mcap"
    write_case(case, path)
    rec = load_recording(store, ingest_recording(path, store).recording_id)
    for name, (t, xyz) in case.markers.items():
        ok = np.isfinite(xyz).all(axis=1)
        track = rec.markers[name]
        assert np.allclose(track.points, xyz[ok]) and len(track.stamps_ns) == ok.sum()
        assert np.allclose((track.stamps_ns - rec.start_ns) / 1e9, t[ok], atol=1e-9)
    assert set(case.poses) <= set(rec.poses)
    assert rec.wrist is not None and len(rec.wrist.stamps_ns) == len(case.wrist[0])


def test_turning_points_finds_each_reversal() -> None:
    angle = np.radians(np.concatenate([np.linspace(0, 70, 30), np.linspace(70, 2, 30), np.linspace(2, 60, 20)]))
    angle += np.radians(0.5) * np.sin(np.arange(len(angle)))
    found = turning_points(angle, np.radians(10.0))
    assert len(found) == 4 and np.abs(np.array(found) - [0, 29, 59, 79]).max() <= 1


def test_circle_fit_recovers_radius() -> None:
    theta = np.linspace(0.2, 1.4, 50)
    pts = np.column_stack([0.6 * np.cos(theta), 0.6 * np.sin(theta), 0 * theta]) + np.array([0.1, 0.2, 0.3])
    _, normal, radius, rms = fit_circle_3d(pts)
    assert radius == pytest.approx(0.6, abs=1e-9) and rms < 1e-9 and abs(normal[2]) == pytest.approx(1.0)


@pytest.mark.skipif(not REAL.is_dir(), reason="needs ../shared/real")
def test_real_truths(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PBD_SHARED", str(SHARED))  # the shared data the tests found (tests/conftest.py)
    cases = {c.name: c for c in real_cases()}
    door = cases["articulation_models/door"]
    assert [np.sign(p.dir @ door.truth[0].dir) for p in door.truth] == [1, -1] * 4
    assert all(np.radians(50) < p.extent < np.radians(75) for p in door.truth)
    assert abs(door.truth[0].dir @ np.array([-0.03, 0.87, 0.49]) / np.linalg.norm([-0.03, 0.87, 0.49])) > 0.999
    drawer = cases["articulation_models/drawer"]
    assert drawer.kinds == ("translation", "translation") and 0.24 < drawer.truth[0].extent < 0.3
    assert cases["champ/traj2_obj2_rel_obj1"].truth[0].extent == pytest.approx(np.radians(150), abs=0.1)
    for name, case in cases.items():
        mechanism = name.split("/")[1] if name.startswith("mechanisms") else ""
        if mechanism in STURM_RADIUS_M:
            assert case.truth[0].radius_m == pytest.approx(STURM_RADIUS_M[mechanism], abs=0.025)
    wash = [c for n, c in cases.items() if n.startswith("second_set")]
    assert len(wash) == 7 and all(0.63 < (c.truth[0].radius_m or 0) < 0.7 for c in wash)


def test_score_right_and_errors() -> None:
    case = stress_case(DEV_SEEDS[0], 3, clean=True)
    chain = [
        {
            "kind": p.kind,
            "pos": None if p.pos is None else (p.pos + 0.001 * p.dir).tolist(),
            "dir": p.dir.tolist(),
            "extent": p.extent + 0.01,
            "t_start": p.t_start,
            "t_end": p.t_end,
            "fit": {"radii_m": {p.radius_marker: (p.radius_m or 0) + 0.005}} if p.radius_m else {},
        }
        for p in case.truth
    ]
    result = score(chain, case)
    assert result["right"] and result["n_learned"] == len(case.truth)
    row = result["primitives"][0]
    assert row["direction_deg"] == pytest.approx(0.0, abs=1e-6) and row["extent_error"] == pytest.approx(0.01)
    if case.truth[0].kind == "rotation":
        assert row["position_mm"] == pytest.approx(0.0, abs=1e-6) and row["radius_error_mm"] == pytest.approx(5.0)
    flipped = [dict(chain[0], dir=(-np.asarray(chain[0]["dir"])).tolist()), *chain[1:]]
    assert score(flipped, case)["primitives"][0]["direction_deg"] == pytest.approx(180.0)
    assert not score(chain[:-1] if len(chain) > 1 else [], case)["right"]
