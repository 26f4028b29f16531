"""Learning what the motion shows, not what the sample rate, marker names or noise level would suggest: unnamed
hand markers, open-and-close, camera noise, rigid-body orientations and real tracks at other rates."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from flows.cli import main as pbd
from tasks.fit.geometry import angle_between_axes
from tasks.fit.rotation import fit_rotation
from tasks.learn.api import fit_segments, learn_chain
from tasks.learn.chain import SegmentFit, drop_small
from tasks.learn.params import LearnParams
from tasks.learn.prepare import isolated_jumps, prepare
from tasks.recording.load import MarkerTrack, PoseTrack, RecordingData
from tasks.recording.writer import RecordingWriter
from tests.conftest import REAL
from tests.learn.synthetic import START_NS

RNG = np.random.default_rng
HINGE = np.array([0.2, -0.1, 0.9])


def _ease(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def _stamps(t: np.ndarray) -> np.ndarray:
    return START_NS + np.round(t * 1e9).astype(np.int64)


def _door_point(angle: np.ndarray, radius: float, height: float = 0.0) -> np.ndarray:
    """A point on a door hinged about the vertical axis through ``HINGE`` (m, world)."""
    return HINGE + np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.full_like(angle, height)])


def _hand_path(
    t: np.ndarray,
    handle: np.ndarray,
    *,
    start: np.ndarray,
    reach_s: tuple[float, float],
    reach_bow: np.ndarray,
    withdraw_s: tuple[float, float],
    away: np.ndarray,
    away_bow: np.ndarray | None = None,
) -> np.ndarray:
    """A hand (m, world) that reaches from ``start`` to the handle along a bowed curve over ``reach_s`` (s), rides on
    the handle's path, and withdraws by ``away`` (bowed by ``away_bow``) over ``withdraw_s``."""
    u = _ease((t - reach_s[0]) / (reach_s[1] - reach_s[0]))[:, None]
    reach = start + u * (handle[0] - start) + np.sin(np.pi * u) * reach_bow
    hand = np.where(t[:, None] < reach_s[1], reach, handle)
    w = _ease((t - withdraw_s[0]) / (withdraw_s[1] - withdraw_s[0]))[:, None]
    bow = np.zeros(3) if away_bow is None else away_bow
    return np.where(t[:, None] >= withdraw_s[0], handle[-1] + w * away + np.sin(np.pi * w) * bow, hand)


