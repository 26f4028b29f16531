"""The axis of a rotationally symmetric part (a cap, a knob), fitted to the points about it.

A cap is turned about its own symmetry axis. When two instances differ in proportions (a fatter bottle, a wider
cap), no similarity maps one onto the other, and a robust ICP settles the thinner shape against one side of the
fatter one: the carried axis ends up beside the true one by about the difference of the radii (10 mm on recorded
bottles). So for a rotation whose source region is itself symmetric about its axis, the carried axis is moved
to the target region's own symmetry axis: points are binned in slices along the (carried) direction and one
centre shared by all slices is fitted with a radius per slice (geometric circle fit, soft-L1 loss).

Only the body's sides enter the fit: points whose surface normal is within ``SIDE_DEG`` of square to the axis. A
face across the axis (a cap's top, a shoulder) puts points at every radius of its slice, and a scan that sees
one side of it pulls the slice's circle towards that side (1.4-1.9 mm at a cap's top with its top face in).
The centre's covariance comes from the fit's Jacobian and its residuals, so the placement carries its own sigma.

``fit_symmetry_line`` fits the direction too: the slices' centre moves linearly along the axis (a tilt), over
every side point within the radius of the line at any height. Over a whole bottle (its body, neck and cap) the
tilt is measured along the body's length, where the stretched fit of a bottle of other proportions leaves the
direction off by the shape it cannot follow.

Lengths in metres; ``pos`` and ``direction`` in the frame of the points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from tasks.arrays import FloatArray, Points, Vector3
from tasks.fit.geometry import perpendicular_basis
from tasks.transfer.local_refine import axis_region
from tasks.transfer.stretch import across_std, worst_std

MIN_POINTS = 60
"""A symmetry fit needs at least this many points in the region."""
SLICES = 12
"""Slices along the axis of a region as long as it is wide (each gets its own radius): a slice is a sixth of the
region radius tall, over which a body's radius changes little."""
MIN_SLICE_POINTS = 6
"""Slices with fewer points are left out of the fit."""
SIDE_DEG = 30.0
"""A point is on the body's side when its normal is within 30 degrees of square to the axis (a cylinder, a
gentle taper); a top, a bottom or a steep shoulder is not on any slice's circle."""


@dataclass(frozen=True)
class SymmetryFit:
    """A symmetry axis fitted near a given one: its point, and how well the region is a body of revolution."""

    pos: Vector3
    """The fitted axis point (the given ``pos`` moved across the axis), metres."""
    offset_m: float
    """Distance from the given axis to the fitted one, metres."""
    rms_m: float
    """Robust RMS of the radial residuals (points within 3 loss scales), metres."""
    inliers: float
    """Fraction of the fitted points within 3 loss scales of their slice's circle."""
    points: int
    pos_cov: FloatArray
    """(3, 3) covariance of ``pos`` across the axis (from the fit's Jacobian and its inliers' residuals), metres
    squared."""
    direction: Vector3
    """The fitted axis direction (unit): the given one unless the fit tilts it (``fit_symmetry_line``)."""
    dir_std_rad: float | None = None
    """One-sigma turn of ``direction`` (RMS over the two directions across it), radians; None: not fitted."""
    reach_m: float = 0.0
    """Farthest a fitted point lies along the axis from ``pos`` (where ``offset_m`` is measured), metres."""

    @property
    def pos_std_m(self) -> float:
        """RMS sigma of ``pos`` over the two directions across the axis, metres."""
        return across_std(self.pos_cov)

    @property
    def worst_pos_std_m(self) -> float:
        """Sigma of ``pos`` in its worst-placed direction across the axis, metres."""
        return worst_std(self.pos_cov)


def fit_symmetry_axis(
    points: Points, normals: Points, pos: Vector3, direction: Vector3, radius_m: float, *, loss_scale_m: float
) -> SymmetryFit | None:
    """The symmetry axis (parallel to unit ``direction``) of the side points (``normals``: their unit normals, any
    sign) within ``radius_m`` of ``pos`` and of the line through it; None when too few points. ``loss_scale_m``:
    the soft-L1 scale (about the surface noise)."""
    sel = axis_region(points, pos, direction, radius_m)
    slices = (-radius_m, radius_m / (SLICES / 2))
    return _fit(points[sel], normals[sel], (pos, direction), slices=slices, loss_scale_m=loss_scale_m, tilt=False)


