"""Recordings the stress corpus found hard, each rebuilt from its mechanism: a short closing seen by a tracked
body's orientation, a slide under a camera's correlated depth noise, a door seen by three very noisy markers,
and a hand marker hidden whenever the part moves."""

from __future__ import annotations

import numpy as np
import pytest

from tasks.fit.geometry import angle_between_axes
from tasks.learn.api import learn_chain
from tasks.learn.chain import displaced, marker_kind, rigid_with
from tasks.learn.params import LearnParams
from tasks.segment.tracks import make_track
from tests.learn.test_unseen_recordings import (
    HINGE,
    RNG,
    _door_point,
    _ease,
    _reach_ride_withdraw,
    _recording,
)

VERTICAL = np.array([0.0, 0.0, 1.0])


def test_a_slide_under_correlated_camera_depth_noise_is_one_translation() -> None:
    """A drawer slid 0.5 m, tracked at 30 Hz by a camera looking along the slide: 15 mm of depth noise correlated
    over 80 ms (AR(1)) and 2 mm across. The wander at rest is one sigma of a smoothed coordinate that averages down
    only by the correlation times in its window, not by its samples."""
    rng = RNG(5)
    t = np.arange(0.0, 7.0, 1.0 / 30.0)
    rho = np.exp(-(1.0 / 30.0) / 0.08)
    white = rng.normal(size=(len(t), 3))
    for k in range(1, len(t)):
        white[k] = rho * white[k - 1] + np.sqrt(1.0 - rho**2) * white[k]
    slide = np.array([0.6, 0.8, 0.0])
    across = np.array([[-0.8, 0.6, 0.0], [0.0, 0.0, 1.0]])
    noise = 0.015 * white[:, :1] * slide + 0.002 * white[:, 1:] @ across
    pts = np.array([0.3, 0.1, 0.8]) + np.outer(0.5 * _ease((t - 3.0) / 1.2), slide) + noise
    chain = learn_chain(_recording({"blob": (t, pts)}), LearnParams(), RNG(0)).chain
    assert [p.kind for p in chain] == ["translation"]
    assert abs(chain[0].extent - 0.5) < 0.05


def test_a_door_seen_by_three_very_noisy_markers_keeps_its_hinge_and_its_closing() -> None:
    """Three markers at 12 Hz with 16 mm of noise (40 mm vertical) on a door opened 0.53 rad, then pushed back
    0.28 rad 0.2 s after it stops: the circle fit of so short and noisy an arc can land far from the hinge, the
    part's turn does not; the closing counts until the door rests, wherever the change points cut it, and its few
    samples, which fit a line about as well as an arc, do not overturn the rotation the whole swing showed."""
    for seed in (1, 2, 3, 5):
        t = np.arange(0.0, 9.0, 1.0 / 12.0)
        angle = 0.53 * _ease((t - 2.5) / 3.5) - 0.28 * _ease((t - 6.2) / 0.8)
        rng = RNG(seed)
        scale = np.array([1.0, 1.0, 2.5])
        spots = [(0.88, 0.0), (0.6, 0.3), (0.4, -0.2)]
        markers = {
            f"m{i}": (t, _door_point(angle, r, h) + rng.normal(0.0, 0.016, (len(t), 3)) * scale)
            for i, (r, h) in enumerate(spots)
        }
        chain = learn_chain(_recording(markers), LearnParams(), RNG(0)).chain
        assert [p.kind for p in chain] == ["rotation", "rotation"], seed
        for prim in chain:
            assert angle_between_axes(np.array(prim.dir), VERTICAL, signed=False) < np.radians(8.0), seed
        assert abs(chain[1].extent - 0.28) < 0.08, seed


def test_a_hand_marker_hidden_while_the_door_turns_is_still_the_hand() -> None:
    """A second hand marker, 4 cm from the first, hidden from 2.3 s to 4.7 s (all the while the door turns): never
    seen riding the door, but it moves rigidly with the hand marker that is, both while reaching and withdrawing."""
    markers = _reach_ride_withdraw(60.0, RNG(3))
    t, hand = markers["marker_2"]
    seen = (t < 2.3) | (t > 4.7)
    markers["marker_3"] = (
        t[seen],
        hand[seen] + np.array([0.03, -0.02, 0.02]) + RNG(4).normal(0, 5e-4, (seen.sum(), 3)),
    )
    chain = learn_chain(_recording(markers), LearnParams(), RNG(0)).chain
    (prim,) = chain
    assert prim.kind == "rotation"
    assert abs(prim.extent - 1.0) < 0.05
    assert "marker_3" not in prim.markers
    assert float(np.linalg.norm(np.cross(np.array(prim.pos) - HINGE, VERTICAL))) < 0.01


def test_a_hand_riding_a_door_marker_hidden_mid_swing_keeps_its_distance() -> None:
    """A hand 3 cm off a door marker that the cameras lose for 0.5 s of a 0.8 s swing: interpolated across the
    hole, the door marker would cut the arc's chord, 2 cm inside where the hand rides."""
    t = np.arange(0.0, 2.0, 1.0 / 25.0)
    angle = 0.8 * _ease((t - 0.6) / 0.8)
    door = _door_point(angle, 0.6)
    hand = door + np.array([0.0, 0.0, 0.03])
    seen = (t < 0.75) | (t > 1.25)
    door_track = make_track("door", t[seen], door[seen], 0.002)
    hand_track = make_track("hand", t, hand, 0.002)
    assert rigid_with(hand_track, door_track, 0.6, 1.4, 0.005)


