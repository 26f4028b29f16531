"""The mount behind a grasped part: the face a handle, a lever or a knob stands on (a door leaf, an oven door), or the
neck and body under a cap (``find_cap``).

A grasp is planned on the part the hand reaches for; the face that part is fixed to is only an obstacle: fingertips
pressing it hold nothing of the part once it is a free body (the shake test). The mount is one of the largest planes of
the model (scikit-learn's seeded ``RANSACRegressor``, depth along the approach a linear function of the two coordinates
across it) that faces the hand (``MAX_TILT_RAD``), is wider than the hand (``MIN_SPAN_M``), is not a strip
(``MIN_WIDTH_M``) and lies at least ``MIN_DEPTH_M`` behind the surface nearest the palm along the approach (the part
stands in front of it). A box face or a cylinder the palm meets first is never a mount. World frame, metres.

A cap the palm looks down on is the solid the palm meets first, as far as its sides keep one radius; all beyond it is
its mount: a bottle's neck and body (none of them a plane facing the hand; counted in the free body, a neck lets
fingers closing on it hold in the planner's check while on the bottle only the cap turns), or a knob's stem and the
plate it stands on.

The top face is the plane most of the points nearest the palm lie on (``_ransac_plane``); the side is walked down its
axis on the points as scanned (voxels average a step's two sides) in slabs while it keeps the rim's radius (``_round``).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation
from sklearn.linear_model import RANSACRegressor

from tasks.arrays import BoolArray, FloatArray, Points, Vector3
from tasks.fit.geometry import perpendicular_basis
from tasks.grasp.primitive_fit import PrimitiveShape

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
    found: list[tuple[float, BoolArray]] = []  # (median depth, the mount's points) of each plane that is one
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
        if _is_mount(points, on, normal, axis, depth):
            behind = (points - points[on].mean(axis=0)) @ normal / float(np.linalg.norm(normal)) > -PLANE_TOLERANCE_M
            found.append((float(np.median(depth[on])), on | behind))
        left = left[~on[left]]
    best = min(found, key=lambda f: f[0])[1] if found else np.zeros(len(points), dtype=bool)
    return best if not best.all() else np.zeros(len(points), dtype=bool)


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


TOP_M = 0.002
"""Scan points within this distance of the top face's plane are on it."""
TOP_BAND_M = 0.008
"""The top face is the plane that most scan points within 8 mm of the nearest along the approach lie on (a disk 40
mm across tilted 10° from square spans 7 mm; a cap's inner faces, which a sampled model has, lie deeper)."""
TOP_PLANE_TOLERANCE_M = 0.0005
"""Points within this distance of a plane lie on it (scikit-learn's ``RANSACRegressor``, seeded)."""
MIN_TOP_POINTS = 20
MAX_TOP_TILT_RAD = math.radians(30.0)
"""The top face has at least this many scan points, its normal within this angle of the approach."""
SLAB_M = 0.002
"""Depth of each slab walked down the cap's side."""
STEP_M = 0.0012
"""A slab point this far inside the rim's radius (a neck 2 mm narrower than the cap) or outside it ends the cap."""
BESIDE_M = 0.03
"""Points farther than this outside the rim's radius are beside the cap, not its side nor its shoulder."""
SECTORS = 8
EMPTY_SECTORS = 1
"""The side is round where in each of ``SECTORS`` a slab's outermost point is within ``STEP_M`` of the rim's radius
(a box's faces lie inside its corners' radius); one may hold none (40 points leave one empty in one slab of 20)."""
MIN_HEIGHT_M = 0.008
MAX_HEIGHT_M = 0.06
MAX_RADIUS_M = 0.05
"""A cap is 8-60 mm tall and at most 50 mm in radius (the open Barrett hand spans about 0.2 m)."""


