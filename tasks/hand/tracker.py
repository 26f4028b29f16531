"""The wrist tracker's mount on the Barrett hand: the pose sensor's offset from the palm frame of ``barrett.py``.

Poses are world positions (3,) in metres and quaternions [x, y, z, w]; the palm frame is ``barrett.py``'s (+z the
approach). A demonstration records the tracker; the grasp is planned and executed for the palm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Vector3


@dataclass(frozen=True)
class PalmOffset:
    """Sensor-to-palm transform: palm = sensor · Trans(translation_m) · R, R = Rz(yaw) then Ry(pitch) (intrinsic)."""

    translation_m: tuple[float, float, float] = (0.0, -0.060, -0.035)
    yaw_rad: float = math.radians(90.0)
    pitch_rad: float = math.radians(30.0)

    def rotation(self) -> Rotation:
        """The offset's rotation (sensor frame to palm frame)."""
        return Rotation.from_euler("ZY", [self.yaw_rad, self.pitch_rad])


GRASPIT_TRACKER_OFFSET = PalmOffset()
"""GraspIt!'s Barrett model: tracker at (0, -60, -35) mm, then 90° about z and 30° about y."""


def palm_from_sensor(
    position: Vector3, quat_xyzw: FloatArray, offset: PalmOffset = GRASPIT_TRACKER_OFFSET
) -> tuple[Vector3, FloatArray]:
    """Palm pose (position (3,) m, quaternion [x, y, z, w]) in the world for a tracker pose in the world."""
    sensor = Rotation.from_quat(quat_xyzw)
    palm_pos = np.asarray(position, dtype=np.float64) + sensor.apply(np.array(offset.translation_m))
    return palm_pos, (sensor * offset.rotation()).as_quat()


def sensor_from_palm(
    position: Vector3, quat_xyzw: FloatArray, offset: PalmOffset = GRASPIT_TRACKER_OFFSET
) -> tuple[Vector3, FloatArray]:
    """Tracker pose (position (3,) m, quaternion [x, y, z, w], world) whose palm is the given world pose: the
    inverse of ``palm_from_sensor``, for writing a wrist track that seeds a wanted palm pose."""
    sensor = Rotation.from_quat(quat_xyzw) * offset.rotation().inv()
    sensor_pos = np.asarray(position, dtype=np.float64) - sensor.apply(np.array(offset.translation_m))
    return sensor_pos, sensor.as_quat()
