"""A box or a cylinder fitted to an object's point cloud (metres, world frame), for planning on the primitive.

When a scanned part is in fact a box or a cylinder (a carton, a bottle, a can) the planner may plan on the fitted
primitive instead of the k-means convex pieces, as GraspIt does with shape primitives (Miller, Knoop, Christensen &
Allen, "Automatic grasp planning using shape primitives", ICRA 2003). Box: a frame from the normals voted into two
perpendicular face directions, extents from point quantiles. Cylinder: the axis is the direction the side normals are
perpendicular to (smallest eigenvector of their scatter, from each eigenvector of the normals' scatter and of the
points' covariance), an algebraic circle fit of the side points, the half height from the points' extent along the axis.
Both are refined by ``scipy.optimize.least_squares`` (soft-L1 loss) over pose and size, minimising the distance of the
points to the closed surface, and kept only when that surface explains the points (``TOLERANCE_M``) and the points cover
the shape (``FACE_COVERAGE``, ``MIN_SIDE_ARC``).

A fit describes the seen part: a face or cap the points do not reach is placed where the seen faces end.

The votes use ``einsum`` and the steps ``lsmr``: OpenBLAS threads spin on a loaded machine.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from tasks.arrays import BoolArray, FloatArray, Points, Vector3
from tasks.fit.geometry import perpendicular_basis

Kind = Literal["box", "cylinder"]
"""The primitives fitted."""

MIN_POINTS = 30
"""Fewest object points a grasp is planned on."""
TOLERANCE_M = 0.0015
"""Default largest 95th percentile of the point-to-surface distance, metres: exact samples with 0.3 mm noise, 4 mm
voxels and ``estimate_normals`` normals give 0.4-0.65 mm; a sphere or a handle on its posts 4 mm and more."""
RMS_FRACTION = 0.55
"""Largest RMS distance as a fraction of the tolerance (0.8 mm at the default; clean fits give 0.2-0.4 mm): a few
per cent of the points far off the surface (a knob, a post) raise the RMS where the 95th percentile misses them."""
RELATIVE_TOLERANCE = 0.01
"""The tolerance grows to this fraction of the object's radius (the points' largest distance from their centroid;
a scan's error grows with the object: 1.5 mm from 150 mm on)."""
SMALL_OBJECT_TOLERANCE = 0.1
SMALL_OBJECT_FLOOR = 0.6
"""The tolerance shrinks to a tenth of the object's radius, but not below 0.6 of the given one (0.9 mm): a sphere's
best cylinder or box misses it by a 95th percentile of 0.145 radii, a true primitive's fit by at most 0.05 radii."""
LOSS_SCALE_M = 0.001
"""Soft-L1 scale of the refinement, metres: points farther off than this weigh less (noise is about 0.3 mm)."""
REFINE_POINTS = 800
"""At most this many points (an even stride) drive the refinement; all are measured afterwards."""
MAX_EVALUATIONS = 50
"""Cap on the refinement's evaluations: a true primitive converges within about 15 from the normals' start, while
a shape no primitive explains (a handle on its posts) wanders for hundreds and is refused anyway."""
VOTE_NORMALS = 400
"""At most this many normals (an even stride) vote for a box's face directions."""
VOTE_COS = math.cos(math.radians(15.0))
"""Normals within 15° of each other (either sign) vote for the same face direction."""
SIDE_COS = 0.5
"""A cylinder side point's normal is more than 60° from the axis (|cos| < 0.5; the rims' normals are blended)."""
FACE_GRID = 4
"""Each box face is split into 4 x 4 cells to measure how much of it the points cover."""
FACE_COVERAGE = 0.5
"""A box face is seen when points lie in at least half of its cells. A box fit needs a seen face along each of its
three axes (three mutually adjacent faces, what one view of a box shows): with two, the third extent is bounded
only by where the seen faces end, and with one the box is a flat patch of any thickness."""
ARC_BINS = 36
MIN_SIDE_ARC = 12
SIDE_BANDS = 4
"""A cylinder fit needs side points over an arc of at least 12 of 36 10° bins (120°, 360° less the longest run of
empty bins; one view shows 180°), which fixes the radius, and in each of 4 bands along its height."""


@dataclass(frozen=True)
class PrimitiveShape:
    """A known shape in the world: ``kind`` box (``size`` = half extents, m) or cylinder (radius, half height,
    axis = local z); ``position`` (3,) m and ``quat_xyzw`` (4,) of its centre frame."""

    kind: Kind
    size: tuple[float, float, float]
    position: tuple[float, float, float]
    quat_xyzw: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class PrimitiveFit:
    """A fitted primitive: ``shape`` (world, m), ``rms_m`` and ``p95_m`` the RMS and 95th percentile of the points'
    distances to its surface (m)."""

    shape: PrimitiveShape
    rms_m: float
    p95_m: float