def _reach_ride_withdraw(hz: float, rng: np.random.Generator) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Two door markers and an unnamed hand marker: the hand reaches along a curve while the door rests (0-2 s),
    rides 3 cm off the handle while the door turns 1 rad (2.5-4.5 s) and withdraws along another curve (5-6.5 s)."""
    t = np.arange(0.0, 7.0, 1.0 / hz)
    angle = 1.0 * _ease((t - 2.5) / 2.0)
    door = {"marker_0": _door_point(angle, 0.6), "marker_1": _door_point(angle, 0.45, 0.2)}
    handle = _door_point(angle, 0.6) + np.array([0.0, 0.0, 0.03])
    start = handle[0] + np.array([-0.4, -0.3, -0.2])
    hand = _hand_path(
        t,
        handle,
        start=start,
        reach_s=(0.0, 2.0),
        reach_bow=np.array([0.0, 0.12, 0.1]),
        withdraw_s=(5.0, 6.5),
        away=np.array([-0.3, 0.4, 0.1]),
        away_bow=np.array([0.1, 0.0, 0.1]),
    )
    markers = {**door, "marker_2": hand}
    return {n: (t, p + rng.normal(0.0, 0.0005, p.shape)) for n, p in markers.items()}


def _recording(
    markers: dict[str, tuple[np.ndarray, np.ndarray]], poses: dict[str, PoseTrack] | None = None
) -> RecordingData:
    tracks = {n: MarkerTrack(n, _stamps(t), p) for n, (t, p) in markers.items()}
    return RecordingData("unseen", Path("unseen"), {"start_ns": START_NS}, tracks, poses or {}, None, {})


@pytest.mark.parametrize("hz", [20.0, 120.0])
def test_an_unnamed_hand_markers_reach_and_withdrawal_are_dropped(hz: float) -> None:
    rec = _recording(_reach_ride_withdraw(hz, RNG(3)))
    result = learn_chain(rec, LearnParams(), RNG(0))
    (prim,) = result.chain
    assert prim.kind == "rotation"
    assert abs(prim.extent - 1.0) < 0.05
    assert angle_between_axes(np.array(prim.dir), np.array([0.0, 0.0, 1.0])) < np.radians(2.0)
    assert 2.2 < prim.t_start < 2.9 and 4.1 < prim.t_end < 4.8


def test_pbd_learn_on_a_written_recording_drops_an_unnamed_hands_reach(tmp_path: Path) -> None:
    path = tmp_path / "unnamed.mcap"
    with RecordingWriter(path, "mcap") as writer:
        for name, (t, p) in _reach_ride_withdraw(60.0, RNG(5)).items():
            writer.add_points(f"/mocap/{name}", _stamps(t), p)
    out = tmp_path / "d.json"
    assert pbd(["learn", str(path), "--store", str(tmp_path / "store"), "--out", str(out)]) == 0
    chain = json.loads(out.read_text())["chain"]
    assert [p["kind"] for p in chain] == ["rotation"]


@pytest.mark.parametrize("noise_m", [0.0002, 0.01])
def test_a_drawer_opened_and_closed_gives_two_translations_of_opposite_sense(noise_m: float) -> None:
    t = np.arange(0.0, 6.0, 1.0 / 30.0)
    travel = 0.3 * (_ease((t - 1.0) / 1.5) - _ease((t - 3.0) / 1.5))
    pts = np.array([0.5, 0.1, 0.7]) + np.outer(travel, [0.6, 0.8, 0.0])
    rec = _recording({"tag": (t, pts + RNG(1).normal(0.0, noise_m, pts.shape))})
    chain = learn_chain(rec, LearnParams(), RNG(0)).chain
    assert [p.kind for p in chain] == ["translation", "translation"]
    opening, closing = chain
    assert float(np.dot(opening.dir, [0.6, 0.8, 0.0])) > 0.99
    assert float(np.dot(closing.dir, [0.6, 0.8, 0.0])) < -0.99
    for prim in chain:
        assert abs(prim.extent - 0.3) < max(0.01, 3.0 * noise_m)


@pytest.mark.parametrize("hz", [10.0, 30.0, 120.0])
def test_a_drawer_with_noisy_orientations_opened_and_closed_is_two_translations_at_any_rate(hz: float) -> None:
    """A camera-tracked drawer (poses with 2 mm and 3 degrees of noise per frame) opened and closed: the
    orientations' scatter, whose range widens with the number of frames, is no turn."""
    t = np.arange(0.0, 4.0, 1.0 / hz)
    travel = 0.3 * (_ease((t - 0.5) / 1.2) - _ease((t - 2.2) / 1.2))
    rng = RNG(8)
    pos = np.array([0.5, 0.1, 0.7]) + np.outer(travel, [0.6, 0.8, 0.0]) + rng.normal(0.0, 0.002, (len(t), 3))
    quats = Rotation.from_rotvec(rng.normal(0.0, np.radians(3.0), (len(t), 3))).as_quat()
    pose = PoseTrack("/drawer", "markers", _stamps(t), pos, quats)
    rec = RecordingData("drawer", Path("drawer"), {"start_ns": START_NS}, {}, {"/drawer": pose}, None, {})
    chain = learn_chain(rec, LearnParams(), RNG(0)).chain
    assert [p.kind for p in chain] == ["translation", "translation"]
    assert float(np.dot(chain[0].dir, [0.6, 0.8, 0.0])) > 0.97
    assert float(np.dot(chain[1].dir, [0.6, 0.8, 0.0])) < -0.97


