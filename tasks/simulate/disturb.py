"""Disturbed descriptors for the compliance test: each primitive's axis moved and tilted by a fixed amount."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from schemas.descriptor import Descriptor, Primitive
from tasks.arrays import FloatArray
from tasks.simulate.waypoints import matrix_from_axis_angle, unit


def _perpendicular(direction: FloatArray, rng: np.random.Generator) -> FloatArray:
    """A random unit vector perpendicular to the unit ``direction``."""
    while True:
        v = rng.normal(size=3)
        v -= (v @ direction) * direction
        norm = float(np.linalg.norm(v))
        if norm > 1e-6:
            return v / norm


def disturb_primitive(prim: Primitive, shift_m: float, tilt_deg: float, rng: np.random.Generator) -> Primitive:
    """``prim`` with its direction tilted by exactly ``tilt_deg`` (about a random perpendicular axis) and, for a
    rotation, its axis point moved by exactly ``shift_m`` metres in a random direction perpendicular to the axis."""
    d = unit(prim.dir, "dir")
    tilted = matrix_from_axis_angle(_perpendicular(d, rng), math.radians(tilt_deg)) @ d
    pos = prim.pos
    if pos is not None:
        p = np.asarray(pos, dtype=np.float64) + shift_m * _perpendicular(d, rng)
        pos = (float(p[0]), float(p[1]), float(p[2]))
    return replace(prim, pos=pos, dir=(float(tilted[0]), float(tilted[1]), float(tilted[2])))


def disturb_descriptor(desc: Descriptor, shift_m: float, tilt_deg: float, rng: np.random.Generator) -> Descriptor:
    """``desc`` with every primitive disturbed (``disturb_primitive``); the grasp is unchanged."""
    chain = tuple(disturb_primitive(p, shift_m, tilt_deg, rng) for p in desc.chain)
    return replace(desc, chain=chain)
