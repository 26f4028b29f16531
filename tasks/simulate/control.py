"""Resolved-rate Cartesian control of the palm from the measured arm state (differential IK, damped least squares).

Each control tick reads the arm's joint angles (the robot's encoders), takes the palm Jacobian there and turns a
small palm twist (linear metres, angular radians, world frame) into joint increments. The joint targets given to
the force-limited position motors are the *measured* angles plus that increment, never an accumulated plan: the
arm leads the hand by at most one step, so when a held part moves along a slightly different path than the one
commanded (a learned axis a few millimetres or degrees off), the part's constraint wins and the next step starts
from where the hand really is. The interaction force stays that of a one-step error instead of growing with the
distance between the planned and the true path (an admittance-like compliance).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pybullet as pb

from tasks.arrays import FloatArray
from tasks.simulate import robot as rb

DAMPING = 0.02
"""Damping of the least-squares inverse (metres / radians): keeps joint steps bounded near singularities."""
LIMIT_MARGIN_RAD = 0.02
"""Joint targets stay this far inside the iiwa's limits."""
LOCK_ROUNDS = 3
"""At most this many re-solves with joints at their limits locked."""
POSTURE_GAIN = 0.1
"""Fraction of the way to the preferred posture (the base placement's verified joint path) per control tick."""
ANGULAR_WEIGHT_M = 0.2
"""Radians count as this many metres when a rotation and a translation are traded off (palm-sized lever)."""
_TWIST_WEIGHTS = np.array([1.0, 1.0, 1.0, ANGULAR_WEIGHT_M, ANGULAR_WEIGHT_M, ANGULAR_WEIGHT_M])
_EYE6 = np.eye(6)


def measured_joints(robot: rb.Robot) -> FloatArray:
    """(15,) positions of every movable joint (arm then hand), radians: what pybullet's Jacobian wants."""

    states = pb.getJointStates(robot.body, list(rb.MOVABLE_JOINTS), physicsClientId=robot.client)
    return np.array([s[0] for s in states], dtype=np.float64)


def palm_jacobian(robot: rb.Robot, joints: FloatArray) -> FloatArray:
    """(6, 7) Jacobian of the palm frame's origin (rows: linear m/rad, angular rad/rad; world frame) over the
    arm's seven joints, at the (15,) movable joint positions ``joints``."""

    zeros = [0.0] * len(joints)
    lin, ang = pb.calculateJacobian(
        robot.body,
        rb.PALM_LINK,
        robot.palm_origin_in_com,
        [float(v) for v in joints],
        zeros,
        zeros,
        physicsClientId=robot.client,
    )
    n = len(rb.ARM_JOINTS)
    base = robot.base_rotation  # pybullet gives a fixed-base Jacobian in the base frame
    return np.vstack([base @ np.asarray(lin, dtype=np.float64)[:, :n], base @ np.asarray(ang, dtype=np.float64)[:, :n]])


def joint_step(
    jacobian: FloatArray, twist: FloatArray, posture_pull: FloatArray | None = None, damping: float = DAMPING
) -> FloatArray:
    """(7,) joint increments (radians) realising the (6,) palm ``twist`` (metres, radians; world frame) in the
    damped least-squares sense, dq = J⁺ twist with J⁺ = J^T (J J^T + λ² I)^-1 (rotations weighted by
    ``ANGULAR_WEIGHT_M``), plus ``posture_pull`` (7,) radians projected on the null space (I - J⁺ J): a
    redundant arm drifts towards a preferred posture without moving the palm."""
    w = _TWIST_WEIGHTS
    jw = jacobian * w[:, None]
    tw = np.asarray(twist, dtype=np.float64) * w
    pinv = np.linalg.solve(jw @ jw.T + (damping**2) * _EYE6, jw).T  # (J J^T + λ² I) is symmetric
    out: FloatArray = pinv @ tw
    if posture_pull is not None:
        out = out + (np.eye(jacobian.shape[1]) - pinv @ jw) @ np.asarray(posture_pull, dtype=np.float64)
    return out