def test_a_camera_noisy_door_swung_open_and_shut_is_two_rotations() -> None:
    t = np.arange(0.0, 8.0, 1.0 / 30.0)
    angle = 1.2 * (_ease((t - 1.0) / 2.0) - _ease((t - 4.5) / 2.0))
    pts = _door_point(angle, 0.5)
    rec = _recording({"blob": (t, pts + RNG(2).normal(0.0, 0.012, pts.shape))})
    chain = learn_chain(rec, LearnParams(), RNG(0)).chain
    assert [p.kind for p in chain] == ["rotation", "rotation"]
    assert float(np.dot(chain[0].dir, [0.0, 0.0, 1.0])) > 0.98
    assert float(np.dot(chain[1].dir, [0.0, 0.0, 1.0])) < -0.98
    for prim in chain:
        assert abs(prim.extent - 1.2) < 0.15
        assert max(prim.fit["radii_m"]) == pytest.approx(0.5, abs=0.03)


def test_a_tracked_bodys_orientation_gives_each_swing_of_a_real_camera_tracked_door() -> None:
    rows = np.loadtxt(REAL / "sturm" / "articulation_models" / "door.txt")
    t = np.arange(len(rows)) / 30.0
    pose = PoseTrack("/tag", "markers", _stamps(t), rows[:, :3], rows[:, 3:7])
    rec = RecordingData("door", Path("door"), {"start_ns": START_NS}, {}, {"/tag": pose}, None, {})
    chain = learn_chain(rec, LearnParams(), RNG(0)).chain
    hinge = np.array([-0.025, 0.866, 0.5])
    assert [p.kind for p in chain] == ["rotation"] * 8
    signs = [float(np.sign(np.dot(p.dir, hinge))) for p in chain]
    assert signs == [signs[0], -signs[0]] * 4
    for prim in chain:
        assert angle_between_axes(np.array(prim.dir), hinge, signed=False) < np.radians(10.0)
        assert prim.markers == ("/tag",)
        assert prim.fit["evidence"] == ["positions", "orientations"]