def surface_distance(shape: PrimitiveShape, points: Points) -> FloatArray:
    """(n,) unsigned distance (m) of (n, 3) world ``points`` to the surface of ``shape`` (not to the solid)."""
    return np.abs(_signed_distance(shape.kind, _local(shape, points), np.asarray(shape.size, dtype=np.float64)))


def fit_primitive(points: Points, normals: Points, *, tolerance_m: float = TOLERANCE_M) -> PrimitiveFit | None:
    """The box or cylinder whose surface explains (n, 3) world ``points`` (m) with outward unit ``normals`` (n, 3;
    signs may flip): 95th percentile distance within ``tolerance_m`` (as ``tolerance`` scales it with the object),
    RMS within ``RMS_FRACTION`` of it, and the points covering the shape; the one of lower RMS when both do. None
    when neither does, or for fewer than ``MIN_POINTS`` points."""
    if len(points) < MIN_POINTS:
        return None
    tol = tolerance(tolerance_m, float(np.linalg.norm(points - points.mean(axis=0), axis=1).max()))
    fits = [fit for fit in (fit_box(points, normals), fit_cylinder(points, normals)) if fit is not None]
    kept = [f for f in fits if f.p95_m <= tol and f.rms_m <= RMS_FRACTION * tol and supported(f.shape, points, tol)]
    return min(kept, key=lambda f: f.rms_m, default=None)


def tolerance(tolerance_m: float, radius_m: float) -> float:
    """The largest 95th percentile distance (m) accepted for an object of ``radius_m`` (its points' largest distance
    from their centroid): ``tolerance_m``, down to ``SMALL_OBJECT_TOLERANCE`` radii for small objects (not below
    ``SMALL_OBJECT_FLOOR`` of it), up to ``RELATIVE_TOLERANCE`` radii for large ones."""
    small = min(tolerance_m, max(SMALL_OBJECT_TOLERANCE * radius_m, SMALL_OBJECT_FLOOR * tolerance_m))
    return max(small, RELATIVE_TOLERANCE * radius_m)


def fit_box(points: Points, normals: Points) -> PrimitiveFit | None:
    """The best box through (n, 3) world ``points`` (m) with unit ``normals`` (n, 3), however poor (None when the
    normals show no two perpendicular directions); checked by ``fit_primitive``."""
    frame = _normal_frame(normals)
    if frame is None:
        return None
    lo, hi = np.quantile(points @ frame, [0.005, 0.995], axis=0)
    return _refined("box", points, frame, frame @ ((lo + hi) / 2), (hi - lo) / 2)


def fit_cylinder(points: Points, normals: Points) -> PrimitiveFit | None:
    """The best cylinder through (n, 3) world ``points`` (m) with unit ``normals`` (n, 3), however poor (None when
    no axis leaves enough side points for a circle); checked by ``fit_primitive``."""
    axes = _axis_candidates(points, normals)
    starts = [s for s in (_cylinder_start(points, normals, axis) for axis in axes) if s is not None]
    if not starts:
        return None
    frame, centre, size = min(starts, key=lambda s: _robust_spread(points, s))
    return _refined("cylinder", points, frame, centre, size)


