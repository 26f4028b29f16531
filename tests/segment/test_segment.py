"""Change points land on known switches; the spectral baseline clusters dense and sparse alike."""

from __future__ import annotations

import numpy as np

from tasks.segment.changepoint import ChangepointParams, search, spans_cost
from tasks.segment.spectral import runs_from_labels, spectral_labels
from tasks.segment.tracks import make_track

HZ = 100.0


def _still_line_circle_still(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """1 s still, 1.5 s straight move along x, 2 s quarter circle in the y-z plane, 1 s still (sharp switches)."""
    t = np.arange(0.0, 5.5, 1.0 / HZ)
    pts = np.zeros((len(t), 3))
    for i, ti in enumerate(t):
        if ti < 1.0:
            pts[i] = [0.0, 0.0, 0.0]
        elif ti < 2.5:
            pts[i] = [0.2 * (ti - 1.0) / 1.5, 0.0, 0.0]
        elif ti < 4.5:
            a = (np.pi / 2) * (ti - 2.5) / 2.0
            pts[i] = [0.2, 0.3 * np.sin(a), 0.3 - 0.3 * np.cos(a)]
        else:
            pts[i] = [0.2, 0.3, 0.3]
    return t, pts + rng.normal(0.0, 0.0005, pts.shape)


def test_changepoint_finds_known_switches() -> None:
    t, pts = _still_line_circle_still(np.random.default_rng(0))
    seg = search([make_track("/m", t, pts, 0.002)], ChangepointParams())
    inner = np.array(seg.bounds_s[1:-1])
    assert len(inner) == 3
    np.testing.assert_allclose(inner, [1.0, 2.5, 4.5], atol=0.03)
    assert seg.bounds_s[0] == 0.0
    assert seg.bounds_s[-1] >= t[-1]


def test_changepoint_shares_switches_across_markers() -> None:
    t, pts = _still_line_circle_still(np.random.default_rng(1))
    other = pts + np.array([0.0, 0.0, 0.1]) + np.random.default_rng(2).normal(0, 0.0005, pts.shape)
    tracks = [make_track("/a", t, pts, 0.002), make_track("/b", t[::2], other[::2], 0.002)]
    seg = search(tracks, ChangepointParams())
    np.testing.assert_allclose(seg.bounds_s[1:-1], [1.0, 2.5, 4.5], atol=0.03)


def test_one_segment_is_cheaper_than_a_cut_inside_a_still_track() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 3.0, 1.0 / HZ)
    track = make_track("/m", t, rng.normal(0.0, 0.0005, (len(t), 3)), 0.002)
    seg = search([track], ChangepointParams())
    assert len(seg.spans) == 1
    whole = spans_cost([track], np.array([0.0]), np.array([3.1]), 9.0)
    halves = spans_cost([track], np.array([0.0, 1.5]), np.array([1.5, 3.1]), 9.0)
    assert whole[0] < halves.sum()


def test_segments_longer_than_the_scored_span_come_back_whole() -> None:
    """A door swung to and fro for 24 s about one hinge is one circle; scoring spans of at most 2 s finds the
    same change points as scoring every span, the subset pass joining the pieces."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 24.0, 1.0 / HZ)
    angle = 0.6 * (1.0 - np.cos(2.0 * np.pi * t / 6.0))
    pts = np.column_stack([0.4 * np.cos(angle), 0.4 * np.sin(angle), np.zeros_like(t)])
    track = make_track("/m", t, pts + rng.normal(0.0, 0.0005, pts.shape), 0.002)
    whole = search([track], ChangepointParams(max_span_s=100.0))
    capped = search([track], ChangepointParams(max_span_s=2.0))
    assert len(whole.spans) == 1
    assert capped.bounds_s == whole.bounds_s


def test_spectral_dense_and_sparse_find_the_two_clusters() -> None:
    rng = np.random.default_rng(4)
    for n in (400, 2400):  # dense eigh below 2000 samples, sparse eigsh above
        t = np.linspace(0.0, 10.0, n)
        pts = np.where((t < 5.0)[:, None], 0.0, 1.0) * np.array([1.0, 0.0, 0.0]) + rng.normal(0, 0.001, (n, 3))
        res = spectral_labels(pts, t, k=2, delta_p_m=0.05, delta_t_s=10.0, rng=np.random.default_rng(0))
        assert res.k == 2
        runs = runs_from_labels(res.labels, t, 0.3)
        assert len(runs) == 2
        assert abs(runs[0][1] - 5.0) < 0.1


def test_spectral_eigengap_picks_k() -> None:
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 9.0, 450, endpoint=False)
    level = np.floor(t / 3.0)
    pts = level[:, None] * np.array([0.5, 0.0, 0.0]) + rng.normal(0, 0.001, (450, 3))
    res = spectral_labels(pts, t, k="auto", delta_p_m=0.05, delta_t_s=30.0, rng=np.random.default_rng(0))
    assert res.k == 3
    assert res.eigenvalues[0] >= res.eigenvalues[1]