def _resampled(points: np.ndarray, hz_from: float, hz_to: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(len(points)) / hz_from
    grid = np.arange(0.0, t[-1], 1.0 / hz_to)
    return grid, np.column_stack([np.interp(grid, t, points[:, i]) for i in range(3)])


@pytest.mark.parametrize("trial", ["002", "007"])
def test_a_real_dishwasher_opening_is_one_rotation_at_every_rate(trial: str) -> None:
    pts = np.loadtxt(REAL / "sturm" / "second_set_dishwasher" / f"{trial}.log")
    radii = []
    for hz in (10.0, 30.0, 100.0):
        chain = learn_chain(_recording({"/gripper": _resampled(pts, 30.0, hz)}), LearnParams(), RNG(0)).chain
        assert [p.kind for p in chain] == ["rotation"], hz
        radii.append(max(chain[0].fit["radii_m"]))
    assert np.ptp(radii) < 0.03
    assert all(0.62 < r < 0.70 for r in radii)


def test_orientations_of_a_rigid_body_are_the_evidence_the_fit_names() -> None:
    t = np.arange(0.0, 5.0, 0.02)
    angle = 0.8 * _ease((t - 1.0) / 2.5)
    pts = _door_point(angle, 0.4) + RNG(4).normal(0.0, 0.0005, (len(t), 3))
    quats = Rotation.from_rotvec(np.outer(angle, [0.0, 0.0, 1.0])).as_quat()
    pose = PoseTrack("/body", "markers", _stamps(t), pts, quats)
    with_pose = RecordingData("p", Path("p"), {"start_ns": START_NS}, {}, {"/body": pose}, None, {})
    (prim,) = learn_chain(with_pose, LearnParams(), RNG(0)).chain
    assert prim.fit["evidence"] == ["positions", "orientations"]
    (plain,) = learn_chain(_recording({"/body": (t, pts)}), LearnParams(), RNG(0)).chain
    assert plain.fit["evidence"] == ["positions"]


@pytest.mark.parametrize(("hz", "noise_m"), [(15.0, 0.008), (100.0, 0.0005), (240.0, 0.002)])
def test_one_sample_tracking_glitches_are_dropped_and_real_motion_kept(hz: float, noise_m: float) -> None:
    """A slider moved 0.5 m in 1.2 s whose marker jumps 3 to 5 cm (at least 10 noise sigmas) for single frames (a
    swapped or mis-triangulated marker): the glitches are dropped with a warning, every sample of the motion is kept,
    and the chain is the one translation."""
    rng = RNG(12)
    t = np.arange(0.0, 4.0, 1.0 / hz)
    travel = 0.5 * _ease((t - 1.0) / 1.2)
    pts = np.array([0.3, 0.2, 0.8]) + np.outer(travel, [1.0, 0.0, 0.0]) + rng.normal(0.0, noise_m, (len(t), 3))
    glitches = np.sort(rng.choice(np.arange(3, len(t) - 3), size=3, replace=False))
    jump = rng.normal(size=(len(glitches), 3))
    size = np.maximum(10.0 * noise_m, rng.uniform(0.03, 0.05, (len(glitches), 1)))
    pts[glitches] += jump / np.linalg.norm(jump, axis=1, keepdims=True) * size
    assert isolated_jumps(t, pts)[glitches].all()
    assert isolated_jumps(t, pts).sum() == len(glitches)
    result = learn_chain(_recording({"marker_7": (t, pts)}), LearnParams(), RNG(0))
    assert [p.kind for p in result.chain] == ["translation"]
    assert abs(result.chain[0].extent - 0.5) < max(0.01, 4.0 * noise_m)
    assert any("isolated jumps dropped" in w for w in result.warnings)


@pytest.mark.parametrize(("hz", "noise_m"), [(10.0, 0.0015), (120.0, 0.0005), (240.0, 0.002)])
def test_a_glitch_on_the_first_or_last_sample_is_dropped_not_learned(hz: float, noise_m: float) -> None:
    """A door swung 0.6 rad about a hinge 0.5 m away, its recording ending (and starting) on a sample 4 cm off the
    path: no later sample can bring the marker back, so the glitch would read as a last step of motion. Both ends
    are dropped, no other sample is, and the chain is the one rotation with its extent."""
    rng = RNG(21)
    t = np.arange(0.0, 4.0, 1.0 / hz)
    angle = 0.6 * _ease((t - 1.0) / 1.5)
    pts = _door_point(angle, 0.5) + rng.normal(0.0, noise_m, (len(t), 3))
    pts[0] += np.array([0.0, 0.04, 0.0])
    pts[-1] += np.array([0.03, 0.0, -0.03])
    jumps = isolated_jumps(t, pts)
    assert jumps[0] and jumps[-1] and jumps.sum() == 2
    (prim,) = learn_chain(_recording({"marker_2": (t, pts)}), LearnParams(), RNG(0)).chain
    assert prim.kind == "rotation"
    assert abs(prim.extent - 0.6) < 0.03


def test_a_still_marker_at_exactly_zero_noise_has_no_jumps() -> None:
    """A marker written with no noise at all (a simulator's exact track) has zero robust scatter; a straight
    constant-speed path is then no jump anywhere, ends included."""
    t = np.arange(0.0, 2.0, 0.01)
    pts = np.outer(t, [0.1, 0.0, 0.0])
    assert not isolated_jumps(t, pts).any()


@pytest.mark.parametrize("cut_s", [4.1, 4.3])
def test_a_swing_cut_before_it_ends_keeps_its_own_span_and_no_segments_overlap(cut_s: float) -> None:
    """A door swings 1 rad from 2.5 to 4.5 s while the hand rides on its handle, and the hand withdraws from 4.4 s.
    Given a cut before the swing ends (the last part of the swing shares a segment with the withdrawal), the
    rotation still ends where the door comes to rest, and the segment after it starts there: no two overlap."""
    t = np.arange(0.0, 7.0, 1.0 / 60.0)
    angle = 1.0 * _ease((t - 2.5) / 2.0)
    handle = _door_point(angle, 0.6) + np.array([0.0, 0.0, 0.03])
    away = handle[-1] + _ease((t - 4.4) / 1.5)[:, None] * np.array([-0.3, 0.4, 0.1])
    markers = {"marker_0": _door_point(angle, 0.6), "marker_1": _door_point(angle, 0.45, 0.2)}
    markers["right_hand"] = np.where(t[:, None] >= 4.4, away, handle)
    rng = RNG(1)
    noisy = {n: (t, p + rng.normal(0.0, 0.0005, p.shape)) for n, p in markers.items()}
    result = fit_segments(_recording(noisy), [(0.0, 2.5), (2.5, cut_s), (cut_s, 7.0 + 1e-9)], LearnParams())
    (prim,) = result.chain
    assert prim.kind == "rotation" and abs(prim.extent - 1.0) < 0.03
    assert 4.3 < prim.t_end < 4.6
    for a, b in itertools.pairwise(result.segments):
        assert a.t_end <= b.t_start + 1e-9


def test_a_knob_turned_then_its_door_swung_are_two_rotations() -> None:
    """Two markers on a door's knob (0.5 mm noise, 240 Hz): the knob turns 2 rad about its own axis, rests, and the
    door swings 0.34 rad about its hinge. Both arcs move the same markers, and one circle fits their union only to
    centimetres against the sub-millimetre fits of each: two rotations about two axes."""
    t = np.arange(0.0, 4.0, 1.0 / 240.0)
    knob_turn = 2.0 * _ease((t - 0.7) / 0.8)
    door_turn = 0.34 * _ease((t - 2.05) / 0.85)
    rng = RNG(13)
    markers = {}
    for name, (r, h) in {"marker_11": (0.035, 0.01), "marker_37": (0.05, 0.03)}.items():
        # knob frame: axis along door normal x, marker at radius r in the door plane (y, z), h out of the door
        local = np.column_stack([np.full_like(t, h), r * np.cos(knob_turn), r * np.sin(knob_turn)])
        on_door = local + np.array([0.0, 0.3, 0.0])  # knob 0.3 m from the hinge along the leaf (y)
        rot = Rotation.from_rotvec(np.outer(door_turn, [0.0, 0.0, 1.0]))
        markers[name] = (t, HINGE + rot.apply(on_door) + rng.normal(0.0, 0.0005, (len(t), 3)))
    chain = learn_chain(_recording(markers), LearnParams(), RNG(0)).chain
    assert [p.kind for p in chain] == ["rotation", "rotation"]
    knob, door = chain
    assert angle_between_axes(np.array(knob.dir), np.array([1.0, 0.0, 0.0]), signed=False) < np.radians(3.0)
    assert angle_between_axes(np.array(door.dir), np.array([0.0, 0.0, 1.0]), signed=False) < np.radians(3.0)
    assert abs(knob.extent - 2.0) < 0.1 and abs(door.extent - 0.34) < 0.03


@pytest.mark.parametrize("hz", [12.0, 30.0, 120.0])
def test_a_swing_mostly_hidden_by_an_occlusion_is_one_rotation_of_its_whole_extent(hz: float) -> None:
    """A door marker (0.8 mm noise) is seen for the first fifth of a 0.66 rad swing, then lost until after the door
    has come to rest. What is seen of the motion is a short, nearly straight piece; the rest it reappears at bounds
    the rest of the path, so the swing is one rotation of its whole angle."""
    t = np.arange(0.0, 3.0, 1.0 / hz)
    angle = 0.66 * _ease((t - 0.8) / 1.1)
    rng = RNG(7)
    door = _door_point(angle, 0.32) + rng.normal(0.0, 0.0008, (len(t), 3))
    seen = (t < 1.25) | (t > 1.95)
    fixed = HINGE + np.array([-0.1, 0.05, 0.3]) + rng.normal(0.0, 0.0008, (len(t), 3))
    rec = _recording({"marker_3": (t[seen], door[seen]), "marker_9": (t, fixed)})
    (prim,) = learn_chain(rec, LearnParams(), RNG(0)).chain
    assert prim.kind == "rotation"
    assert abs(prim.extent - 0.66) < 0.05
    off = angle_between_axes(np.array(prim.dir), np.array([0.0, 0.0, 1.0]), signed=False)
    assert off < 3.0 * prim.fit["dir_std_rad"] < np.radians(10.0)  # a few samples at 12 Hz place it to degrees


@pytest.mark.parametrize("noise_m", [0.0001, 0.0003])
def test_a_short_lever_arc_under_low_noise_is_a_rotation_not_a_line(noise_m: float) -> None:
    """A lever handle of 7 cm turns 0.47 rad (a 33 mm arc whose sagitta is 1.9 mm) tracked at 0.1-0.3 mm: the
    arc is far above the noise, and no play of a 7 cm lever strays 2 mm from its circle."""
    t = np.arange(0.0, 2.5, 1.0 / 120.0)
    angle = 0.47 * _ease((t - 0.6) / 0.8)
    rng = RNG(5)
    tip = HINGE + np.column_stack([0.07 * np.cos(angle), np.zeros_like(t), 0.07 * np.sin(angle)])
    mid = HINGE + np.column_stack([0.04 * np.cos(angle), np.full_like(t, 0.01), 0.04 * np.sin(angle)])
    markers = {n: (t, p + rng.normal(0.0, noise_m, p.shape)) for n, p in {"m1": tip, "m2": mid}.items()}
    (prim,) = learn_chain(_recording(markers), LearnParams(), RNG(0)).chain
    assert prim.kind == "rotation"
    assert abs(prim.extent - 0.47) < 0.03
    off = angle_between_axes(np.array(prim.dir), np.array([0.0, 1.0, 0.0]), signed=False)
    assert off < 3.0 * prim.fit["dir_std_rad"] < np.radians(10.0)


@pytest.mark.parametrize("hz", [10.0, 12.0])
def test_an_unnamed_hand_that_withdraws_soon_after_a_drawer_stops_is_dropped(hz: float) -> None:
    """A drawer (a tracked rigid body, 2 mm noise) slides 0.27 m from 3.0 to 3.8 s; two unnamed hand markers reach
    for its handle along a curve, ride with it (7-8 samples), and withdraw from 4.2 s. At 10-12 Hz the change points
    may join the drawer's stop and the withdrawal in one span; the part's rests between them show the hand alone."""
    t = np.arange(0.0, 6.0, 1.0 / hz)
    slide = 0.27 * _ease((t - 3.0) / 0.8)
    body = HINGE + np.column_stack([np.zeros_like(t), -slide, np.zeros_like(t)])
    handle = body + np.array([0.0, -0.05, 0.04])
    start = handle[0] + np.array([-0.35, -0.2, -0.25])
    hand = _hand_path(
        t,
        handle,
        start=start,
        reach_s=(0.8, 2.6),
        reach_bow=np.array([0.0, 0.1, 0.12]),
        withdraw_s=(4.2, 5.0),
        away=np.array([-0.3, -0.1, 0.2]),
    )
    rng = RNG(1)
    markers = {
        "marker_24": (t, hand + rng.normal(0.0, 0.002, hand.shape)),
        "marker_18": (t, hand + np.array([0.02, 0.0, 0.01]) + rng.normal(0.0, 0.002, hand.shape)),
    }
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1))
    pose = PoseTrack("RigidBody1", "markers", _stamps(t), body + rng.normal(0.0, 0.002, body.shape), quat)
    (prim,) = learn_chain(_recording(markers, {"RigidBody1": pose}), LearnParams(), RNG(0)).chain
    assert prim.kind == "translation"
    assert abs(prim.extent - 0.27) < 0.02


