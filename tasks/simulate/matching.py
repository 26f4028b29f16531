"""Which scene joint does each primitive of a descriptor drive? Matched by axis, in the world frame.

A rotation primitive matches a revolute joint, a translation primitive a prismatic one. The score of a pair is
the angle between the two axis lines (0..90°, direction sign ignored) and, for rotations, the distance of the
primitive's axis point ``pos`` from the joint's axis line. The sign tells whether the demonstrated positive
motion is a positive or negative motion of the joint.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from schemas.descriptor import Primitive
from tasks.arrays import Vector3
from tasks.errors import SimulationError

MAX_AXIS_ANGLE_RAD = math.radians(20.0)
"""A primitive's axis may differ from its joint's axis by up to 20° (learned axes are within a few degrees)."""
MAX_AXIS_DISTANCE_M = 0.10
"""... and its axis point may lie up to 10 cm from the joint's axis line."""


@dataclass(frozen=True)
class JointAxis:
    """An articulated joint of the scene: ``kind``, axis ``point`` (3,) metres and unit ``direction`` (3,), world."""

    name: str
    kind: Literal["revolute", "prismatic"]
    point: Vector3
    direction: Vector3


@dataclass(frozen=True)
class JointMatch:
    """Primitive ``primitive`` drives joint ``joint``; ``sign`` = +1 if the primitive's positive motion is the
    joint's positive motion, else -1; axis angle (radians) and distance (metres) of the pair."""

    primitive: int
    joint: str
    sign: float
    angle_rad: float
    distance_m: float


def axis_angle_rad(a: Vector3, b: Vector3) -> float:
    """Angle between two axis lines, radians in 0..π/2 (the directions' signs ignored)."""
    cos = abs(float(a @ b) / float(np.linalg.norm(a) * np.linalg.norm(b)))
    return math.acos(min(1.0, cos))


def point_line_distance_m(point: Vector3, line_point: Vector3, line_dir: Vector3) -> float:
    """Distance (metres) of ``point`` from the line through ``line_point`` along ``line_dir``."""
    d = line_dir / np.linalg.norm(line_dir)
    v = point - line_point
    return float(np.linalg.norm(v - (v @ d) * d))


def match_primitive(
    index: int,
    primitive: Primitive,
    joints: Sequence[JointAxis],
    *,
    max_angle_rad: float = MAX_AXIS_ANGLE_RAD,
    max_distance_m: float = MAX_AXIS_DISTANCE_M,
) -> JointMatch:
    """The joint that primitive ``index`` drives; ``SimulationError`` naming the primitive and the distance."""
    kind = "revolute" if primitive.kind == "rotation" else "prismatic"
    label = f"primitive {index} ({primitive.kind})"
    candidates = [j for j in joints if j.kind == kind]
    if not candidates:
        msg = f"{label}: no {kind} joint in the scene to drive (joints: {', '.join(j.name for j in joints) or 'none'})"
        raise SimulationError(msg)
    direction = np.asarray(primitive.dir, dtype=np.float64)
    best: JointMatch | None = None
    best_score = math.inf
    for joint in candidates:
        angle = axis_angle_rad(direction, joint.direction)
        distance = 0.0
        if primitive.pos is not None and kind == "revolute":
            distance = point_line_distance_m(np.asarray(primitive.pos, dtype=np.float64), joint.point, joint.direction)
        score = angle / max_angle_rad + distance / max_distance_m
        if score < best_score:
            sign = 1.0 if float(direction @ joint.direction) >= 0.0 else -1.0
            best, best_score = JointMatch(index, joint.name, sign, angle, distance), score
    assert best is not None
    if best.angle_rad > max_angle_rad or best.distance_m > max_distance_m:
        msg = (
            f"{label}: axis is {best.distance_m:.3f} m and {math.degrees(best.angle_rad):.1f}° from the nearest "
            f"{kind} joint {best.joint} (limits {max_distance_m:.2f} m, {math.degrees(max_angle_rad):.0f}°)"
        )
        raise SimulationError(msg)
    return best


def match_chain(chain: Sequence[Primitive], joints: Sequence[JointAxis]) -> tuple[JointMatch, ...]:
    """Match every primitive of the chain to a scene joint (see ``match_primitive``); an empty chain is an error."""
    if not chain:
        msg = "descriptor has an empty manipulation chain: nothing to execute"
        raise SimulationError(msg)
    return tuple(match_primitive(i, p, joints) for i, p in enumerate(chain))
