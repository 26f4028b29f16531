"""Waypoints along an arc about an axis and along a line are exact."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tasks.rotations import matrix_from_quat, quat_from_matrix
from tasks.simulate.waypoints import angle_between_quats, arc_waypoints, line_waypoints, matrix_from_axis_angle, unit

finite = st.floats(-2.0, 2.0, allow_nan=False)


def test_quarter_turn_about_z_lands_exactly() -> None:
    wps = arc_waypoints([1.0, 0.0, 0.5], [0, 0, 0, 1], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], math.pi / 2)
    np.testing.assert_allclose(wps.positions[0], [1.0, 0.0, 0.5], atol=1e-12)
    np.testing.assert_allclose(wps.positions[-1], [0.0, 1.0, 0.5], atol=1e-12)
    np.testing.assert_allclose(
        matrix_from_quat(wps.quats[-1]), matrix_from_axis_angle([0, 0, 1], math.pi / 2), atol=1e-12
    )
    assert wps.progress[-1] == pytest.approx(math.pi / 2)
    assert len(wps) == 91  # 1° steps, start included
    assert np.max(np.diff(wps.progress)) <= math.radians(1.0) + 1e-12


@settings(max_examples=60, deadline=None)
@given(
    st.tuples(finite, finite, finite),
    st.tuples(finite, finite, finite),
    st.tuples(finite, finite, finite).filter(lambda v: np.linalg.norm(v) > 0.1),
    st.floats(0.01, 3.0),
)
def test_arc_keeps_radius_and_turns_hand_with_the_part(
    start: tuple[float, float, float],
    centre: tuple[float, float, float],
    axis: tuple[float, float, float],
    angle: float,
) -> None:
    q0 = quat_from_matrix(matrix_from_axis_angle([0.3, -0.2, 0.9], 0.7))
    wps = arc_waypoints(start, q0, centre, axis, angle, step_rad=0.05)
    k = unit(axis)
    c = np.asarray(centre)
    rel = wps.positions - c
    radial = rel - np.outer(rel @ k, k)
    # distance from the axis and height along it stay those of the start
    np.testing.assert_allclose(np.linalg.norm(radial, axis=1), np.linalg.norm(radial[0]), atol=1e-9)
    np.testing.assert_allclose(rel @ k, rel[0] @ k, atol=1e-9)
    # every waypoint is the start pose moved rigidly by R(progress): hand-fixed points follow
    R0 = matrix_from_quat(q0)
    probe_local = np.array([0.05, -0.02, 0.1])
    for i in (0, len(wps) // 2, len(wps) - 1):
        R = matrix_from_axis_angle(k, float(wps.progress[i]))
        expected = c + R @ (np.asarray(start) + R0 @ probe_local - c)
        got = wps.positions[i] + matrix_from_quat(wps.quats[i]) @ probe_local
        np.testing.assert_allclose(got, expected, atol=1e-9)
    assert angle_between_quats(wps.quats[0], wps.quats[-1]) == pytest.approx(angle, abs=1e-7)


def test_line_is_exact_and_keeps_orientation() -> None:
    q0 = quat_from_matrix(matrix_from_axis_angle([1, 1, 0], 0.4))
    wps = line_waypoints([0.1, 0.2, 0.3], q0, [0.0, 2.0, 0.0], 0.3, step_m=0.005)
    assert len(wps) == 61
    np.testing.assert_allclose(wps.positions[-1], [0.1, 0.5, 0.3], atol=1e-12)
    np.testing.assert_allclose(np.diff(wps.positions, axis=0), np.tile([0.0, 0.005, 0.0], (60, 1)), atol=1e-12)
    np.testing.assert_allclose(wps.quats, np.tile(q0, (61, 1)), atol=1e-12)


def test_quaternion_round_trip() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        q = q if q[3] >= 0 else -q
        np.testing.assert_allclose(quat_from_matrix(matrix_from_quat(q)), q, atol=1e-12)


def test_bad_inputs_name_the_argument() -> None:
    with pytest.raises(ValueError, match="axis_dir: expected a non-zero finite direction"):
        arc_waypoints([0, 0, 0], [0, 0, 0, 1], [0, 0, 0], [0, 0, 0], 1.0)
    with pytest.raises(ValueError, match=r"extent: expected a finite value >= 0, got -1\.0"):
        line_waypoints([0, 0, 0], [0, 0, 0, 1], [1, 0, 0], -1.0)
    with pytest.raises(ValueError, match="start_position: expected shape"):
        line_waypoints([0, 0], [0, 0, 0, 1], [1, 0, 0], 1.0)
    with pytest.raises(ValueError, match=r"quat_xyzw: expected shape \(4,\)"):
        matrix_from_quat([0, 0, 1])