@pytest.mark.parametrize("hz", [30.0, 144.0])
def test_a_hand_withdrawing_right_after_a_noisy_door_closes_is_dropped(hz: float) -> None:
    """A door (a rigid body tracked with 15 mm of camera noise) swings open 1 rad and shut again; an unnamed hand
    marker (as noisy) reaches for its handle, rides both swings, and withdraws 23 cm from 0.3 s after the door
    shuts. Under that noise the door's last swing and the withdrawal may share one span; the hand is still told
    by its own motion."""
    t = np.arange(0.0, 8.0, 1.0 / hz)
    angle = 1.0 * _ease((t - 1.5) / 2.0) - 1.0 * _ease((t - 4.0) / 2.0)
    door = _door_point(angle, 0.55)
    handle = _door_point(angle, 0.55) + np.array([0.0, 0.0, 0.04])
    start = handle[0] + np.array([-0.4, -0.3, -0.2])
    hand = _hand_path(
        t,
        handle,
        start=start,
        reach_s=(0.2, 1.3),
        reach_bow=np.array([0.0, 0.12, 0.1]),
        withdraw_s=(6.3, 7.5),
        away=np.array([-0.1, -0.2, 0.05]),
    )
    rng = RNG(4)
    quats = Rotation.from_rotvec(np.outer(angle, [0.0, 0.0, 1.0])).as_quat()
    pose = PoseTrack("Body 3", "markers", _stamps(t), door + rng.normal(0.0, 0.015, door.shape), quats)
    markers = {"rb3/m23": (t, hand + rng.normal(0.0, 0.015, hand.shape))}
    chain = learn_chain(_recording(markers, {"Body 3": pose}), LearnParams(), RNG(0)).chain
    assert [p.kind for p in chain] == ["rotation", "rotation"]
    assert all(abs(p.extent - 1.0) < 0.1 for p in chain)