@pytest.mark.parametrize(("hz", "corr_s"), [(15.0, 0.0), (60.0, 0.02)])
def test_a_still_marker_under_noise_is_still_in_nearly_every_short_window(hz: float, corr_s: float) -> None:
    """Windows of 0.45-0.8 s of a resting marker under 5 mm of noise, white at 15 Hz or correlated over 20 ms at
    60 Hz: a line through a handful of samples explains about as much scatter as it pays for,
    so the model choice alone calls many such windows moving; a displacement between the window's parts beyond
    four standard errors is what motion shows."""
    rng = RNG(8)
    t = np.arange(0.0, 60.0, 1.0 / hz)
    noise = rng.normal(0.0, 0.005, (len(t), 3))
    if corr_s > 0.0:
        rho = np.exp(-(1.0 / hz) / corr_s)
        for k in range(1, len(t)):
            noise[k] = rho * noise[k - 1] + np.sqrt(1.0 - rho**2) * noise[k]
    track = make_track("rest", t, np.array([0.3, 0.1, 0.8]) + noise, 0.002)
    starts = np.arange(0.0, 59.0, 0.5)
    kinds = [marker_kind(track, a, a + rng.uniform(0.45, 0.8), 9.0) for a in starts]
    assert sum(k != "still" for k in kinds) <= 2


@pytest.mark.parametrize("hz", [100.0, 240.0])
def test_a_still_marker_from_a_camera_upsampled_by_its_recorder_is_not_displaced(hz: float) -> None:
    """A resting marker seen by a 30 Hz camera under 5 mm of noise and written at 100 or 240 Hz by interpolation:
    the recorder's samples between two frames are no new draws of the noise, so a window's parts average it down
    by their frames, not by their samples (the hand detector's windows test this displacement alone)."""
    rng = RNG(9)
    frames = np.arange(0.0, 60.0, 1.0 / 30.0)
    noise = rng.normal(0.0, 0.005, (len(frames), 3))
    t = np.arange(0.0, 59.9, 1.0 / hz)
    pts = np.column_stack([np.interp(t, frames, noise[:, k]) for k in range(3)]) + np.array([0.3, 0.1, 0.8])
    track = make_track("rest", t, pts, 0.002)
    starts = np.arange(0.0, 59.0, 0.5)
    moved = [displaced(track, a, a + rng.uniform(0.45, 0.8)) for a in starts]
    assert sum(moved) <= 2


def _tracker_filtered(rng: np.random.Generator, t: np.ndarray, sigma: float, corr_s: float) -> np.ndarray:
    """(n, 3) noise (m) of standard deviation ``sigma`` correlated over ``corr_s`` (s) at times ``t`` (AR(1))."""
    rho = np.exp(-np.diff(t, prepend=t[0]) / corr_s)
    noise = rng.normal(0.0, sigma, (len(t), 3))
    for k in range(1, len(t)):
        noise[k] = rho[k] * noise[k - 1] + np.sqrt(1.0 - rho[k] ** 2) * noise[k]
    return noise


@pytest.mark.parametrize(("hz", "corr_s"), [(100.0, 0.07), (240.0, 0.1), (30.0, 0.07)])
def test_a_still_marker_under_a_trackers_filtered_noise_is_not_displaced(hz: float, corr_s: float) -> None:
    """A resting marker under 5 mm of noise that a tracker's filter correlates over 70-100 ms: its wander between
    a window's quarters is noise, which their means average down only by the correlation times they span (counted
    per sample or per camera frame, it passes for motion in a fifth to a half of the windows; the correlation time
    estimated from 60 s is within about a third of the truth, so a few windows still pass)."""
    rng = RNG(10)
    t = np.arange(0.0, 60.0, 1.0 / hz)
    track = make_track("rest", t, np.array([0.3, 0.1, 0.8]) + _tracker_filtered(rng, t, 0.005, corr_s), 0.002)
    starts = np.arange(0.0, 59.0, 0.5)
    moved = [displaced(track, a, a + rng.uniform(0.45, 0.8)) for a in starts]
    assert sum(moved) <= 6


def test_a_slide_under_a_trackers_filtered_noise_is_displaced() -> None:
    """A marker slid 100 mm in 0.6 s (a drawer pulled) at 100 Hz under 5 mm of noise correlated over 70 ms: the
    correlation widens the test, and a slide of twenty noise sigmas still shows in every window over it."""
    rng = RNG(11)
    t = np.arange(0.0, 60.0, 0.01)
    x = 0.1 / 0.6 * np.minimum(t % 1.2, 0.6)
    pts = np.column_stack([x, np.zeros_like(t), np.zeros_like(t)]) + _tracker_filtered(rng, t, 0.005, 0.07)
    track = make_track("slide", t, pts, 0.002)
    assert all(displaced(track, a, a + 0.6) for a in np.arange(0.0, 58.0, 1.2))


def test_a_drawer_whose_noisy_markers_seem_to_turn_is_still_a_translation() -> None:
    """Three markers 4 cm apart on a drawer slid 0.2 m at 14 Hz under 5 mm of noise: their triangle's orientation
    wanders by tenths of a radian, which is no turn the arc of a line would sweep."""
    for seed in (1, 2, 3):
        rng = RNG(seed)
        t = np.arange(0.0, 5.0, 1.0 / 14.0)
        travel = np.outer(0.2 * _ease((t - 2.0) / 0.8), [0.6, 0.8, 0.0])
        spots = [np.array([0.0, 0.0, 0.0]), np.array([0.04, 0.0, 0.0]), np.array([0.0, 0.0, 0.04])]
        markers = {
            f"d{i}": (t, 0.5 + spot + travel + rng.normal(0.0, 0.005, travel.shape)) for i, spot in enumerate(spots)
        }
        chain = learn_chain(_recording(markers), LearnParams(), RNG(0)).chain
        assert [p.kind for p in chain] == ["translation"], seed
