"""Cylinders found in a part's point cloud (metres, world frame): the bar of a handle, the arm of a lever.

A handle or lever on its mount is no single primitive (``primitive_fit`` refuses it), but most of its surface is often
one cylinder: the bar the hand wraps. Found by RANSAC (Schnabel, Wahl & Klein, "Efficient RANSAC for point-cloud shape
detection", 2007): a hypothesis from two points with normals (the axis is perpendicular to both normals; the centre
where the two normal lines meet in the plane across the axis), scored by the points within the tolerance of its side
whose normals point away from its axis; the best one's inliers (the longest run of them along the axis) refined and
checked by ``primitive_fit.fit_cylinder`` and its tolerances. Planned on as one exact piece (a 64-sided prism,
``prism_vertices``) beside the convex pieces of the rest of the part, so the bar's surface does not depend on how
k-means cuts it.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from tasks.arrays import BoolArray, Points
from tasks.grasp.primitive_fit import (
    MIN_POINTS,
    RMS_FRACTION,
    TOLERANCE_M,
    PrimitiveFit,
    PrimitiveShape,
    fit_cylinder,
    supported,
    surface_distance,
)

HYPOTHESES = 256
"""RANSAC hypotheses drawn per cylinder."""
PAIR_NEIGHBOURS = 24
"""A hypothesis pairs a point with one of its this many nearest neighbours."""
MIN_NORMAL_SINE = 0.25
"""The two normals of a hypothesis differ by at least 14.5°, else its axis is ill-defined."""
LINE_MISS_M = 0.003
"""The two normal lines of a hypothesis meet the axis within this of each other (their radii differ by at most)."""
RADIUS_RANGE_M = (0.004, 0.05)
"""Radii looked for: bars, levers and knobs, not the door."""
INLIER_M = 0.002
"""A point within this of a hypothesis's side (and its normal within ``SIDE_COS`` of radial) supports it."""
SIDE_COS = 0.7
"""Cosine between a supporting point's normal and the outward radial direction, at least."""
RUN_GAP_M = 0.015
"""Inliers further apart than this along the axis belong to different runs; the longest run is kept."""
MIN_SHARE = 0.25
"""The cylinder explains at least this share of the part's points."""
MIN_ASPECT = 2.0
"""The cylinder is at least this many radii long (a bar; a sphere's belt or a knob's rim is not one)."""
PRISM_SIDES = 64
"""Sides of the prism standing for a cylinder (0.04 mm from the true surface at 20 mm radius)."""


def find_cylinder(
    points: Points, normals: Points, rng: np.random.Generator, *, tolerance_m: float = TOLERANCE_M
) -> PrimitiveFit | None:
    """The cylinder explaining most of (n, 3) world ``points`` (m) with outward unit ``normals`` (n, 3), when it
    explains at least ``MIN_SHARE`` of them within ``tolerance_m`` (95th percentile; RMS within ``RMS_FRACTION``),
    is a bar (``MIN_ASPECT``) and they cover its side (``primitive_fit.supported``); else None."""
    n = len(points)
    if n < MIN_POINTS:
        return None
    inliers = _best_hypothesis(points, normals, rng)
    if inliers is None or inliers.sum() < max(MIN_POINTS, MIN_SHARE * n):
        return None
    fit = fit_cylinder(points[inliers], normals[inliers])
    if fit is None or fit.p95_m > tolerance_m or fit.rms_m > RMS_FRACTION * tolerance_m:
        return None
    if 2.0 * fit.shape.size[1] < MIN_ASPECT * fit.shape.size[0]:
        return None
    if not supported(fit.shape, points[inliers], tolerance_m):
        return None
    explained = surface_distance(fit.shape, points) <= tolerance_m
    return fit if explained.sum() >= MIN_SHARE * n else None


def _best_hypothesis(points: Points, normals: Points, rng: np.random.Generator) -> BoolArray | None:
    """Inliers (n,) of the best-supported cylinder hypothesis (the longest run along its axis), or None."""
    n = len(points)
    k = min(PAIR_NEIGHBOURS, n - 1)
    _, near = cKDTree(points).query(points, k + 1)
    first = rng.integers(0, n, HYPOTHESES)
    second = near[first, rng.integers(1, k + 1, HYPOTHESES)]
    axis = np.cross(normals[first], normals[second])
    sine = np.linalg.norm(axis, axis=1)
    keep = sine >= MIN_NORMAL_SINE
    first, second, axis = first[keep], second[keep], axis[keep] / sine[keep, None]
    if len(first) == 0:
        return None
    # the normals' components across the axis, and where their lines meet: p_i - t_i m_i = p_j - t_j m_j
    m_i = _across(normals[first], axis)
    m_j = _across(normals[second], axis)
    d = _across(points[first] - points[second], axis)
    pair = np.stack([m_i, -m_j], axis=2)  # t_i m_i - t_j m_j = d, solved by its normal equations
    gram = np.einsum("kai,kaj->kij", pair, pair)
    ok = np.abs(np.linalg.det(gram)) > 1e-9
    t = np.linalg.solve(np.where(ok[:, None, None], gram, np.eye(2)), np.einsum("kai,ka->ki", pair, d)[..., None])
    t_i, t_j = t[:, 0, 0], t[:, 1, 0]
    radius = (t_i + t_j) / 2.0
    ok &= (np.abs(t_i - t_j) <= LINE_MISS_M) & (radius >= RADIUS_RANGE_M[0]) & (radius <= RADIUS_RANGE_M[1])
    if not ok.any():
        return None
    centre = points[first[ok]] - t_i[ok, None] * m_i[ok]
    axis, radius = axis[ok], radius[ok]
    best: BoolArray | None = None
    best_count = 0
    for c, a, r in zip(centre, axis, radius, strict=True):
        rel = points - c
        along = rel @ a
        radial = rel - along[:, None] * a
        dist = np.linalg.norm(radial, axis=1)
        outward = np.einsum("ij,ij->i", normals, radial) / np.maximum(dist, 1e-12)
        inl = (np.abs(dist - r) <= INLIER_M) & (outward >= SIDE_COS)
        if inl.sum() <= best_count:
            continue
        run = _longest_run(along, inl)
        if run.sum() > best_count:
            best, best_count = run, int(run.sum())
    return best


def _across(vectors: Points, axis: Points) -> Points:
    """Rows of ``vectors`` without their components along the unit rows of ``axis``."""
    out: Points = vectors - np.einsum("ij,ij->i", vectors, axis)[:, None] * axis
    return out


def _longest_run(along: np.ndarray, inliers: BoolArray) -> BoolArray:
    """The inliers of the longest run along the axis (gaps over ``RUN_GAP_M`` split runs)."""
    idx = np.flatnonzero(inliers)
    order = idx[np.argsort(along[idx])]
    cuts = np.flatnonzero(np.diff(along[order]) > RUN_GAP_M) + 1
    runs = np.split(order, cuts)
    longest = max(runs, key=len)
    out = np.zeros(len(along), dtype=bool)
    out[longest] = True
    return out


def prism_vertices(shape: PrimitiveShape, sides: int = PRISM_SIDES) -> Points:
    """Vertices (2 ``sides``, 3), world m, of the prism standing for a cylinder ``shape`` (radius, half height)."""
    radius, half = shape.size[0], shape.size[1]
    theta = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    ring = np.column_stack([radius * np.cos(theta), radius * np.sin(theta)])
    local = np.concatenate([np.column_stack([ring, np.full(sides, z)]) for z in (-half, half)])
    out: Points = Rotation.from_quat(shape.quat_xyzw).apply(local) + np.asarray(shape.position)
    return out
