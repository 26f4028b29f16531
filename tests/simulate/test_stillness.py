"""Stillness at the end of an execution is judged from how far each driven joint moved, not pybullet's velocity."""

from __future__ import annotations

from pathlib import Path

import pybullet as pb
import pytest

from tasks.simulate.api import urdf_setup
from tasks.simulate.result import STILL_ANGULAR_RAD_S
from tasks.simulate.session import TIME_STEP_S, Session, scene_joints
from tests.simulate.fixtures import write_door


def test_mean_speed_is_the_joint_displacement_over_the_steps(tmp_path: Path) -> None:
    run = Session(urdf_setup(write_door(tmp_path), None), None)
    try:
        (hinge,) = (j.index for j in scene_joints(run.sim, run.scene, None) if j.axis.name == "hinge")
        pb.setJointMotorControl2(run.scene, hinge, pb.VELOCITY_CONTROL, force=0.0, physicsClientId=run.sim)
        pb.resetJointState(run.scene, hinge, 0.2, 2.0, physicsClientId=run.sim)  # a door swinging freely
        speeds = run.mean_speeds([hinge], 12)
        moved = run.joint_value(hinge)[0] - 0.2
        assert speeds[hinge] == pytest.approx(moved / (12 * TIME_STEP_S))
        assert speeds[hinge] > STILL_ANGULAR_RAD_S  # not still
        assert run.steps == 12

        pb.resetJointState(run.scene, hinge, 0.5, 0.0, physicsClientId=run.sim)  # a door at rest
        assert run.mean_speeds([hinge], 12)[hinge] < 1e-3
    finally:
        run.close()
