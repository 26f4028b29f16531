"""The mount behind a grasped part: the face a handle, a lever or a knob stands on (a door leaf, an oven door).

A grasp is planned on the part the hand reaches for; the face that part is fixed to is only an obstacle. Counted as part
of the object, it gives fingertips resting on it a share in the grasp: a planned force closure whose fingertips pressed
on a door's leaf behind its lever pushed the part away as soon as it was a free body (the shake test), and held the
lever by nothing. The mount is found as one of the largest planes of the object model (scikit-learn's
``RANSACRegressor``, depth along the approach as a linear function of the two coordinates across it: seeded, so the same
scan gives the same mount) that faces the hand (its normal within ``MAX_TILT_RAD`` of the approach axis), is wider than
the hand (``MIN_SPAN_M``), is not a strip (``MIN_WIDTH_M``) and lies at least ``MIN_DEPTH_M`` behind the surface nearest
the palm along the approach (something stands in front of it: the part). A box face or a cylinder the palm meets first
is never a mount. World frame, metres.
"""

from __future__ import annotations

import math

import numpy as np
from sklearn.linear_model import RANSACRegressor

from tasks.arrays import BoolArray, FloatArray, Points, Vector3
from tasks.fit.geometry import perpendicular_basis

PLANE_TOLERANCE_M = 0.003
"""Points within 3 mm of the plane are on it (a scan's noise and its 4 mm voxels)."""
MIN_SHARE = 0.15
"""The plane holds at least this share of the object points."""
MIN_SPAN_M = 0.12
"""Its points span at least this much across (the open Barrett hand is about 0.2 m across)."""
MIN_WIDTH_M = 0.05
"""... and at least this much in the other direction: the strip of a cylinder's back within the plane tolerance
is 20-30 mm wide for radii of 15-40 mm, a handle's plate 60 mm."""
MIN_DEPTH_M = 0.015
"""It lies at least this far behind the object surface nearest the palm, along the approach."""
MAX_TILT_RAD = math.radians(35.0)
"""Its normal lies within this angle of the approach axis."""
RANSAC_ITERATIONS = 150
"""RANSAC trials per plane (scikit-learn stops sooner once a plane holds enough points; 120-180 ms per model)."""
PLANES = 3
"""Planes tried, largest first."""
FIT_POINTS = 600
"""Points (an even subsample) each plane is fitted on; every point is then tested against it. On a scan of a few
thousand points the time goes to scikit-learn's per-trial overhead, not to the point count."""


def find_mount(points: Points, palm_position: Vector3, approach: Vector3) -> BoolArray:
    """(n,) True for the points on the mount behind the part (see the module docstring): the face nearest the
    palm and all behind it (a plate's edges and back); all False when there is none. ``points`` (n, 3) world m;
    ``palm_position`` (3,) m and unit ``approach`` (3,): the demonstrated palm. The ``PLANES`` largest planes
    are tried (a slanted plane through a handle's bar and the edges of its plate can hold more points than the
    plate's face; a plate's back face as many as its front)."""

    axis = np.asarray(approach, dtype=np.float64) / float(np.linalg.norm(approach))
    depth = (points - np.asarray(palm_position, dtype=np.float64)) @ axis
    across = in_plane(axis)
    uv = points @ across  # coordinates across the approach: the mount's depth is a function of them
    left = np.arange(len(points))
    best: BoolArray | None = None
    best_depth = np.inf
    for k in range(PLANES):
        if len(left) < MIN_SHARE * len(points):
            break
        sample = left[:: max(1, len(left) // FIT_POINTS)]  # an even subsample fits the plane; all points test it
        ransac = ransac_plane(uv[sample], depth[sample], PLANE_TOLERANCE_M, RANSAC_ITERATIONS, k)
        if ransac is None:
            break
        on = np.zeros(len(points), dtype=bool)
        residual = np.abs(ransac.predict(uv[left]) - depth[left])
        on[left[residual < PLANE_TOLERANCE_M]] = True
        slope = np.asarray(ransac.estimator_.coef_, dtype=np.float64)
        normal = axis - across @ slope  # depth = slope . uv + c: the plane's normal, towards +approach
        if _is_mount(points, on, normal, axis, depth) and float(np.median(depth[on])) < best_depth:
            away = normal / float(np.linalg.norm(normal))
            best = on | ((points - points[on].mean(axis=0)) @ away > -PLANE_TOLERANCE_M)
            best_depth = float(np.median(depth[on]))
        left = left[~on[left]]
    return best if best is not None and not best.all() else np.zeros(len(points), dtype=bool)


def _is_mount(points: Points, on: BoolArray, normal: Vector3, axis: Vector3, depth: np.ndarray) -> bool:
    """Whether the plane (its points ``on``, unit-less ``normal``) is a mount for the approach ``axis``, with
    ``depth`` (n,) m of every point along it from the palm."""
    if on.sum() < MIN_SHARE * len(points) or on.all():
        return False
    unit = normal / float(np.linalg.norm(normal))
    if abs(float(unit @ axis)) < math.cos(MAX_TILT_RAD):
        return False
    if float(np.median(depth[on])) - float(depth[~on].min()) < MIN_DEPTH_M:
        return False
    flat = (points[on] - points[on].mean(axis=0)) @ in_plane(unit)
    _, axes = np.linalg.eigh(flat.T @ flat)  # the plane's points' own principal directions, shortest first
    narrow, wide = np.ptp(flat @ axes, axis=0)
    return float(wide) >= MIN_SPAN_M and float(narrow) >= MIN_WIDTH_M


def in_plane(normal: Vector3) -> FloatArray:
    """(3, 2) two unit vectors spanning the plane of ``normal`` (``tasks.fit.geometry.perpendicular_basis``)."""
    return np.stack(perpendicular_basis(normal), axis=1)


def ransac_plane(uv: Points, depth: FloatArray, tolerance_m: float, trials: int, seed: int) -> RANSACRegressor | None:
    """scikit-learn's seeded RANSAC of ``depth`` (n,) m as a linear function of the coordinates ``uv`` (n, 2) m
    across it, its points within ``tolerance_m``; None when no consensus set is found."""
    ransac = RANSACRegressor(min_samples=3, residual_threshold=tolerance_m, max_trials=trials, random_state=seed)
    try:
        ransac.fit(uv, depth)
    except ValueError:
        return None
    return ransac
