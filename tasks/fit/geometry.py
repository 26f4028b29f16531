"""Small geometric helpers: orthonormal bases, points nearest an axis, angle unwrapping."""

from __future__ import annotations

import numpy as np

from tasks.arrays import FloatArray, Vector3


def unit(v: FloatArray) -> Vector3:
    """``v`` scaled to unit length (``v`` must be non-zero)."""
    out: Vector3 = np.asarray(v, dtype=np.float64) / float(np.linalg.norm(v))
    return out


def perpendicular_basis(direction: Vector3) -> tuple[Vector3, Vector3]:
    """Two unit vectors e1, e2 with (e1, e2, direction) right-handed and orthonormal."""
    d = unit(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = unit(np.cross(d, helper))
    e2 = np.cross(d, e1)
    return e1, e2


def nearest_on_axis(point: Vector3, axis_point: Vector3, axis_dir: Vector3) -> Vector3:
    """The point of the line (axis_point, axis_dir) nearest ``point`` (metres)."""
    d = unit(axis_dir)
    out: Vector3 = axis_point + float(np.dot(point - axis_point, d)) * d
    return out


def point_line_distance(point: Vector3, axis_point: Vector3, axis_dir: Vector3) -> float:
    """Distance from ``point`` to the line (axis_point, axis_dir), metres."""
    return float(np.linalg.norm(point - nearest_on_axis(point, axis_point, axis_dir)))


def angle_between_axes(a: Vector3, b: Vector3, *, signed: bool = True) -> float:
    """Angle between two directions, radians; with ``signed=False`` a and -a count as the same axis."""
    c = float(np.dot(unit(a), unit(b)))
    if not signed:
        c = abs(c)
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def net_change(values: FloatArray, k: int = 1) -> float:
    """End minus start of a sequence, each averaged over ``k`` samples (k > 1 trades end bias for noise)."""
    k = max(1, min(k, len(values) // 4 or 1))
    return float(np.mean(values[-k:]) - np.mean(values[:k]))
