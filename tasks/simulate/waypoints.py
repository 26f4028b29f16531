"""Cartesian hand waypoints along a manipulation primitive, and the small rotation helpers they need.

Poses are (position (3,) metres, quaternion (4,) [x, y, z, w]) in the world frame. A rotation primitive moves
the hand rigidly with the part: every waypoint is the start pose turned about the axis (``axis_point``,
``axis_dir``) by a growing angle, so the hand turns with the part (paper Section V-A). A translation primitive
shifts the start pose along ``direction``, keeping its orientation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from tasks.arrays import FloatArray, Points, Quats, check_vector3
from tasks.rotations import matrix_from_quat, quat_from_matrix

ARC_STEP_RAD = math.radians(1.0)
"""Default angular spacing of waypoints along an arc (1°)."""
LINE_STEP_M = 0.005
"""Default spacing of waypoints along a line (5 mm)."""


def unit(vector: npt.ArrayLike, name: str = "vector") -> FloatArray:
    """(3,) unit vector of ``vector``; ``ValueError`` naming it if it is (near) zero."""
    v = check_vector3(vector, name)
    norm = float(np.linalg.norm(v))
    if not math.isfinite(norm) or norm < 1e-12:
        msg = f"{name}: expected a non-zero finite direction, got {v.tolist()}"
        raise ValueError(msg)
    return v / norm


def matrix_from_axis_angle(axis: npt.ArrayLike, angle_rad: float) -> FloatArray:
    """(3, 3) rotation by ``angle_rad`` (right-hand rule) about the unit ``axis`` (Rodrigues' formula)."""
    k = unit(axis, "axis")
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    out: FloatArray = np.eye(3) + math.sin(angle_rad) * K + (1.0 - math.cos(angle_rad)) * (K @ K)
    return out


def angle_between_quats(a_xyzw: npt.ArrayLike, b_xyzw: npt.ArrayLike) -> float:
    """Rotation angle (radians, 0..π) taking orientation ``a`` to ``b``."""
    a = np.asarray(a_xyzw, dtype=np.float64)
    b = np.asarray(b_xyzw, dtype=np.float64)
    dot = abs(float(a @ b) / float(np.linalg.norm(a) * np.linalg.norm(b)))
    return 2.0 * math.acos(min(1.0, dot))


@dataclass(frozen=True)
class Waypoints:
    """Hand poses along a primitive: ``positions`` (n, 3) metres and ``quats`` (n, 4) [x, y, z, w], world frame;
    ``progress`` (n,) the primitive's motion at each waypoint (radians for an arc, metres for a line)."""

    positions: Points
    quats: Quats
    progress: FloatArray

    def __len__(self) -> int:
        """Number of waypoints (the start pose included)."""
        return int(self.positions.shape[0])


def _steps(extent: float, step: float) -> FloatArray:
    if not math.isfinite(extent) or extent < 0.0:
        msg = f"extent: expected a finite value >= 0, got {extent}"
        raise ValueError(msg)
    if not step > 0.0:
        msg = f"step: expected > 0, got {step}"
        raise ValueError(msg)
    n = max(1, math.ceil(extent / step - 1e-9))
    return np.linspace(0.0, extent, n + 1)


def arc_waypoints(
    start_position: npt.ArrayLike,
    start_quat_xyzw: npt.ArrayLike,
    axis_point: npt.ArrayLike,
    axis_dir: npt.ArrayLike,
    angle_rad: float,
    *,
    step_rad: float = ARC_STEP_RAD,
) -> Waypoints:
    """Hand poses turning rigidly about the axis through ``axis_point`` along ``axis_dir`` by 0..``angle_rad``.

    Waypoints are evenly spaced, at most ``step_rad`` apart; the first is the start pose, the last is the start
    pose turned by exactly ``angle_rad`` (right-hand rule about ``axis_dir``).
    """
    p0 = check_vector3(start_position, "start_position")
    R0 = matrix_from_quat(start_quat_xyzw)
    c = check_vector3(axis_point, "axis_point")
    k = unit(axis_dir, "axis_dir")
    angles = _steps(angle_rad, step_rad)
    positions = np.empty((angles.size, 3))
    quats = np.empty((angles.size, 4))
    for i, theta in enumerate(angles):
        R = matrix_from_axis_angle(k, float(theta))
        positions[i] = c + R @ (p0 - c)
        quats[i] = quat_from_matrix(R @ R0)
    return Waypoints(positions, quats, angles)


def line_waypoints(
    start_position: npt.ArrayLike,
    start_quat_xyzw: npt.ArrayLike,
    direction: npt.ArrayLike,
    distance_m: float,
    *,
    step_m: float = LINE_STEP_M,
) -> Waypoints:
    """Hand poses shifted along the unit ``direction`` by 0..``distance_m`` metres, orientation unchanged."""
    p0 = check_vector3(start_position, "start_position")
    q0 = quat_from_matrix(matrix_from_quat(start_quat_xyzw))
    d = unit(direction, "direction")
    dist = _steps(distance_m, step_m)
    positions = p0[None, :] + dist[:, None] * d[None, :]
    quats = np.tile(q0, (dist.size, 1))
    return Waypoints(positions, quats, dist)


def approach_axis(quat_xyzw: npt.ArrayLike) -> FloatArray:
    """(3,) world direction of the palm's +z axis (the Barrett hand's approach direction)."""
    return matrix_from_quat(quat_xyzw)[:, 2]
