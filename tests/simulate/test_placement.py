"""Automatic base placement makes a palm target reachable (real pybullet IK, limits honoured)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from tasks.errors import SimulationError
from tasks.rotations import matrix_from_quat
from tasks.simulate import robot as rb
from tasks.simulate.placement import KeyPose, place_base
from tasks.simulate.waypoints import angle_between_quats


@pytest.fixture
def planning() -> Iterator[tuple[rb.Robot, int]]:
    import pybullet as pb

    client = pb.connect(pb.DIRECT)
    box = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.2, 0.2, 0.4], physicsClientId=client)
    scene = pb.createMultiBody(0.0, box, basePosition=[1.5, 1.0, 0.4], physicsClientId=client)
    robot = rb.load_robot(client, [0.0, 0.0, -5.0], [0.0, 0.0, 0.0, 1.0])
    yield robot, scene
    pb.disconnect(client)


def test_target_far_from_the_origin_becomes_reachable(planning: tuple[rb.Robot, int]) -> None:
    robot, scene = planning
    # palm facing -x, 1.3 m up and 1.3 m from the origin: out of reach of a base at the origin
    quat = np.array([0.0, -0.7071067811865476, 0.0, 0.7071067811865476])
    target = np.array([1.2, 1.0, 1.3])
    keys = [KeyPose(target, quat, {})]
    placement = place_base(robot, scene, keys)
    rb.set_arm(robot, placement.q_path[0])
    position, orientation = rb.palm_pose(robot)
    assert np.linalg.norm(position - target) < 0.003
    assert angle_between_quats(orientation, quat) < np.radians(2.0)
    assert np.all(placement.q_path[0] >= rb.ARM_LOWER) and np.all(placement.q_path[0] <= rb.ARM_UPPER)
    # the base stands behind the hand (the palm's +z points away from it)
    approach = matrix_from_quat(quat)[:, 2]
    assert float((target - placement.base_position) @ approach) > 0.2


def test_unreachable_chain_is_an_error(planning: tuple[rb.Robot, int]) -> None:
    robot, scene = planning
    quat = np.array([0.0, 0.0, 0.0, 1.0])
    keys = [KeyPose(np.array([0.0, 0.0, 1.0]), quat, {}), KeyPose(np.array([0.0, 0.0, 4.0]), quat, {})]
    with pytest.raises(SimulationError, match="no base placement among 420 candidates reaches the whole chain"):
        place_base(robot, scene, keys)
    with pytest.raises(SimulationError, match="no key poses"):
        place_base(robot, scene, [])
