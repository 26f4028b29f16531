"""Similarity transforms, quaternions and the pure carry functions."""

from __future__ import annotations

import numpy as np
import pytest

from schemas.descriptor import Grasp, Primitive
from tasks.rotations import matrix_from_quat, quat_tuple_from_matrix
from tasks.transfer.carry import carry_grasp, carry_primitive
from tasks.transfer.similarity import Similarity, angle_between_deg, point_line_distance, umeyama
from tests.transfer.shapes import random_rotation


def _truth(seed: int, scale: float) -> Similarity:
    rng = np.random.default_rng(seed)
    return Similarity(scale, random_rotation(rng), rng.normal(size=3))


@pytest.mark.parametrize("scale", [0.8, 1.3])
def test_umeyama_recovers_a_known_similarity(scale: float) -> None:
    truth = _truth(1, scale)
    pts = np.random.default_rng(2).normal(size=(50, 3))
    est = umeyama(pts, truth.apply_points(pts))
    assert est.scale == pytest.approx(scale, rel=1e-9)
    np.testing.assert_allclose(est.matrix(), truth.matrix(), atol=1e-9)


def test_compose_inverse_and_matrix_round_trip() -> None:
    a, b = _truth(3, 0.8), _truth(4, 1.3)
    pts = np.random.default_rng(5).normal(size=(10, 3))
    np.testing.assert_allclose(a.compose(b).apply_points(pts), a.apply_points(b.apply_points(pts)), atol=1e-12)
    np.testing.assert_allclose(a.inverse().apply_points(a.apply_points(pts)), pts, atol=1e-12)
    back = Similarity.from_matrix(a.matrix())
    assert back.scale == pytest.approx(0.8)
    np.testing.assert_allclose(back.rotation, a.rotation, atol=1e-12)


def test_from_matrix_rejects_non_similarities() -> None:
    with pytest.raises(ValueError, match=r"expected shape \(4, 4\)"):
        Similarity.from_matrix(np.eye(3))
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="not a similarity"):
        Similarity.from_matrix(mirror)
    with pytest.raises(ValueError, match="non-finite"):
        Similarity.from_matrix(np.full((4, 4), np.nan))


def test_quaternion_round_trip() -> None:
    rng = np.random.default_rng(6)
    for _ in range(20):
        rot = random_rotation(rng)
        np.testing.assert_allclose(matrix_from_quat(quat_tuple_from_matrix(rot)), rot, atol=1e-12)
    assert quat_tuple_from_matrix(np.diag([1.0, -1.0, -1.0])) == pytest.approx((1.0, 0.0, 0.0, 0.0))


@pytest.mark.parametrize("scale", [0.8, 1.3])
def test_extents_scale_for_translations_only(scale: float) -> None:
    truth = _truth(7, scale)
    rot = Primitive("rotation", (0.1, 0.2, 0.3), (0.0, 0.0, 1.0), 1.2)
    tra = Primitive("translation", None, (0.0, 1.0, 0.0), 0.3)
    rot2, tra2 = carry_primitive(rot, truth), carry_primitive(tra, truth)
    assert rot2.extent == pytest.approx(1.2)
    assert tra2.extent == pytest.approx(0.3 * scale)
    assert tra2.pos is None
    np.testing.assert_allclose(rot2.pos, truth.apply_point(np.array([0.1, 0.2, 0.3])), atol=1e-12)
    np.testing.assert_allclose(rot2.dir, truth.rotation @ np.array([0.0, 0.0, 1.0]), atol=1e-12)
    assert np.linalg.norm(tra2.dir) == pytest.approx(1.0)


def test_wrist_pose_turns_with_the_rotation_part() -> None:
    truth = _truth(8, 1.3)
    grasp = Grasp("barrett", (0.3, 0.1), (0.0, 0.1, 0.2), (0.0, 0.0, 0.0, 1.0), {"epsilon": 0.1})
    moved = carry_grasp(grasp, truth)
    np.testing.assert_allclose(moved.wrist_position, truth.apply_point(np.array([0.0, 0.1, 0.2])), atol=1e-12)
    np.testing.assert_allclose(matrix_from_quat(moved.wrist_orientation), truth.rotation, atol=1e-12)
    assert moved.eigengrasps == (0.3, 0.1)


def test_axis_measures() -> None:
    assert angle_between_deg(np.array([1.0, 0, 0]), np.array([0.0, 1, 0])) == pytest.approx(90.0)
    assert angle_between_deg(np.array([1.0, 0, 0]), np.array([-1.0, 0, 0]), undirected=True) == pytest.approx(0.0)
    d = point_line_distance(np.array([0.0, 2.0, 5.0]), np.zeros(3), np.array([0.0, 0.0, 3.0]))
    assert d == pytest.approx(2.0)
