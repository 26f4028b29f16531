"""Resolved-rate control: the palm Jacobian in the world frame (any base pose), twists realised by joint steps."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pybullet as pb
import pytest

from tasks.rotations import matrix_from_quat, quat_from_matrix
from tasks.simulate import robot as rb
from tasks.simulate.control import (
    joint_step,
    line_twist,
    measured_joints,
    palm_jacobian,
    pose_error,
    rotation_vector,
    screw_twist,
)
from tasks.simulate.waypoints import matrix_from_axis_angle


@pytest.fixture
def tilted_robot() -> Iterator[rb.Robot]:
    """The iiwa + hand on a base turned 1 rad about z and tipped a little (pybullet's Jacobian is in the base frame)."""
    client = pb.connect(pb.DIRECT)
    try:
        robot = rb.load_robot(client, [0.3, 0.2, 0.1], pb.getQuaternionFromEuler([0.1, 0.2, 1.0]))
        for joint, angle in zip(rb.ARM_JOINTS, rb.ARM_REST + 0.1, strict=True):
            pb.resetJointState(robot.body, joint, float(angle), physicsClientId=client)
        yield robot
    finally:
        pb.disconnect(client)


def _set_arm(robot: rb.Robot, q: np.ndarray) -> None:
    for joint, angle in zip(rb.ARM_JOINTS, q, strict=True):
        pb.resetJointState(robot.body, joint, float(angle), physicsClientId=robot.client)


def test_jacobian_matches_finite_differences_on_a_turned_base(tilted_robot: rb.Robot) -> None:
    q0 = rb.arm_angles(tilted_robot)
    jac = palm_jacobian(tilted_robot, measured_joints(tilted_robot))
    p0, r0 = rb.palm_pose(tilted_robot)
    numeric = np.zeros((6, 7))
    for i in range(7):
        q = q0.copy()
        q[i] += 1e-3
        _set_arm(tilted_robot, q)
        p1, r1 = rb.palm_pose(tilted_robot)
        numeric[:, i] = pose_error(p0, r0, p1, r1) / 1e-3
    assert np.max(np.abs(jac - numeric)) < 2e-3


def test_joint_step_realises_a_screw_twist(tilted_robot: rb.Robot) -> None:
    p0, r0 = rb.palm_pose(tilted_robot)
    axis_point, axis_dir = p0 + np.array([0.0, 0.4, 0.0]), np.array([0.0, 0.0, 1.0])
    twist = screw_twist(p0, axis_point, axis_dir, math.radians(1.0))
    q0 = rb.arm_angles(tilted_robot)
    _set_arm(tilted_robot, q0 + joint_step(palm_jacobian(tilted_robot, measured_joints(tilted_robot)), twist))
    p1, r1 = rb.palm_pose(tilted_robot)
    turn = matrix_from_axis_angle(axis_dir, math.radians(1.0))
    assert np.linalg.norm(p1 - (axis_point + turn @ (p0 - axis_point))) < 2e-4  # 7 mm step, first order
    assert np.linalg.norm(pose_error(p1, r1, p1, quat_from_matrix(turn @ matrix_from_quat(r0)))[3:]) < 1e-3


def test_posture_pull_moves_the_arm_not_the_palm(tilted_robot: rb.Robot) -> None:
    p0, r0 = rb.palm_pose(tilted_robot)
    q0 = rb.arm_angles(tilted_robot)
    jac = palm_jacobian(tilted_robot, measured_joints(tilted_robot))
    pull = np.full(7, 0.02)
    dq = joint_step(jac, np.zeros(6), posture_pull=pull)
    assert np.linalg.norm(dq) > 1e-3  # the redundant arm does move ...
    _set_arm(tilted_robot, q0 + pull)
    raw = np.linalg.norm(pose_error(p0, r0, *rb.palm_pose(tilted_robot)))
    _set_arm(tilted_robot, q0 + dq)
    moved = np.linalg.norm(pose_error(p0, r0, *rb.palm_pose(tilted_robot)))
    assert moved < 0.02 * raw  # ... in its null space, where the raw pull would swing the palm


def test_twists_and_rotation_vectors() -> None:
    on_axis = screw_twist(np.array([1.0, 2.0, 3.0]), [1.0, 2.0, 0.0], [0.0, 0.0, 2.0], 0.1)
    np.testing.assert_allclose(on_axis, [0.0, 0.0, 0.0, 0.0, 0.0, 0.1], atol=1e-12)
    off_axis = screw_twist(np.array([1.5, 2.0, 3.0]), [1.0, 2.0, 0.0], [0.0, 0.0, 1.0], 0.1)
    np.testing.assert_allclose(off_axis[:3], [0.0, 0.05, 0.0], atol=1e-12)  # tangential, radius x angle
    np.testing.assert_allclose(line_twist([0.0, 3.0, 4.0], 0.5), [0.0, 0.3, 0.4, 0.0, 0.0, 0.0])
    for angle in (1e-10, 0.3, 2.0, math.pi):
        axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
        vec = rotation_vector(matrix_from_axis_angle(axis, angle))
        assert abs(np.linalg.norm(vec) - angle) < 1e-6
        if angle > 1e-6:
            assert abs(abs(float(vec @ axis)) / np.linalg.norm(vec) - 1.0) < 1e-6
