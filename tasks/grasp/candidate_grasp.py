"""The descriptor's grasp ``G`` (DESCRIPTOR.md) for a planned candidate: hand, eigengrasp amplitudes, palm pose
(world, metres, quaternion [x, y, z, w]) and qualities."""

from __future__ import annotations

from schemas.descriptor import Grasp
from tasks.grasp.execution import GraspCandidate
from tasks.hand import barrett

HAND = "barrett"
"""The hand every planned grasp is for."""


def grasp_from_candidate(candidate: GraspCandidate) -> Grasp:
    """The descriptor's ``Grasp`` for a planned candidate (pre-grasp amplitudes, palm pose, qualities)."""
    q = candidate.quality
    return Grasp(
        hand=HAND,
        eigengrasps=(barrett.spread_amplitude(float(candidate.closed[0])), barrett.CLOSE_AMPLITUDE),
        wrist_position=(float(candidate.position[0]), float(candidate.position[1]), float(candidate.position[2])),
        wrist_orientation=(
            float(candidate.quat_xyzw[0]),
            float(candidate.quat_xyzw[1]),
            float(candidate.quat_xyzw[2]),
            float(candidate.quat_xyzw[3]),
        ),
        quality={
            "epsilon": q.epsilon,
            "volume": q.volume,
            "force_closure": q.force_closure,
            "contacts": q.contacts,
            "mu": q.mu,
            "closed_dofs": [float(candidate.closed[0]), *(float(v) for v in candidate.closed[1:4])],
            "demo_offset_m": candidate.offset_m,
            "demo_angle_rad": candidate.angle_rad,
        },
    )