def find_cap(scan: Points, palm_position: Vector3, approach: Vector3) -> PrimitiveShape | None:
    """The cylinder of the cap the palm at ``palm_position`` (3,) m looks down on along unit ``approach`` (3,), on
    the (n, 3) world points (m) of a ``scan`` (its local +z from the top face into the object); None when the nearest
    surface is not a disk within ``MAX_TOP_TILT_RAD`` of square to the approach on a side of one radius
    ``MIN_HEIGHT_M`` to ``MAX_HEIGHT_M`` tall, or when nothing lies beyond the cap (see the module docstring)."""
    raw = np.asarray(scan, dtype=np.float64)
    look = np.asarray(approach, dtype=np.float64) / float(np.linalg.norm(approach))
    depth = (raw - np.asarray(palm_position, dtype=np.float64)) @ look
    band = raw[depth <= float(depth.min()) + TOP_BAND_M]
    if len(band) < MIN_TOP_POINTS:
        return None
    plane = _ransac_plane(band, look)
    if plane is None:
        return None
    centre, axis = plane
    if float(axis @ look) < math.cos(MAX_TOP_TILT_RAD):
        return None
    top = np.abs((raw - centre) @ axis) <= TOP_M
    if int(top.sum()) < MIN_TOP_POINTS:
        return None
    across = in_plane(axis)
    flat = raw[top] @ across
    centre = centre + across @ ((flat.min(axis=0) + flat.max(axis=0)) / 2.0 - (centre @ across))  # the disk's
    rel = raw - centre  # centre: its points' centroid lies off it where the sampling is uneven
    along = rel @ axis
    radial = np.linalg.norm(rel - along[:, None] * axis, axis=1)
    if float(along.min()) < -TOP_M:
        return None  # the face is not the nearest surface along its own axis
    rim = float(radial[top].max())
    if rim > MAX_RADIUS_M:
        return None
    outermost = np.flatnonzero(top)[int(np.argmax(radial[top]))]
    u = rel[outermost] - float(along[outermost]) * axis
    u /= float(np.linalg.norm(u))
    azimuth = np.arctan2(rel @ np.cross(axis, u), rel @ u)
    sector = np.floor((azimuth + math.pi) / (2.0 * math.pi) * SECTORS).astype(np.int64) % SECTORS
    height = 0.0
    side: list[FloatArray] = []  # each round slab's distances from the axis of its points on the side
    for start in np.arange(TOP_M, MAX_HEIGHT_M + SLAB_M, SLAB_M):
        slab = (along > start) & (along <= start + SLAB_M) & (radial <= rim + BESIDE_M)
        if not _round(radial[slab], sector[slab], rim):
            break
        height = float(start + SLAB_M)
        side.append(radial[slab][np.abs(radial[slab] - rim) <= STEP_M])  # a round slab has some (``_round``)
    if not MIN_HEIGHT_M <= height < MAX_HEIGHT_M:
        return None  # too short, or a side that goes on: a can, a box's corner, not a cap
    if not np.any(along > height + SLAB_M):
        return None  # nothing beyond the cap: the object is the cap alone
    middle = centre + axis * height / 2.0
    quat = Rotation.align_vectors(axis[None, :], np.array([[0.0, 0.0, 1.0]]))[0].as_quat()
    radius = float(np.median(np.concatenate(side)))  # unbiased by noise, where the top's outermost point is not
    return PrimitiveShape(
        "cylinder", (radius, height / 2.0, 0.0), (middle[0], middle[1], middle[2]), (quat[0], quat[1], quat[2], quat[3])
    )


def _ransac_plane(points: Points, look: Vector3) -> tuple[Vector3, Vector3] | None:
    """Centroid (3,) and unit normal (3,) (the smallest principal direction, its sign along ``look``) of the plane
    most of ``points`` (n, 3) lie on (depth along ``look`` a linear function of the two coordinates across it, within
    ``TOP_PLANE_TOLERANCE_M``), fitted again to its inliers; None when fewer than ``MIN_TOP_POINTS`` lie on it."""
    ransac = ransac_plane(points @ in_plane(look), points @ look, TOP_PLANE_TOLERANCE_M, 100, 0)
    if ransac is None or int(np.sum(ransac.inlier_mask_)) < MIN_TOP_POINTS:
        return None
    on = points[np.asarray(ransac.inlier_mask_, dtype=bool)]
    centre = on.mean(axis=0)
    _, vectors = np.linalg.eigh((on - centre).T @ (on - centre))
    return centre, vectors[:, 0] if float(vectors[:, 0] @ look) >= 0.0 else -vectors[:, 0]


def _round(radial: FloatArray, sector: npt.NDArray[np.int64], rim: float) -> bool:
    """Whether a slab's points (distances ``radial`` (k,) m from the axis, ``sector`` (k,) indices) reach the rim's
    radius ``rim`` (m) within ``STEP_M`` in every sector that holds one (``EMPTY_SECTORS`` may hold none)."""
    outermost = np.full(SECTORS, np.nan)
    np.fmax.at(outermost, sector, radial)
    seen = np.isfinite(outermost)
    return int((~seen).sum()) <= EMPTY_SECTORS and bool(np.all(np.abs(outermost[seen] - rim) <= STEP_M))