def fit_symmetry_line(
    points: Points, normals: Points, pos: Vector3, direction: Vector3, radius_m: float, *, loss_scale_m: float
) -> SymmetryFit | None:
    """The symmetry axis (point and direction, near ``pos`` and unit ``direction``) of the side points within
    ``radius_m`` of the line at any height along it, sliced as ``fit_symmetry_axis`` slices a region of radius
    ``radius_m``; ``pos`` of the result is across the axis from the given one, ``offset_m`` the largest distance
    between the two lines over the fitted points' extent. None when too few points."""
    sel = axis_region(points, pos, direction, radius_m, half_length_m=math.inf)
    slices = (None, radius_m / (SLICES / 2))
    return _fit(points[sel], normals[sel], (pos, direction), slices=slices, loss_scale_m=loss_scale_m, tilt=True)


def _fit(
    points: Points,
    normals: Points,
    line: tuple[Vector3, Vector3],
    *,
    slices: tuple[float | None, float],
    loss_scale_m: float,
    tilt: bool,
) -> SymmetryFit | None:
    """One centre (moving linearly along the axis when ``tilt``) and one radius per slice, fitted to the side
    points among ``points``. ``slices``: where along the axis from ``pos`` the first slice starts (None: at the
    lowest side point) and how tall each is, metres."""
    pos, direction = line
    side = np.abs(normals @ direction) <= math.sin(math.radians(SIDE_DEG))
    if int(side.sum()) < MIN_POINTS:
        return None
    rel = points[side] - pos
    u, v = perpendicular_basis(direction)
    x, y, h = rel @ u, rel @ v, rel @ direction
    origin = float(h.min()) if slices[0] is None else slices[0]
    slice_of = np.clip(np.floor((h - origin) / slices[1]).astype(np.intp), 0, None)
    counts = np.bincount(slice_of)
    keep = counts[slice_of] >= MIN_SLICE_POINTS
    x, y, h, slice_of = x[keep], y[keep], h[keep], slice_of[keep]
    if x.shape[0] < MIN_POINTS:
        return None
    used = np.unique(slice_of)
    index = np.searchsorted(used, slice_of)
    r0 = np.hypot(x, y)
    radii0 = np.array([np.median(r0[index == k]) for k in range(len(used))])
    axis_params = 4 if tilt else 2  # the centre (and its tilt) ahead of the radii

    def residuals(params: FloatArray) -> FloatArray:
        cx, cy = (params[0] + h * params[2], params[1] + h * params[3]) if tilt else (params[0], params[1])
        out: FloatArray = np.hypot(x - cx, y - cy) - params[axis_params + index]
        return out

    result = least_squares(
        residuals, np.concatenate([np.zeros(axis_params), radii0]), loss="soft_l1", f_scale=loss_scale_m, max_nfev=200
    )
    res = residuals(result.x)
    inlier = np.abs(res) <= 3.0 * loss_scale_m
    rms = float(np.sqrt(np.mean(res[inlier] ** 2))) if inlier.any() else float("inf")
    dof = max(int(inlier.sum()) - result.x.shape[0], 1)
    variance = float(np.sum(res[inlier] ** 2)) / dof if inlier.any() else float("inf")
    cov = np.linalg.pinv(result.jac.T @ result.jac)[:axis_params, :axis_params] * variance
    basis = np.column_stack([u, v])
    cx, cy = float(result.x[0]), float(result.x[1])
    centre = pos + cx * u + cy * v
    pos_cov = basis @ cov[:2, :2] @ basis.T
    if not tilt:
        return SymmetryFit(
            centre, float(np.hypot(cx, cy)), rms, float(inlier.mean()), int(x.shape[0]), pos_cov, direction
        )
    tx, ty = float(result.x[2]), float(result.x[3])
    fitted = direction + tx * u + ty * v
    fitted /= np.linalg.norm(fitted)
    offset = max(float(np.hypot(cx + tx * end, cy + ty * end)) for end in (float(h.min()), float(h.max())))
    dir_std = math.sqrt(max(float(cov[2, 2] + cov[3, 3]), 0.0) / 2.0)
    reach = max(abs(float(h.min())), abs(float(h.max())))
    return SymmetryFit(centre, offset, rms, float(inlier.mean()), int(x.shape[0]), pos_cov, fitted, dir_std, reach)
