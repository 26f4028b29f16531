"""A part's turn read from markers at different distances from its axis: each marker's angle weighs by its squared
radius where the angle is measured (an angle's noise is the marker's noise over its radius), so a marker resting
near the axis, whose angle is its noise alone, does not move the part's turn."""

from __future__ import annotations

import numpy as np

from tasks.fit.rotation import RotationFit
from tasks.learn.boundaries import part_coordinate
from tasks.learn.chain import SegmentFit, refine_extents
from tasks.learn.prepare import PreparedRecording
from tasks.segment.tracks import make_track

Z = np.array([0.0, 0.0, 1.0])
ORIGIN = np.zeros(3)


def _turn(t: np.ndarray, radius: float, angle: np.ndarray) -> np.ndarray:
    return np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.full(len(t), 0.8)])


def _rotation(radii: tuple[float, ...]) -> RotationFit:
    return RotationFit(ORIGIN, Z, 0.5, radii, 0.001, 0.01, 0.001, 0.0, 40)


def test_a_marker_near_the_axis_while_the_part_turns_does_not_steer_its_angle() -> None:
    """Over 0-2 s a door marker 0.2 m from the axis turns 0.5 rad while a marker 5 mm from the axis scatters by
    3 mm (its angle swings by radians); later in the recording the second marker is 0.5 m away (a hand that
    left), which must not give it the weight of a 0.5 m radius inside the span."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 6.0, 0.02)
    turn = 0.5 * np.clip(t / 2.0, 0.0, 1.0)
    door = _turn(t, 0.2, turn)
    near = _turn(t, 0.005, np.zeros(len(t))) + rng.normal(0.0, 0.003, (len(t), 3))
    near[t >= 2.0] += np.array([0.5, 0.0, 0.0])
    tracks = (make_track("door", t, door, 0.002), make_track("near", t, near, 0.002))
    fit = SegmentFit("rotation", 0.0, 2.0, ("door", "near"), rotation=_rotation((0.2, 0.005)))
    grid = t[t < 2.0]
    got = part_coordinate(fit, list(tracks), grid)
    assert got is not None
    coord, _ = got
    seen = np.isfinite(coord)
    moved = coord[seen] - coord[seen][0]
    truth = turn[t < 2.0][seen] - turn[t < 2.0][seen][0]
    assert seen.sum() > 90
    assert float(np.max(np.abs(moved - truth))) < 0.05


def test_a_turn_is_not_pulled_by_a_marker_resting_near_the_axis() -> None:
    """A lid turned 0.5 rad, read from a marker 0.2 m out and one 5 mm from the axis that moves from one side of
        the axis to the other (half a turn of noise): the turn, read between the first and the last 50 ms, stays within
    0.02 rad of 0.5."""
    t = np.arange(0.0, 2.0, 0.02)
    turn = 0.5 * t / 2.0
    lid = _turn(t, 0.2, turn)
    near = _turn(t, 0.005, np.pi * (t >= 1.0))
    prep = PreparedRecording((make_track("lid", t, lid, 0.002), make_track("near", t, near, 0.002)), frozenset(), ())
    fit = SegmentFit("rotation", 0.0, 2.01, ("lid", "near"), rotation=_rotation((0.2, 0.005)))
    (out,) = refine_extents(prep, [fit])
    assert abs(out.extent - 0.5) < 0.02
