"""A primitive is one monotonic motion of its joint: a segment whose part goes out and comes back along the same
axis (a drawer opened and closed, a door swung to and fro) is cut at each reversal into primitives of opposite
sense, each with the extent it travelled (``../shared/DESCRIPTOR.md``: extents are never negative).

The part's coordinate along the segment's fitted primitive (angle about the axis, or distance along the
direction; ``tasks.learn.boundaries.part_coordinate``) is smoothed, and a reversal is a turning point after which
the coordinate retraces more than a real motion (``min_motion_m`` of path, and ``min_rotation_rad`` of a turn),
well above the smoothed coordinate's noise.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tasks.arrays import FloatArray
from tasks.learn.boundaries import smoothed_coordinate
from tasks.learn.chain import SegmentFit
from tasks.learn.params import LearnParams
from tasks.learn.prepare import PreparedRecording

REVERSAL_SIGMAS = 5.0
"""A retrace must exceed this many noise sigmas of the smoothed coordinate to be a reversal, not scatter."""


def turning_points(coord: FloatArray, threshold: float) -> list[int]:
    """Indices of the extremes of a sequence after which it retraces more than ``threshold`` (a zig-zag filter;
    NaNs are skipped). The sense is set once the sequence first leaves its start by more than ``threshold``."""
    idx = np.flatnonzero(np.isfinite(coord))
    out: list[int] = []
    if len(idx) < 3:
        return out
    start = int(idx[0])
    direction = 0
    ext = start
    for i in idx[1:]:
        v = float(coord[i])
        if direction == 0:
            if abs(v - coord[start]) > threshold:
                direction, ext = (1 if v > coord[start] else -1), int(i)
            continue
        if (v - coord[ext]) * direction > 0:
            ext = int(i)
        elif (coord[ext] - v) * direction > threshold:
            out.append(ext)
            direction, ext = -direction, int(i)
    return out


def _least_motion(f: SegmentFit, params: LearnParams) -> float:
    """Smallest retrace that is a motion of its own, in the primitive's coordinate: ``min_motion_m`` of path, and
    for a rotation at least ``min_rotation_rad`` (a hand re-gripping a swinging door lets it fall back a few
    degrees without closing it)."""
    if f.kind == "rotation" and f.rotation is not None:
        radius = max(max(f.rotation.radii, default=0.0), 1e-6)
        return max(params.min_motion_m / radius, params.min_rotation_rad)
    return params.min_motion_m


def _piece(f: SegmentFit, t0: float, t1: float, travel: float) -> SegmentFit:
    """The part of ``f`` over [t0, t1) that travels ``travel`` (signed, along f's positive sense)."""
    sign = 1.0 if travel >= 0 else -1.0
    rot = f.rotation
    tra = f.translation
    if f.kind == "rotation" and rot is not None:
        rot = replace(rot, dir=sign * rot.dir, angle_rad=abs(travel))
    elif tra is not None:
        tra = replace(tra, dir=sign * tra.dir, distance_m=abs(travel))
    return replace(f, t_start=t0, t_end=t1, rotation=rot, translation=tra, extent=abs(travel))


def split_reversals(prep: PreparedRecording, fits: list[SegmentFit], params: LearnParams) -> list[SegmentFit]:
    """Every rotation or translation cut at the reversals of its part's motion (see the module docstring). The
    coordinate is followed into the rests on either side, so a retrace counts all the way to where the part comes
    to rest, however the change points cut the end of its motion."""
    out: list[SegmentFit] = []
    for i, f in enumerate(fits):
        before = fits[i - 1] if i > 0 and fits[i - 1].kind == "still" else f
        after = fits[i + 1] if i + 1 < len(fits) and fits[i + 1].kind == "still" else f
        wide = replace(f, t_start=before.t_start, t_end=after.t_end)
        got = smoothed_coordinate(prep, wide, 3) if f.kind in ("rotation", "translation") else None
        if got is None:
            out.append(f)
            continue
        grid, level, noise = got
        threshold = max(_least_motion(f, params), REVERSAL_SIGMAS * noise)
        turns = [k for k in turning_points(level, threshold) if f.t_start < grid[k] < f.t_end]
        if not turns:
            out.append(f)
            continue
        finite = np.flatnonzero(np.isfinite(level))
        cuts = [int(finite[0]), *turns, int(finite[-1])]
        times = [f.t_start, *(float(grid[k]) for k in turns), f.t_end]
        for k in range(len(cuts) - 1):
            travel = float(level[cuts[k + 1]] - level[cuts[k]])
            out.append(_piece(f, times[k], times[k + 1], travel))
    return out