def _refined(kind: Kind, points: Points, frame: FloatArray, centre: Vector3, size: Vector3) -> PrimitiveFit:
    """The shape refined from a start (``frame`` (3, 3) columns = local axes, ``centre`` (3,) m, ``size`` (3,) m)
    by least squares (soft-L1, a finite-difference Jacobian) of the signed distances of at most ``REFINE_POINTS`` of
    ``points`` to its surface, then the distances of all ``points`` to it. Parameters: a rotation vector after
    ``frame`` (about local x, y only for a cylinder), the centre's offset (m), the sizes (m)."""
    sub = points[:: max(1, len(points) // REFINE_POINTS)]
    n_rot, n_size = (3, 3) if kind == "box" else (2, 2)

    def unpack(x: FloatArray) -> tuple[FloatArray, Vector3, Vector3]:
        rotvec = np.zeros(3)
        rotvec[:n_rot] = x[:n_rot]
        out_size = np.zeros(3)
        out_size[:n_size] = np.abs(x[n_rot + 3 :])
        return frame @ Rotation.from_rotvec(rotvec).as_matrix(), centre + x[n_rot : n_rot + 3], out_size

    def residuals(x: FloatArray) -> FloatArray:
        rot, c, s = unpack(x)
        return _signed_distance(kind, (sub - c) @ rot, s)

    x0 = np.concatenate([np.zeros(n_rot + 3), size[:n_size]])
    result = least_squares(
        residuals,
        x0,
        loss="soft_l1",
        f_scale=LOSS_SCALE_M,
        x_scale="jac",
        tr_solver="lsmr",
        max_nfev=MAX_EVALUATIONS,
    )
    rot, c, s = unpack(np.asarray(result.x, dtype=np.float64))
    quat = Rotation.from_matrix(rot).as_quat()
    shape = PrimitiveShape(
        kind,
        (float(s[0]), float(s[1]), float(s[2])),
        (float(c[0]), float(c[1]), float(c[2])),
        (float(quat[0]), float(quat[1]), float(quat[2]), float(quat[3])),
    )
    dist = surface_distance(shape, points)
    return PrimitiveFit(shape, float(np.sqrt(np.mean(dist**2))), float(np.quantile(dist, 0.95)))


def _local(shape: PrimitiveShape, points: Points) -> Points:
    """(n, 3) ``points`` in the shape's centre frame (m)."""
    rot = Rotation.from_quat(shape.quat_xyzw).as_matrix()
    out: Points = (np.asarray(points, dtype=np.float64) - np.asarray(shape.position)) @ rot
    return out


def _signed_distance(kind: Kind, local: Points, size: Vector3) -> FloatArray:
    """(n,) signed distance (m, negative inside) of centre-frame points to a box (half extents ``size``) or a
    closed cylinder (``size`` = radius, half height, 0; axis z)."""
    excess = _excess(kind, local, size)
    over = np.maximum(excess, 0.0)
    out: FloatArray = np.sqrt(np.einsum("ij,ij->i", over, over)) + np.minimum(excess.max(axis=1), 0.0)
    return out


def _excess(kind: Kind, local: Points, size: Vector3) -> Points:
    """How far (m) centre-frame points lie outside each pair of a box's faces (n, 3), or outside a cylinder's side
    and its pair of end faces (n, 2); negative inside."""
    if kind == "box":
        out: Points = np.abs(local) - size
        return out
    return np.stack([np.hypot(local[:, 0], local[:, 1]) - size[0], np.abs(local[:, 2]) - size[1]], axis=1)


def within(shape: PrimitiveShape, points: Points, margin_m: float) -> BoolArray:
    """(n,) whether each of (n, 3) world ``points`` lies inside ``shape`` grown by ``margin_m`` (m) from each face."""
    size = np.asarray(shape.size, dtype=np.float64)
    inside: BoolArray = np.all(_excess(shape.kind, _local(shape, points), size) <= margin_m, axis=1)
    return inside


def _normal_frame(normals: Points) -> FloatArray | None:
    """(3, 3) rotation whose columns are the two face directions most normals agree with (either sign, the second
    within 15° of perpendicular to the first) and their cross product; None when no second direction."""
    votes = normals[:: max(1, len(normals) // VOTE_NORMALS)]
    first = _voted_direction(votes)
    perpendicular = votes[np.abs(votes @ first) < math.sin(math.radians(15.0))]
    if len(perpendicular) < 3:
        return None
    second = _voted_direction(perpendicular)
    second -= (second @ first) * first
    second /= np.linalg.norm(second)
    return np.stack([first, second, np.cross(first, second)], axis=1)


def _voted_direction(normals: Points) -> Vector3:
    """The unit direction (sign free) most of ``normals`` lie within 15° of: the mean of the best one's voters."""
    agree = np.einsum("ik,jk->ij", normals, normals)  # not BLAS: its threads spin on a shared machine
    votes = (np.abs(agree) > VOTE_COS).sum(axis=1)
    best = int(np.argmax(votes))
    voters = np.abs(agree[best]) > VOTE_COS
    mean = (normals[voters] * np.sign(agree[best, voters])[:, None]).sum(axis=0)
    out: Vector3 = mean / np.linalg.norm(mean)
    return out


def _axis_candidates(points: Points, normals: Points) -> list[Vector3]:
    """Unit cylinder axis candidates: each eigenvector of the normals' scatter and of the points' covariance,
    turned twice to the direction the side normals (``SIDE_COS``) are most perpendicular to."""
    _, normal_axes = np.linalg.eigh(normals.T @ normals)
    _, point_axes = np.linalg.eigh(np.cov(points.T))
    out = []
    for start in np.concatenate([normal_axes, point_axes], axis=1).T:
        axis = start
        for _ in range(2):
            side = normals[np.abs(normals @ axis) < SIDE_COS]
            if len(side) < MIN_POINTS:
                break
            axis = np.linalg.eigh(side.T @ side)[1][:, 0]
        out.append(np.asarray(axis, dtype=np.float64))
    return out


def _cylinder_start(points: Points, normals: Points, axis: Vector3) -> tuple[FloatArray, Vector3, Vector3] | None:
    """Frame (3, 3; z = ``axis``), centre (3,) m and (radius, half height, 0) m: a circle fitted to the side points
    (algebraic least squares, Kåsa) and the points' 0.5-99.5 % extent along the axis; None without side points."""
    frame = np.stack([*perpendicular_basis(axis), axis], axis=1)
    local = points @ frame
    side = local[np.abs(normals @ axis) < SIDE_COS]
    if len(side) < MIN_POINTS:
        return None
    design = np.column_stack([2 * side[:, 0], 2 * side[:, 1], np.ones(len(side))])
    (cx, cy, c), *_ = np.linalg.lstsq(design, side[:, 0] ** 2 + side[:, 1] ** 2, rcond=None)
    radius_sq = c + cx**2 + cy**2
    if radius_sq <= 0:
        return None
    lo, hi = np.quantile(local[:, 2], [0.005, 0.995])
    centre = frame @ np.array([cx, cy, (lo + hi) / 2])
    return frame, centre, np.array([math.sqrt(radius_sq), (hi - lo) / 2, 0.0])


def _robust_spread(points: Points, start: tuple[FloatArray, Vector3, Vector3]) -> float:
    """Mean distance (m, each capped at 5 mm) of ``points`` to a cylinder start (frame, centre, size)."""
    frame, centre, size = start
    dist = np.abs(_signed_distance("cylinder", (points - centre) @ frame, size))
    return float(np.minimum(dist, 0.005).mean())


def supported(shape: PrimitiveShape, points: Points, tol: float) -> bool:
    """Whether the points within ``tol`` (m) of ``shape``'s surface cover it: a box a seen face (``FACE_COVERAGE``)
    along each axis, a cylinder its side (``MIN_SIDE_ARC``, ``SIDE_BANDS``)."""
    size = np.asarray(shape.size, dtype=np.float64)
    local = _local(shape, points)
    local = local[np.abs(_signed_distance(shape.kind, local, size)) <= tol]
    if shape.kind == "box":
        face_axis = np.argmax(np.abs(local) - size, axis=1)
        for axis in range(3):
            others = [a for a in range(3) if a != axis]
            seen = False
            for sign in (-1.0, 1.0):
                on_face = local[(face_axis == axis) & (np.sign(local[:, axis]) == sign)][:, others]
                seen |= _covered(on_face, size[others], FACE_GRID, FACE_GRID) >= FACE_COVERAGE
            if not seen:
                return False
        return True
    side = local[np.hypot(local[:, 0], local[:, 1]) - size[0] >= np.abs(local[:, 2]) - size[1]]
    angle_bin = ((np.arctan2(side[:, 1], side[:, 0]) + math.pi) / (2 * math.pi) * ARC_BINS).astype(np.int64)
    occupied = np.zeros(ARC_BINS, dtype=bool)
    occupied[np.clip(angle_bin, 0, ARC_BINS - 1)] = True
    gap = run = 0
    for empty in np.concatenate([~occupied, ~occupied]):
        run = run + 1 if empty else 0
        gap = max(gap, run)
    band = np.clip(((side[:, 2] + size[1]) / max(2 * size[1], 1e-9) * SIDE_BANDS).astype(np.int64), 0, SIDE_BANDS - 1)
    return ARC_BINS - min(gap, ARC_BINS) >= MIN_SIDE_ARC and len(np.unique(band)) == SIDE_BANDS


def _covered(coords: FloatArray, half: FloatArray, rows: int, cols: int) -> float:
    """Fraction of the ``rows`` x ``cols`` cells of the rectangle [-half, half] (2,) that hold a point of (k, 2)
    ``coords``."""
    if len(coords) == 0:
        return 0.0
    scaled = (coords + half) / (2 * np.maximum(half, 1e-9))
    i = np.clip((scaled[:, 0] * rows).astype(np.int64), 0, rows - 1)
    j = np.clip((scaled[:, 1] * cols).astype(np.int64), 0, cols - 1)
    return len(np.unique(i * cols + j)) / (rows * cols)
