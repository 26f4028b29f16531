"""A measuring case: marker tracks, rigid-body poses and wrist of one demonstration, with its true chain.

Times are seconds from the start of the recording (``t = 0`` is the first written sample), positions metres in
one world frame, quaternions ``[x, y, z, w]``. ``write_case`` turns a case into a recording with the real
``RecordingWriter``; ``resample`` gives the same motion at another rate. Cases and truths hold arrays, so they
compare by identity.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from bench.learn_corpus.rotations import Array, BoolArray, IntArray, slerp
from tasks.recording.writer import Format, RecordingWriter

START_NS = 1_700_000_000_000_000_000
"""Stamp of ``t = 0`` in written recordings (ns since the Unix epoch, November 2023)."""

GAP_FACTOR = 5.0
"""An interval between valid samples longer than this many median intervals is a gap (the tracker lost the marker),
not something to interpolate across."""

Track = tuple[Array, Array]
PoseTrack = tuple[Array, Array, Array]


@dataclass(frozen=True, eq=False)
class TruthPrimitive:
    """One demonstrated primitive.

    ``pos``: a point on the axis (m, world), the foot of the moving marker's position at the primitive's midpoint
    (None for translations); ``dir``: unit, signed so the motion is positive (right-hand rule for rotations);
    ``extent``: travelled (rad or m, >= 0); ``t_start``/``t_end``: s; ``radius_m``: the moving marker's distance
    from the axis (rotations); ``radius_marker``: the name of that marker, when known.
    """

    kind: str
    pos: Array | None
    dir: Array
    extent: float
    t_start: float
    t_end: float
    radius_m: float | None = None
    radius_marker: str | None = None


@dataclass(frozen=True, eq=False)
class Case:
    """One demonstration and its truth.

    ``markers``: name -> (t_s (n,), xyz (n, 3) m; NaN rows are occlusions); ``poses``: rigid body -> (t_s, xyz,
    quat xyzw); ``wrist``: (t_s, xyz, quat) or None; ``noise_m``: largest per-axis sigma of the position noise;
    ``hz``: nominal rate; ``check_axis``: whether the truth axis is known precisely enough to score;
    ``radius_tol_m``: tolerance on the radius, when the radius is part of "right"; ``roles``: what each marker or
    rigid body is ("object", "static", "hand", "body"), for diagnostics only (never written to the recording).
    """

    name: str
    markers: dict[str, Track]
    poses: dict[str, PoseTrack]
    wrist: PoseTrack | None
    truth: tuple[TruthPrimitive, ...]
    noise_m: float
    hz: float
    tags: tuple[str, ...] = ()
    check_axis: bool = True
    radius_tol_m: float | None = None
    roles: dict[str, str] = field(default_factory=dict)

    @property
    def kinds(self) -> tuple[str, ...]:
        """The truth's primitive kinds in order."""
        return tuple(p.kind for p in self.truth)


def _stamps_ns(t: Array) -> IntArray:
    return START_NS + np.round(np.asarray(t, dtype=np.float64) * 1e9).astype(np.int64)


def write_case(case: Case, path: Path, fmt: Format = "mcap") -> None:
    """Write ``case`` as a recording at ``path``: one ``PointStamped`` topic per marker (named by the marker),
    one ``PoseStamped`` topic per rigid body, the wrist as ``PoseStamped`` on ``/wrist``; NaN rows are skipped."""
    with RecordingWriter(path, fmt) as writer:
        for name, (t, xyz) in case.markers.items():
            writer.add_points(name, _stamps_ns(t), xyz)
        for name, (t, xyz, quat) in case.poses.items():
            writer.add_poses(name, _stamps_ns(t), xyz, quat)
        if case.wrist is not None:
            t, xyz, quat = case.wrist
            writer.add_poses("/wrist", _stamps_ns(t), xyz, quat)


def _valid_brackets(t: Array, valid: BoolArray, t_new: Array) -> tuple[IntArray, IntArray, BoolArray]:
    """For each new time: the indices of the valid samples before and after it and whether it may be interpolated
    (both exist, no invalid sample between them, and they are not further apart than a gap)."""
    idx: IntArray = np.flatnonzero(valid).astype(np.int64)
    tv = t[idx]
    hi = np.searchsorted(tv, t_new, side="left")
    exact = (hi < len(tv)) & (tv[np.minimum(hi, len(tv) - 1)] == t_new)
    lo = np.where(exact, hi, hi - 1)
    ok: BoolArray = (lo >= 0) & (hi < len(tv))
    lo_c = np.clip(lo, 0, len(tv) - 1)
    hi_c = np.clip(hi, 0, len(tv) - 1)
    i_lo, i_hi = idx[lo_c], idx[hi_c]
    contiguous = (i_hi - i_lo) <= 1
    step = np.diff(tv)
    limit = GAP_FACTOR * float(np.median(step)) if len(step) else np.inf
    ok &= contiguous & ((tv[hi_c] - tv[lo_c]) <= limit)
    return i_lo, i_hi, ok


def _new_times(t: Array, hz: float) -> Array:
    n = int(np.floor((t[-1] - t[0]) * hz + 1e-9)) + 1
    out: Array = t[0] + np.arange(n) / hz
    return out


def _resample_points(t: Array, xyz: Array, hz: float) -> Track:
    valid: BoolArray = np.asarray(np.isfinite(xyz).all(axis=1))
    t_new = _new_times(t, hz)
    if valid.sum() < 2:
        return t_new, np.full((len(t_new), 3), np.nan)
    i_lo, i_hi, ok = _valid_brackets(t, valid, t_new)
    span = t[i_hi] - t[i_lo]
    f = np.where(span > 0, (t_new - t[i_lo]) / np.where(span > 0, span, 1.0), 0.0)
    out = xyz[i_lo] + f[:, None] * (xyz[i_hi] - xyz[i_lo])
    out[~ok] = np.nan
    return t_new, out


def _resample_pose(track: PoseTrack, hz: float) -> PoseTrack:
    t, xyz, quat = track
    valid: BoolArray = np.asarray(np.isfinite(xyz).all(axis=1) & np.isfinite(quat).all(axis=1))
    t_new, pos = _resample_points(t, np.where(valid[:, None], xyz, np.nan), hz)
    if valid.sum() < 2:
        return t_new, pos, np.full((len(t_new), 4), np.nan)
    i_lo, i_hi, ok = _valid_brackets(t, valid, t_new)
    span = t[i_hi] - t[i_lo]
    f = np.where(span > 0, (t_new - t[i_lo]) / np.where(span > 0, span, 1.0), 0.0)
    q = slerp(quat[i_lo], quat[i_hi], f)
    q[~ok] = np.nan
    pos[~ok] = np.nan
    return t_new, pos, q


def resample(case: Case, hz: float) -> Case:
    """The same motion at ``hz``: each stream on a uniform grid from its first to its last stamp, positions
    interpolated linearly and quaternions by slerp between the original samples; gaps (NaN rows, or intervals
    longer than ``GAP_FACTOR`` median intervals) stay gaps. Truth, noise and tags are kept."""
    markers = {name: _resample_points(t, xyz, hz) for name, (t, xyz) in case.markers.items()}
    poses = {name: _resample_pose(track, hz) for name, track in case.poses.items()}
    wrist = _resample_pose(case.wrist, hz) if case.wrist is not None else None
    return replace(case, name=f"{case.name}@{hz:g}Hz", markers=markers, poses=poses, wrist=wrist, hz=float(hz))
