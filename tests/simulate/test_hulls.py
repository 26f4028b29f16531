"""The iiwa's hull collision meshes collide exactly like its STL meshes (real pybullet)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from tasks.simulate import robot as rb
from tasks.simulate.hulls import hull_mesh, stl_vertices, with_hull_collisions
from tasks.simulate.placement import wrists_within_reach


def _closest(urdf: Path, configs: np.ndarray) -> np.ndarray:
    import pybullet as pb

    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(urdf), useFixedBase=True, physicsClientId=client)
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.2, 0.2, 0.2], physicsClientId=client)
        box = pb.createMultiBody(0.0, shape, basePosition=[0.45, 0.0, 0.5], physicsClientId=client)
        out = []
        for q in configs:
            for j, angle in enumerate(q):
                pb.resetJointState(body, j, float(angle), physicsClientId=client)
            pb.performCollisionDetection(physicsClientId=client)
            for link in range(-1, 7):
                pts = pb.getClosestPoints(body, box, 1.0, linkIndexA=link, physicsClientId=client)
                out.append(min(p[8] for p in pts))
        return np.array(out)
    finally:
        pb.disconnect(client)


def test_hull_robot_has_the_same_closest_points(tmp_path: Path) -> None:
    stl_urdf = tmp_path / "stl.urdf"
    stl_urdf.write_text(rb.robot_urdf_text())
    hull_urdf = rb.robot_urdf(tmp_path / "cache")
    assert "hull" in hull_urdf.read_text() and ".stl" not in re.sub(r"<visual>.*?</visual>", "", hull_urdf.read_text())
    configs = np.random.default_rng(3).uniform(-1.5, 1.5, size=(12, 7))
    a, b = _closest(stl_urdf, configs), _closest(hull_urdf, configs)
    assert np.any(a < 0.0)  # some configurations do touch the box
    np.testing.assert_allclose(a, b, atol=1e-9)


def test_hull_has_far_fewer_vertices(tmp_path: Path) -> None:
    text = with_hull_collisions(rb.robot_urdf_text(), tmp_path)
    stl = Path(re.findall(r'filename="([^"]+link_1\.stl)"', rb.robot_urdf_text())[0])
    obj = hull_mesh(stl, tmp_path)
    assert str(obj) in text
    n_hull = sum(1 for line in obj.read_text().splitlines() if line.startswith("v "))
    assert 50 < n_hull < len(stl_vertices(stl.read_bytes())) / 5


def test_wrist_screen_rejects_a_key_beyond_reach_and_keeps_one_within() -> None:
    import pybullet as pb

    from tasks.simulate.placement import KeyPose

    client = pb.connect(pb.DIRECT)
    try:
        robot = rb.load_robot(client, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
        rb.set_arm(robot, rb.ARM_REST)
        p, q = rb.palm_pose(robot)
        assert wrists_within_reach(robot, [KeyPose(p, q, {})])
        assert not wrists_within_reach(robot, [KeyPose(p + np.array([0.6, 0.0, 0.0]), q, {})])
    finally:
        pb.disconnect(client)