def rotation_vector(rot: FloatArray) -> FloatArray:
    """(3,) axis times angle (radians, 0..π) of a (3, 3) rotation matrix."""
    cos = max(-1.0, min(1.0, (float(np.trace(rot)) - 1.0) / 2.0))
    angle = math.acos(cos)
    vee = np.array([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])
    if angle < 1e-9:
        return 0.5 * vee
    if math.pi - angle < 1e-6:  # half turn: axis from the symmetric part
        sym = (rot + np.eye(3)) / 2.0
        axis = sym[:, int(np.argmax(np.diag(sym)))]
        return angle * axis / np.linalg.norm(axis)
    out: FloatArray = angle / (2.0 * math.sin(angle)) * vee
    return out


def tick_matrix(quat_xyzw: npt.ArrayLike) -> FloatArray:
    """(3, 3) rotation matrix of a quaternion [x, y, z, w] (world from frame) by pybullet's
    ``getMatrixFromQuaternion``: for the control tick, a fifth of the cost of ``tasks.rotations.matrix_from_quat``
    (scipy's ``Rotation`` with its checks, 8 µs a call), which the rest of pbd uses."""
    q = [float(v) for v in np.asarray(quat_xyzw, dtype=np.float64)]
    return np.asarray(pb.getMatrixFromQuaternion(q), dtype=np.float64).reshape(3, 3)


def pose_error(
    position: FloatArray, quat_xyzw: FloatArray, target_position: npt.ArrayLike, target_quat_xyzw: npt.ArrayLike
) -> FloatArray:
    """(6,) world twist taking the palm pose (``position``, ``quat_xyzw``) to the target: [dp (m), rotation
    vector (rad)]."""
    dp = np.asarray(target_position, dtype=np.float64) - position
    drot = tick_matrix(target_quat_xyzw) @ tick_matrix(quat_xyzw).T
    return np.concatenate([dp, rotation_vector(drot)])


def screw_twist(
    position: FloatArray, axis_point: npt.ArrayLike, axis_dir: npt.ArrayLike, angle_rad: float
) -> FloatArray:
    """(6,) world twist of a palm at ``position`` turned rigidly by ``angle_rad`` about the axis through
    ``axis_point`` along the unit ``axis_dir`` (first order: v = ω × (p - c))."""
    k = np.asarray(axis_dir, dtype=np.float64)
    k = k / np.linalg.norm(k)
    omega = angle_rad * k
    r = position - np.asarray(axis_point, dtype=np.float64)
    v = [omega[1] * r[2] - omega[2] * r[1], omega[2] * r[0] - omega[0] * r[2], omega[0] * r[1] - omega[1] * r[0]]
    return np.concatenate([v, omega])


def line_twist(direction: npt.ArrayLike, distance_m: float) -> FloatArray:
    """(6,) world twist shifting the palm by ``distance_m`` along the unit ``direction``, orientation kept."""
    d = np.asarray(direction, dtype=np.float64)
    return np.concatenate([distance_m * d / np.linalg.norm(d), np.zeros(3)])


def command_for_twist(
    robot: rb.Robot, twist: FloatArray, posture: FloatArray | None = None, posture_gain: float = POSTURE_GAIN
) -> FloatArray:
    """(7,) arm joint targets: the measured angles plus the increment realising ``twist``; with ``posture`` (7,)
    radians, the null space pulls the arm ``posture_gain`` of the way towards it per tick. A joint the increment
    would push past its limit (less ``LIMIT_MARGIN_RAD``) is locked there and the twist re-solved with the others,
    so the redundant arm works round a limit instead of stalling the palm against it."""
    joints = measured_joints(robot)
    q = joints[: len(rb.ARM_JOINTS)]
    lower, upper = rb.ARM_LOWER + LIMIT_MARGIN_RAD, rb.ARM_UPPER - LIMIT_MARGIN_RAD
    pull = None if posture is None else posture_gain * (np.asarray(posture, dtype=np.float64) - q)
    jac = palm_jacobian(robot, joints)
    locked = np.zeros(len(q), dtype=bool)
    dq = np.zeros(len(q))
    for _ in range(LOCK_ROUNDS):
        free = ~locked
        dq = np.zeros(len(q))
        dq[free] = joint_step(jac[:, free], twist, None if pull is None else pull[free])
        over = ((q + dq < lower) & (dq < 0.0)) | ((q + dq > upper) & (dq > 0.0))
        if not over.any():
            break
        locked |= over
    out: FloatArray = np.clip(q + dq, lower, upper)
    return out
