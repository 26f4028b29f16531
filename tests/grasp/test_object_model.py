"""Object models from point clouds: normals, convex pieces, and the errors of bad input."""

from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from tasks.errors import GraspError
from tasks.grasp.api import plan_grasp
from tasks.grasp.object_model import (
    ObjectModel,
    build_object_model,
    estimate_normals,
    load_object,
    voxel_downsample,
)
from tests.grasp.surface_sampling import sample_box_surface

from .conftest import PALM_DOWN


def test_normals_point_outwards_on_a_box() -> None:
    rng = np.random.default_rng(0)
    pts, truth = sample_box_surface(np.array([0.03, 0.02, 0.05]), 2000, rng)
    est = estimate_normals(pts)
    agree = np.einsum("ij,ij->i", est, truth)
    assert np.mean(agree < 0.0) < 0.01  # oriented outwards: (almost) none flipped
    assert np.mean(agree > 0.5) > 0.97  # within 60° of the face normal except at the edges


def test_convex_pieces_cover_the_cloud_and_collide_in_pybullet() -> None:
    rng = np.random.default_rng(1)
    pts, _ = sample_box_surface(np.array([0.03, 0.03, 0.03]), 2000, rng)
    model = build_object_model(pts, rng, fit=False)
    assert model.primitive is None
    assert len(model.parts) > 4
    assert model.radius == pytest.approx(np.sqrt(3) * 0.03, rel=0.1)
    client = pb.connect(pb.DIRECT)
    try:
        body = load_object(client, model)
        sphere = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.005, physicsClientId=client)
        probe = pb.createMultiBody(0, sphere, physicsClientId=client)
        pb.resetBasePositionAndOrientation(probe, [0.0, 0.0, 0.05], [0, 0, 0, 1], physicsClientId=client)
        gap = min(p[8] for p in pb.getClosestPoints(probe, body, 0.1, physicsClientId=client))
        assert gap == pytest.approx(0.05 - 0.03 - 0.005, abs=0.003)  # sphere 15 mm above the top face
    finally:
        pb.disconnect(client)


def test_voxel_downsample_merges_points_in_a_cell() -> None:
    pts = np.array([[0.0001, 0.0001, 0.0001], [0.0002, 0.0002, 0.0002], [0.01, 0.0, 0.0]])
    assert len(voxel_downsample(pts, 0.004)) == 2


def test_bad_object_input_is_refused() -> None:
    rng = np.random.default_rng(0)
    tiny = rng.uniform(0.0, 0.001, (100, 3))  # 100 points inside one 4 mm voxel
    with pytest.raises(GraspError, match=r"1 points after 4 mm voxels, need 30"):
        build_object_model(tiny, rng)
    pts, _ = sample_box_surface(np.array([0.03, 0.03, 0.03]), 200, rng)
    bare = ObjectModel(pts, pts, np.zeros(3), 0.05)
    client = pb.connect(pb.DIRECT)
    try:
        with pytest.raises(GraspError, match="object model has no collision parts"):
            load_object(client, bare)
    finally:
        pb.disconnect(client)


def test_a_hand_buried_in_the_object_finds_no_grasp() -> None:
    rng = np.random.default_rng(2)
    # a solid 30 cm block, the seed palm at its centre (20000 points: at 6000, 16 mm apart, the hand at spread
    # pi/2 found a pocket it grazed by under 2 mm, which the planner allows a pre-grasp)
    pts = rng.uniform(-0.15, 0.15, (20000, 3))
    with pytest.raises(GraspError, match="no collision-free grasp found near the seed pose"):
        plan_grasp(pts, np.zeros(3), PALM_DOWN, rng)


def test_normals_seen_from_the_palm_face_it_behind_a_bar_handle() -> None:
    # a 12 mm bar along x, and 70 mm behind it a face cropped from a door (its back not in the cloud), seen from
    # the palm 40 mm in front of the bar: the face's normals point at the palm (-y), the bar's back away (+y)
    rng = np.random.default_rng(3)
    theta = rng.uniform(0.0, 2.0 * np.pi, 1500)
    bar = np.stack([rng.uniform(-0.08, 0.08, 1500), 0.012 * np.cos(theta), 0.012 * np.sin(theta)], axis=1)
    face_pts = np.stack([rng.uniform(-0.12, 0.12, 4000), np.full(4000, 0.07), rng.uniform(-0.12, 0.12, 4000)], axis=1)
    pts = voxel_downsample(np.concatenate([bar, face_pts]), 0.004)
    palm = np.array([0.0, -0.04, 0.0])
    est = estimate_normals(pts, viewpoint=palm)
    face = np.abs(pts[:, 1] - 0.07) < 0.001
    back = (pts[:, 1] > 0.009) & (np.abs(pts[:, 2]) < 0.006) & (pts[:, 1] < 0.02)
    assert face.sum() > 100 and back.sum() > 10
    assert np.mean(est[face, 1] < -0.9) > 0.95  # without the viewpoint: 0 (the whole face flipped)
    assert np.mean(est[back, 1] > 0.7) > 0.8
