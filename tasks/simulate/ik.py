"""Inverse kinematics of the palm frame with pybullet's damped least squares, joint limits honoured.

pybullet's ``calculateInverseKinematics`` starts from the body's current joint state and ignores joint limits
unless ``lowerLimits``/``upperLimits``/``jointRanges``/``restPoses`` are given with one entry per movable joint
(arm and hand: 15 here). The solver runs in its own planning client, where the arm is reset to the seed first,
so the solution is seeded from the last one and the physics client is never disturbed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pybullet as pb

from tasks.arrays import FloatArray
from tasks.simulate.robot import (
    ARM_JOINTS,
    ARM_LOWER,
    ARM_UPPER,
    HAND_JOINTS,
    PALM_LINK,
    Robot,
    palm_pose,
    reset_arm,
)
from tasks.simulate.waypoints import angle_between_quats

IK_POSITION_TOL_M = 0.003
"""A solution is accepted within 3 mm of the target position ..."""
IK_ANGLE_TOL_RAD = math.radians(2.0)
"""... and 2° of its orientation."""
_HAND_LOWER = [-0.1] * len(HAND_JOINTS)
_HAND_UPPER = [3.3] * len(HAND_JOINTS)


@dataclass(frozen=True)
class IkSolution:
    """Arm angles ``q`` (7,) radians reaching the palm pose within ``position_error_m`` and ``angle_error_rad``."""

    q: FloatArray
    position_error_m: float
    angle_error_rad: float

    @property
    def ok(self) -> bool:
        """Within ``IK_POSITION_TOL_M`` and ``IK_ANGLE_TOL_RAD``."""
        return self.position_error_m <= IK_POSITION_TOL_M and self.angle_error_rad <= IK_ANGLE_TOL_RAD


def solve_ik(
    robot: Robot,
    position: npt.ArrayLike,
    quat_xyzw: npt.ArrayLike,
    seed: npt.ArrayLike,
    *,
    rounds: int = 4,
    iterations: int = 100,
) -> IkSolution:
    """Palm pose -> arm angles, starting from ``seed`` (7,) radians; ``robot`` lives in a planning client.

    Runs pybullet's null-space IK (rest pose = seed, so the arm stays near it; at most ``iterations`` per call) up
    to ``rounds`` times, each from the previous answer, and keeps the best; the arm is left at the returned angles.
    """

    target_p = np.asarray(position, dtype=np.float64)
    target_q = np.asarray(quat_xyzw, dtype=np.float64)
    q = np.clip(np.asarray(seed, dtype=np.float64), ARM_LOWER, ARM_UPPER)
    hand_now = [s[0] for s in pb.getJointStates(robot.body, list(HAND_JOINTS), physicsClientId=robot.client)]
    lower = [*ARM_LOWER.tolist(), *_HAND_LOWER]
    upper = [*ARM_UPPER.tolist(), *_HAND_UPPER]
    ranges = [u - lo for lo, u in zip(lower, upper, strict=True)]
    best: IkSolution | None = None
    for _ in range(rounds):
        reset_arm(robot, q)
        out = pb.calculateInverseKinematics(
            robot.body,
            PALM_LINK,
            target_p.tolist(),
            target_q.tolist(),
            lowerLimits=lower,
            upperLimits=upper,
            jointRanges=ranges,
            restPoses=[*q.tolist(), *hand_now],
            maxNumIterations=iterations,
            residualThreshold=1e-4,
            physicsClientId=robot.client,
        )
        q = np.clip(np.array(out[: len(ARM_JOINTS)], dtype=np.float64), ARM_LOWER, ARM_UPPER)
        reset_arm(robot, q)
        p, r = palm_pose(robot)
        sol = IkSolution(q, float(np.linalg.norm(p - target_p)), angle_between_quats(r, target_q))
        if best is None or sol.position_error_m + 0.1 * sol.angle_error_rad < (
            best.position_error_m + 0.1 * best.angle_error_rad
        ):
            best = sol
        if sol.ok:
            break
    assert best is not None
    reset_arm(robot, best.q)
    return best
