"""Quaternion [x, y, z, w] <-> rotation matrix: scipy's values, w >= 0, non-unit quaternions, named errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import Quats
from tasks.rotations import matrix_from_quat, quat_from_matrix, quat_tuple_from_matrix


def _random_quats(seed: int, n: int) -> Quats:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    out: Quats = q / np.linalg.norm(q, axis=1, keepdims=True)
    return out


def test_quarter_turn_about_z_maps_x_to_y() -> None:
    s = math.sqrt(0.5)
    rot = matrix_from_quat([0.0, 0.0, s, s])
    assert rot.shape == (3, 3)
    assert rot.dtype == np.float64
    np.testing.assert_allclose(rot, [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], atol=1e-15)
    np.testing.assert_allclose(rot @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


def test_matches_scipy_and_round_trips() -> None:
    for q in _random_quats(11, 200):
        rot = matrix_from_quat(q)
        np.testing.assert_allclose(rot, Rotation.from_quat(q).as_matrix(), atol=1e-15)
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-14)
        back = quat_from_matrix(rot)
        assert back.shape == (4,)
        assert back.dtype == np.float64
        assert back[3] >= 0.0
        np.testing.assert_allclose(back, q if q[3] >= 0.0 else -q, atol=1e-12)


def test_matrix_columns_are_the_frame_axes() -> None:
    x_axis, y_axis, z_axis = [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]
    q = quat_from_matrix(np.column_stack([x_axis, y_axis, z_axis]))
    np.testing.assert_allclose(q, [0.5, 0.5, 0.5, 0.5], atol=1e-15)
    np.testing.assert_allclose(matrix_from_quat(q)[:, 2], z_axis, atol=1e-15)


def test_non_unit_quaternion_is_normalised() -> None:
    for q in _random_quats(12, 20):
        np.testing.assert_allclose(matrix_from_quat(3.7 * q), matrix_from_quat(q), atol=1e-15)
        np.testing.assert_allclose(matrix_from_quat(-0.2 * q), matrix_from_quat(q), atol=1e-15)


def test_negated_quaternion_is_the_same_rotation_and_comes_back_with_w_positive() -> None:
    q = np.array([0.1, -0.5, 0.3, -0.8])
    q /= np.linalg.norm(q)
    np.testing.assert_allclose(matrix_from_quat(q), matrix_from_quat(-q), atol=1e-15)
    np.testing.assert_allclose(quat_from_matrix(matrix_from_quat(q)), -q, atol=1e-15)


def test_half_turns_have_w_zero_and_first_non_zero_component_positive() -> None:
    assert quat_from_matrix(np.diag([1.0, -1.0, -1.0])).tolist() == [1.0, 0.0, 0.0, 0.0]
    s = math.sqrt(0.5)
    rot = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # half turn about (1, -1, 0)
    np.testing.assert_allclose(quat_from_matrix(rot), [s, -s, 0.0, 0.0], atol=1e-15)
    rot = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, -1.0, 0.0]])  # half turn about (0, 1, -1)
    np.testing.assert_allclose(quat_from_matrix(rot), [0.0, s, -s, 0.0], atol=1e-15)
    np.testing.assert_allclose(matrix_from_quat(quat_from_matrix(rot)), rot, atol=1e-15)


def test_exact_zeros_are_positive_zeros() -> None:
    q = quat_from_matrix([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # -90 degrees about x
    np.testing.assert_allclose(q, [-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)], atol=1e-15)
    assert not np.signbit(q[1:3]).any()


def test_nearly_orthonormal_matrix_gives_the_nearest_rotation() -> None:
    q = _random_quats(13, 1)[0]
    noisy = matrix_from_quat(q) + 1e-9 * np.random.default_rng(14).normal(size=(3, 3))
    np.testing.assert_allclose(quat_from_matrix(noisy), q if q[3] >= 0.0 else -q, atol=1e-8)


def test_tuple_form_is_plain_floats() -> None:
    rot = matrix_from_quat(_random_quats(15, 1)[0])
    quat = quat_tuple_from_matrix(rot)
    assert isinstance(quat, tuple)
    assert all(type(v) is float for v in quat)
    assert quat == tuple(quat_from_matrix(rot).tolist())


def test_bad_inputs_name_the_argument() -> None:
    with pytest.raises(ValueError, match=r"quat_xyzw: expected shape \(4,\), got \(3,\)"):
        matrix_from_quat([0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match=r"quat_xyzw: expected shape \(4,\), got \(2, 4\)"):
        matrix_from_quat(np.zeros((2, 4)))
    with pytest.raises(ValueError, match=r"quat_xyzw: expected finite values, got \[nan, 0\.0, 0\.0, 1\.0\]"):
        matrix_from_quat([math.nan, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="zero norm"):
        matrix_from_quat([0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"rot: expected shape \(3, 3\), got \(4, 4\)"):
        quat_from_matrix(np.eye(4))
    with pytest.raises(ValueError, match="rot: expected finite values"):
        quat_from_matrix(np.full((3, 3), math.inf))
    with pytest.raises(ValueError, match="Non-positive determinant"):
        quat_from_matrix(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match=r"rot: expected shape \(3, 3\)"):
        quat_tuple_from_matrix(np.eye(2))