def test_a_primitive_on_fewer_samples_than_a_model_needs_is_undefined() -> None:
    """Three samples of arc (0.13 s at 15 Hz), however far they swing, support no motion model (a circle passes
    through any three points): the primitive becomes undefined with a note; the same arc over 1 s stays."""
    t = np.arange(0.0, 3.0, 1.0 / 15.0)
    angle = np.clip((t - 1.0) * 0.4, 0.0, 0.4)
    rec = _recording({"a": (t, _door_point(angle, 0.3)), "b": (t, _door_point(angle, 0.2, 0.1))})
    prep = prepare(rec, LearnParams().sigma_floor_m, LearnParams().hand_pattern)
    rf = fit_rotation([_door_point(np.linspace(0.0, 0.4, 3), 0.3)], 0.002)
    for duration, kind in ((0.13, "undefined"), (1.0, "rotation")):
        f = SegmentFit("rotation", 1.0, 1.0 + duration, ("a", "b"), rotation=rf, extent=0.4)
        (out,) = drop_small(prep, [f], 0.015)
        assert out.kind == kind
        assert (kind == "undefined") == out.note.endswith("samples < 4")


@pytest.mark.parametrize("hz", [20.0, 120.0])
def test_an_unnamed_hand_occluded_at_the_end_of_its_withdrawal_is_dropped(hz: float) -> None:
    """The unnamed hand of ``_reach_ride_withdraw`` is lost to the cameras for the last 0.6 s of the recording,
    while it withdraws: the distance it gained from the door before it was lost shows the withdrawal."""
    markers = _reach_ride_withdraw(hz, RNG(3))
    t, hand = markers["marker_2"]
    seen = t < 6.4
    markers["marker_2"] = (t[seen], hand[seen])
    (prim,) = learn_chain(_recording(markers), LearnParams(), RNG(0)).chain
    assert prim.kind == "rotation"
    assert abs(prim.extent - 1.0) < 0.05


