"""Object models: points on the surfaces of the scene's parts, functional part included."""

from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from tasks.errors import SceneError
from tasks.scenes.catalog import SCENE_NAMES, build_scene
from tasks.scenes.kinematics import joint_values_at_motion, link_indices, scene_client, set_joints
from tasks.scenes.surface import model_shapes, sample_object_model


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_points_lie_on_the_part_surfaces(name: str) -> None:
    scene = build_scene(name, 1)
    points = sample_object_model(scene, 3000, np.random.default_rng(0))
    assert points.shape == (3000, 3) and points.dtype == np.float64
    check = points[np.random.default_rng(1).choice(len(points), 80, replace=False)]
    on_grasp_part = 0
    with scene_client(scene) as (client, body):
        set_joints(client, body, joint_values_at_motion(scene, 0, 0.0))
        links = link_indices(client, body)
        probe = pb.createCollisionShape(pb.GEOM_SPHERE, radius=1e-4, physicsClientId=client)
        ball = pb.createMultiBody(0.0, probe, -1, [0.0, 0.0, 0.0], physicsClientId=client)
        for p in check:
            pb.resetBasePositionAndOrientation(ball, p.tolist(), [0, 0, 0, 1], physicsClientId=client)
            gaps = {
                link: min(
                    (abs(c[8]) for c in pb.getClosestPoints(ball, body, 0.05, linkIndexB=i, physicsClientId=client)),
                    default=1.0,
                )
                for link, i in ((name, links[name]) for name in scene.model_links)
            }
            # pybullet meshes URDF cylinders into polygons: a sample on the true circle is within 1.5 mm of one
            assert min(gaps.values()) < 1.5e-3, (p, gaps)
        for p in points:
            pb.resetBasePositionAndOrientation(ball, p.tolist(), [0, 0, 0, 1], physicsClientId=client)
            near = pb.getClosestPoints(ball, body, 1.5e-3, linkIndexB=links[scene.grasp_link], physicsClientId=client)
            on_grasp_part += int(bool(near))
    assert on_grasp_part >= 10  # the functional part (door, panel, lever, cap) is in the model


def test_area_weighting_and_reproducibility() -> None:
    scene = build_scene("bottle", None)
    a = sample_object_model(scene, 2000, np.random.default_rng(5))
    b = sample_object_model(scene, 2000, np.random.default_rng(5))
    np.testing.assert_array_equal(a, b)
    shapes = model_shapes(scene)
    cap_share = sum(s.area for s in shapes if s.link == "cap") / sum(s.area for s in shapes)
    cap = next(s for s in shapes if s.link == "cap")
    local = (a - cap.translation) @ cap.rotation
    r, length = cap.size
    on_cap = (np.hypot(local[:, 0], local[:, 1]) <= r + 1e-9) & (np.abs(local[:, 2]) <= length / 2 + 1e-9)
    assert on_cap.mean() == pytest.approx(cap_share, abs=0.03)


def test_bad_point_count() -> None:
    with pytest.raises(SceneError, match="n_points: need at least 1 point, got 0"):
        sample_object_model(build_scene("door", None), 0, np.random.default_rng(0))
