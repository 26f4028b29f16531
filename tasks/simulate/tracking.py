"""The primitive's axis corrected from the measured motion of the hand that holds the part.

While the hand holds the part, the palm's measured pose (the arm's forward kinematics from its joint angles)
moves with the part. Once it has turned far enough, the rotation from the palm's start pose to its pose now gives
the part's actual axis: its direction is that rotation's axis, and its position the line of points the rotation
leaves fixed. (For a translation, the palm's displacement gives the direction.) The executor steps about this
measured axis instead of the descriptor's, blended in as the motion grows, so a learned axis a few millimetres
or degrees off stops costing progress (Karayiannidis et al.'s door opening with an uncertain hinge estimates
the axis from the end effector's motion in the same spirit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from schemas.descriptor import Primitive
from tasks.arrays import FloatArray
from tasks.simulate.control import rotation_vector, tick_matrix

BLEND_START_RAD = 0.1
BLEND_FULL_RAD = 0.3
"""A rotation's measured axis is trusted from 0.1 rad of palm turn, fully from 0.3 rad (a short arc's axis is
poorly determined: 1 mm of grasp compliance over 6 degrees at 0.4 m is 1.5 % of the chord) ..."""
BLEND_START_M = 0.02
BLEND_FULL_M = 0.05
"""... a translation's from 2 cm, fully from 5 cm."""
MAX_TILT_RAD = math.radians(15.0)
MAX_SHIFT_M = 0.05
"""A measured axis more than 15 degrees or 5 cm from the descriptor's is not believed (the hand slipped)."""


@dataclass(frozen=True)
class AxisTracker:
    """The primitive ``prim`` being executed and the palm's pose when it began (``p0`` (3,) m, ``q0`` (4,)
    [x, y, z, w], world)."""

    prim: Primitive
    p0: FloatArray
    q0: FloatArray

    @cached_property
    def start_rotation_t(self) -> FloatArray:
        """(3, 3) transpose of the palm's world rotation when the primitive began."""
        return tick_matrix(self.q0).T

    def corrected(self, p: FloatArray, q: FloatArray) -> Primitive:
        """The primitive with its axis blended towards the one the palm's motion from (p0, q0) to (``p``, ``q``)
        shows (unchanged while that motion is too short or implausible)."""
        if self.prim.kind == "rotation":
            return self._rotation(p, q)
        return self._translation(p)

    def _rotation(self, p: FloatArray, q: FloatArray) -> Primitive:
        assert self.prim.pos is not None
        d = np.asarray(self.prim.dir, dtype=np.float64)
        d /= np.linalg.norm(d)
        rot = tick_matrix(q) @ self.start_rotation_t
        rv = rotation_vector(rot)
        angle = float(np.linalg.norm(rv))
        if angle < BLEND_START_RAD:
            return self.prim
        k = rv / angle
        if math.acos(min(1.0, float(k @ d))) > MAX_TILT_RAD:
            return self.prim
        pos = np.asarray(self.prim.pos, dtype=np.float64)
        # the palm turned rigidly about (c, k): p - R p0 = (I - R) c; with c = pos + offset, offset ⟂ k, solve
        # (I - R) offset = b in the plane ⟂ k, where I - R acts as 1 - e^{iθ}, whose inverse is ½ + ½ cot(θ/2) k×
        b = p - rot @ self.p0 - (pos - rot @ pos)
        b -= (b @ k) * k
        offset = 0.5 * b + 0.5 / math.tan(0.5 * angle) * np.cross(k, b)
        if float(np.linalg.norm(offset)) > MAX_SHIFT_M:
            return self.prim
        w = min(1.0, (angle - BLEND_START_RAD) / (BLEND_FULL_RAD - BLEND_START_RAD))
        new_dir = (1.0 - w) * d + w * k
        new_dir /= np.linalg.norm(new_dir)
        new_pos = pos + w * offset
        return replace(self.prim, pos=_vec(new_pos), dir=_vec(new_dir))

    def _translation(self, p: FloatArray) -> Primitive:
        d = np.asarray(self.prim.dir, dtype=np.float64)
        d /= np.linalg.norm(d)
        moved = p - self.p0
        dist = float(np.linalg.norm(moved))
        if dist < BLEND_START_M:
            return self.prim
        k = moved / dist
        if math.acos(min(1.0, float(k @ d))) > MAX_TILT_RAD:
            return self.prim
        w = min(1.0, (dist - BLEND_START_M) / (BLEND_FULL_M - BLEND_START_M))
        new_dir = (1.0 - w) * d + w * k
        return replace(self.prim, dir=_vec(new_dir / np.linalg.norm(new_dir)))


def _vec(v: FloatArray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))
