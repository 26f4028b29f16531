"""The wrist tracker: its mount on the Barrett hand (the pose sensor's offset from the palm frame of ``barrett.py``),
its pose at a time, and the stillest moment before the part moves, when the hand rested on it (the grasp's seed).

Poses are world positions (3,) in metres and quaternions [x, y, z, w]; the palm frame is ``barrett.py``'s (+z the
approach). A demonstration records the tracker; the grasp is planned and executed for the palm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from tasks.arrays import FloatArray, Vector3
from tasks.errors import GraspError
from tasks.recording.load import PoseTrack


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


SEED_WINDOW_S = 1.0
"""The seed is the stillest wrist pose within this long before the first primitive's start (``stillest_time_ns``)."""


def wrist_pose_at(track: PoseTrack, stamp_ns: int) -> tuple[Vector3, FloatArray]:
    """Tracker pose at ``stamp_ns`` (positions linear, orientations slerped; clamped to the track's span)."""
    ok = np.all(np.isfinite(track.positions), axis=1) & np.all(np.isfinite(track.quats), axis=1)
    stamps = np.asarray(track.stamps_ns)[ok]
    if len(stamps) == 0:
        msg = f"wrist track {track.frame}: no finite samples"
        raise GraspError(msg)
    positions = np.asarray(track.positions, dtype=np.float64)[ok]
    quats = np.asarray(track.quats, dtype=np.float64)[ok]
    t = float(np.clip(stamp_ns, stamps[0], stamps[-1]) - stamps[0]) * 1e-9
    times = (stamps - stamps[0]).astype(np.float64) * 1e-9
    if len(stamps) == 1 or not np.all(np.diff(times) > 0):
        i = int(np.argmin(np.abs(times - t)))
        return positions[i], quats[i] / np.linalg.norm(quats[i])
    pos = np.array([np.interp(t, times, positions[:, k]) for k in range(3)])
    return pos, Slerp(times, Rotation.from_quat(quats))(t).as_quat()


def stillest_time_ns(track: PoseTrack, stamp_ns: int, window_s: float = SEED_WINDOW_S) -> int:
    """The stamp (ns) in ``[stamp_ns - window_s, stamp_ns]`` where the wrist moves least (over ±0.1 s: 10 mm or
    2° count alike; near-ties go to the latest): the moment the demonstrator's hand rested on the part while
    closing, the grasp. A primitive's detected start can come late, after the hand began turning the part."""
    half_ns = 100_000_000
    times: list[int] = []
    costs: list[float] = []
    for k in range(round(window_s / 0.05), -1, -1):
        t = stamp_ns - k * 50_000_000
        p0, q0 = wrist_pose_at(track, t - half_ns)
        p1, q1 = wrist_pose_at(track, t + half_ns)
        turn = float((Rotation.from_quat(q0).inv() * Rotation.from_quat(q1)).magnitude())
        times.append(t)
        costs.append(float(np.linalg.norm(p1 - p0)) / 0.01 + turn / math.radians(2.0))
    floor = min(costs) + 0.25  # ties (within 2.5 mm or 0.5°) go to the latest moment
    return max(t for t, c in zip(times, costs, strict=True) if c <= floor)