def test_a_cap_twisted_open_and_back_in_spans_cut_mid_return_is_two_rotations() -> None:
    """One marker 29 mm from a cap's axis (0.3 mm noise, 160 Hz) turns 2.4 rad open and at once 2.25 rad back.
    Given spans that cut the return in two (the first span holds the opening and half the return), the halves of
    the return are one rotation once the reversal is split: two rotations of opposite sense, each its own extent."""
    t = np.arange(0.0, 2.4, 1.0 / 160.0)
    angle = 2.4 * _ease((t - 0.3) / 0.8) - 2.25 * _ease((t - 1.13) / 0.8)
    cap = HINGE + 0.029 * np.column_stack([np.cos(angle), np.sin(angle), np.zeros_like(t)])
    rec = _recording({"marker_4": (t, cap + RNG(2).normal(0.0, 0.0003, cap.shape))})
    result = fit_segments(rec, [(0.0, 0.45), (0.45, 1.5), (1.5, 2.4 + 1e-9)], LearnParams())
    opening, closing = result.chain
    assert opening.kind == closing.kind == "rotation"
    assert abs(opening.extent - 2.4) < 0.1 and abs(closing.extent - 2.25) < 0.1
    assert np.dot(opening.dir, closing.dir) < -0.99


@pytest.mark.parametrize(("hz", "noise_m"), [(25.0, 0.002), (100.0, 0.003)])
def test_a_lever_whose_markers_travel_unequal_distances_is_a_rotation(hz: float, noise_m: float) -> None:
    """Two markers on a lever, 33 and 70 mm from its spindle, sampled at unequal times under millimetres of noise:
    the lever turns 0.6 rad in 1 s, so one marker travels twice as far as the other. Each marker alone is nearly a line,
    but a sliding part would move both the same distance."""
    rng = RNG(21)
    markers = {}
    for name, (r, lag) in {"marker_2": (0.033, 0.0), "marker_5": (0.070, 0.4 / hz)}.items():
        t = np.arange(lag, 2.0, 1.0 / hz) + rng.uniform(-0.2, 0.2, int(np.ceil((2.0 - lag) * hz))) / hz
        angle = 0.6 * _ease((t - 0.5) / 1.0)
        lever = HINGE + np.column_stack([r * np.cos(angle), np.zeros_like(t), r * np.sin(angle)])
        markers[name] = (np.sort(t), lever[np.argsort(t)] + rng.normal(0.0, noise_m, lever.shape))
    (prim,) = learn_chain(_recording(markers), LearnParams(), RNG(0)).chain
    assert prim.kind == "rotation"
    assert abs(prim.extent - 0.6) < 0.1


