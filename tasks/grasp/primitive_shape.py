"""A box or cylinder in the world, the exact shape a grasp is planned on when one explains the object's points."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

MIN_POINTS = 30
"""Fewest object points a grasp is planned on."""


@dataclass(frozen=True)
class PrimitiveShape:
    """A known shape in the world: ``kind`` box (``size`` = half extents, m) or cylinder (radius, half height,
    axis = local z); ``position`` (3,) m and ``quat_xyzw`` (4,) of its centre frame."""

    kind: Literal["box", "cylinder"]
    size: tuple[float, float, float]
    position: tuple[float, float, float]
    quat_xyzw: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
