"""Points sampled uniformly on the surfaces of simple shapes (metres, the shape's own frame), with outward unit
normals: stand-ins for scans of boxes, cylinders and handles (tests and ``bench/grasp.py``)."""

from __future__ import annotations

import math

import numpy as np

from tasks.arrays import FloatArray, Points


def sample_box_surface(half: FloatArray, n: int, rng: np.random.Generator) -> tuple[Points, Points]:
    """``n`` points uniformly on a box surface (half extents, m, centred at the origin) and outward normals."""
    h = np.asarray(half, dtype=np.float64)
    areas = np.array([h[1] * h[2], h[1] * h[2], h[0] * h[2], h[0] * h[2], h[0] * h[1], h[0] * h[1]])
    face = rng.choice(6, size=n, p=areas / areas.sum())
    pts = rng.uniform(-h, h, size=(n, 3))
    nrm = np.zeros((n, 3))
    axis = face // 2
    sign = np.where(face % 2 == 0, 1.0, -1.0)
    pts[np.arange(n), axis] = sign * h[axis]
    nrm[np.arange(n), axis] = sign
    return pts, nrm


def sample_cylinder_surface(
    radius: float, half_height: float, n: int, rng: np.random.Generator
) -> tuple[Points, Points]:
    """``n`` points on a closed cylinder (axis z, centred at the origin) and outward normals."""
    side = 2 * math.pi * radius * 2 * half_height
    cap = math.pi * radius**2
    kind = rng.choice(3, size=n, p=np.array([side, cap, cap]) / (side + 2 * cap))
    theta = rng.uniform(0, 2 * math.pi, n)
    r = np.where(kind == 0, radius, radius * np.sqrt(rng.uniform(0, 1, n)))
    z = np.where(kind == 0, rng.uniform(-half_height, half_height, n), np.where(kind == 1, half_height, -half_height))
    pts = np.stack([r * np.cos(theta), r * np.sin(theta), z], axis=1)
    nrm = np.where(
        (kind == 0)[:, None],
        np.stack([np.cos(theta), np.sin(theta), np.zeros(n)], axis=1),
        np.stack([np.zeros(n), np.zeros(n), np.where(kind == 1, 1.0, -1.0)], axis=1),
    )
    return pts, nrm
