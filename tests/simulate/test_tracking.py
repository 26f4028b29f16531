"""The axis measured from the palm's motion: recovered once the palm has turned enough, ignored before."""

from __future__ import annotations

import math

import numpy as np

from schemas.descriptor import Primitive
from tasks.rotations import matrix_from_quat, quat_from_matrix
from tasks.simulate.tracking import AxisTracker
from tasks.simulate.waypoints import matrix_from_axis_angle

TRUE_POS = np.array([0.5, -0.2, 1.0])
TRUE_DIR = np.array([0.0, 0.0, 1.0])
P0 = np.array([0.9, -0.2, 1.1])
Q0 = quat_from_matrix(matrix_from_axis_angle([1.0, 0.0, 0.0], 0.4))


def _turned(angle: float) -> tuple[np.ndarray, np.ndarray]:
    rot = matrix_from_axis_angle(TRUE_DIR, angle)
    return TRUE_POS + rot @ (P0 - TRUE_POS), quat_from_matrix(rot @ matrix_from_quat(Q0))


def _learned() -> Primitive:
    tilted = matrix_from_axis_angle([1.0, 1.0, 0.0], math.radians(5.0)) @ TRUE_DIR
    pos = TRUE_POS + np.array([0.0, 0.02, 0.0])
    return Primitive("rotation", tuple(pos), tuple(tilted), 1.5)


def test_rotation_axis_recovered_from_the_palm_motion() -> None:
    tracker = AxisTracker(_learned(), P0, Q0)
    fixed = tracker.corrected(*_turned(0.5))
    assert fixed.pos is not None
    assert math.degrees(math.acos(min(1.0, float(np.dot(fixed.dir, TRUE_DIR))))) < 0.01
    off = np.asarray(fixed.pos) - TRUE_POS
    assert np.linalg.norm(off - (off @ TRUE_DIR) * TRUE_DIR) < 1e-6


def test_short_or_implausible_motion_keeps_the_descriptor_axis() -> None:
    learned = _learned()
    tracker = AxisTracker(learned, P0, Q0)
    assert tracker.corrected(*_turned(0.05)) == learned  # 3 degrees: too short to trust
    halfway = tracker.corrected(*_turned(0.2))  # blended half way
    tilt = math.degrees(math.acos(min(1.0, float(np.dot(halfway.dir, TRUE_DIR)))))
    assert 1.5 < tilt < 3.5
    wrong = quat_from_matrix(matrix_from_axis_angle([1.0, 0.0, 0.0], 0.5) @ matrix_from_quat(Q0))
    assert tracker.corrected(P0, wrong) == learned  # turned about an axis 90 degrees off: the hand slipped


def test_translation_direction_from_the_palm_displacement() -> None:
    learned = Primitive("translation", None, (1.0, 0.1, 0.0), 0.3)
    tracker = AxisTracker(learned, P0, Q0)
    assert tracker.corrected(P0 + np.array([0.01, 0.0, 0.0]), Q0) == learned
    fixed = tracker.corrected(P0 + np.array([0.08, 0.0, 0.0]), Q0)
    np.testing.assert_allclose(fixed.dir, [1.0, 0.0, 0.0], atol=1e-12)
