"""Grasp planning entry points used by the learn stage (``G`` of the descriptor, DESCRIPTOR.md).

The wrist seed is the demonstrator's wrist pose (world frame, metres, quaternion [x, y, z, w]); the planner
searches Barrett eigengrasp amplitudes and a wrist pose near it (Dang & Allen, GraspIt! online planner).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import numpy.typing as npt

from schemas.descriptor import Grasp
from tasks.arrays import Points, Quats, StampsNs, Vector3
from tasks.errors import GraspError


class WristTrack(Protocol):
    """What the planner reads from a ``PoseTrack`` (tasks.recording.load): stamps (ns), positions (m), quats."""

    @property
    def stamps_ns(self) -> StampsNs:
        """(n,) int64 time stamps, nanoseconds."""

    @property
    def positions(self) -> Points:
        """(n, 3) float64 positions, metres, world frame."""

    @property
    def quats(self) -> Quats:
        """(n, 4) float64 orientations [x, y, z, w], world frame."""


def plan_grasp_for_recording(
    object_points: Points | None,
    wrist: WristTrack | None,
    t_seed_s: float | None,
    start_ns: int,
    rng: np.random.Generator,
) -> Grasp | None:
    """Plan a Barrett grasp for a recording: None without an object model (stub: always None for now)."""
    del object_points, wrist, t_seed_s, start_ns, rng
    return None


def plan_grasp(
    object_points: Points,
    seed_position: Vector3,
    seed_quat_xyzw: npt.NDArray[np.float64],
    rng: np.random.Generator,
) -> Grasp:
    """Plan a force-closure Barrett grasp on ``object_points`` (world, metres) near the seed wrist pose."""
    del object_points, seed_position, seed_quat_xyzw, rng
    msg = "not implemented yet"
    raise GraspError(msg)