@pytest.mark.parametrize("seed", [1, 2])
def test_a_knobs_turn_and_its_doors_swing_seen_by_one_noisy_marker_stay_two_rotations(seed: int) -> None:
    """One marker 4 cm off a knob's axis (45 Hz, 2.6 mm noise): the knob turns 1.5 rad, rests, and the door swings
    0.55 rad. One circle fits the two arcs together about four times worse than each arc's own: the noise is
    already in each arc's residual, so it does not excuse the union's misfit a second time."""
    t = np.arange(0.0, 4.5, 1.0 / 45.0)
    knob_turn = 1.5 * _ease((t - 0.8) / 0.8)
    door_turn = 0.55 * _ease((t - 2.3) / 0.8)
    local = np.column_stack([np.full_like(t, 0.05), 0.04 * np.cos(-knob_turn), 0.04 * np.sin(-knob_turn)])
    on_door = Rotation.from_rotvec(np.outer(door_turn, [0.0, 0.0, 1.0])).apply(local + np.array([0.0, 0.3, 0.0]))
    rec = _recording({"marker_3": (t, HINGE + on_door + RNG(seed).normal(0.0, 0.0026, (len(t), 3)))})
    knob, door = learn_chain(rec, LearnParams(), RNG(0)).chain
    assert knob.kind == door.kind == "rotation"
    for prim, axis in ((knob, [1.0, 0.0, 0.0]), (door, [0.0, 0.0, 1.0])):
        off = angle_between_axes(np.array(prim.dir), np.array(axis), signed=False)
        assert off < 3.0 * prim.fit["dir_std_rad"] < np.radians(20.0)  # some 30 samples of each arc, to degrees
    assert abs(knob.extent - 1.5) < 0.3 and abs(door.extent - 0.55) < 0.25
