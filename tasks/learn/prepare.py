"""From an ingested recording to segmentation-ready marker tracks (boundary checks happen here)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Points, Quats, StampsNs
from tasks.errors import FitError
from tasks.fit.noise import robust_variance
from tasks.fit.select import SIGMA_MIN_M
from tasks.recording.load import PoseTrack, RecordingData
from tasks.segment.tracks import Track, make_track

MIN_SAMPLES = 8
"""A marker with fewer finite samples than this cannot be fitted and is left out (with a warning)."""
MAX_COORDINATE_M = 1000.0
"""A marker coordinate beyond this (m) is a corrupt sample, not a motion: capture volumes are tens of metres across."""
HAND_DISTANCE_STD_M = 0.005
"""A marker whose distance to the wrist varies by less than this (std, m) rides on the hand."""


@dataclass(frozen=True)
class PreparedRecording:
    """Finite marker tracks sorted by name, which of them are on the hand, and what was dropped."""

    tracks: tuple[Track, ...]
    hand: frozenset[str]
    warnings: tuple[str, ...]
    orientations: dict[str, tuple[FloatArray, Quats]] = field(default_factory=dict)
    """Rigid-body markers with poses: times (s since start) and quaternions [x, y, z, w], finite rows only."""


ORIENTATION_LEVER_M = 0.1
"""Distance (m) from a rigid body's origin of the three points that carry its orientation: about the size of a
handle or a marker cluster, so an orientation error of 1 degree moves them by 1.7 mm."""
ORIENTATION_SEPARATOR = "#axis-"
"""Joins a rigid body's name and the body axis (x, y, z) of a point that carries its orientation."""


def is_orientation_marker(name: str) -> bool:
    """Whether ``name`` is a point made from a rigid body's orientation, not a recorded marker."""
    return ORIENTATION_SEPARATOR in name


def orientation_markers(name: str, pose: PoseTrack) -> dict[str, tuple[StampsNs, Points]]:
    """Three points fixed in a rigid body, ``ORIENTATION_LEVER_M`` along its x, y and z axes (m, world), so that
    its orientation enters segmentation and the rigid part's fits as marker positions; rows with an invalid
    quaternion are NaN. Empty when no quaternion is valid."""
    quats = np.asarray(pose.quats, dtype=np.float64)
    norms = np.linalg.norm(quats, axis=1)
    ok = np.isfinite(quats).all(axis=1) & np.isfinite(pose.positions).all(axis=1) & (norms > 0.5)
    if not ok.any():
        return {}
    rot = np.full((len(quats), 3, 3), np.nan)
    rot[ok] = Rotation.from_quat(quats[ok] / norms[ok, None]).as_matrix()
    out: dict[str, tuple[StampsNs, Points]] = {}
    for k, axis in enumerate("xyz"):
        pts: Points = pose.positions + ORIENTATION_LEVER_M * rot[:, :, k]
        out[f"{name}{ORIENTATION_SEPARATOR}{axis}"] = (pose.stamps_ns, pts)
    return out


def _interp_positions(stamps: StampsNs, positions: Points, at: StampsNs) -> Points:
    t = stamps.astype(np.float64)
    out: Points = np.column_stack([np.interp(at.astype(np.float64), t, positions[:, i]) for i in range(3)])
    return out


def _rides_on_wrist(t_ns: StampsNs, pts: Points, wrist: PoseTrack) -> bool:
    ok = np.isfinite(wrist.positions).all(axis=1)
    if ok.sum() < MIN_SAMPLES:
        return False
    w = _interp_positions(wrist.stamps_ns[ok], wrist.positions[ok], t_ns)
    dist = np.linalg.norm(pts - w, axis=1)
    moves = float(np.ptp(pts, axis=0).max()) > 0.02
    return moves and float(np.std(dist)) < HAND_DISTANCE_STD_M


def _usable_samples(pts: Points) -> tuple[npt.NDArray[np.bool_], str]:
    """Rows of ``pts`` (n, 3) that are finite and within ``MAX_COORDINATE_M``, and the dropped ones in words."""
    nan = np.isnan(pts).any(axis=1)
    inf = ~nan & np.isinf(pts).any(axis=1)
    with np.errstate(invalid="ignore"):
        far = ~nan & ~inf & (np.abs(pts) > MAX_COORDINATE_M).any(axis=1)
    parts = [
        f"{int(count)} {what}"
        for count, what in (
            (nan.sum(), "NaN samples"),
            (inf.sum(), "infinite samples"),
            (far.sum(), f"samples beyond {MAX_COORDINATE_M:g} m"),
        )
        if count
    ]
    keep: npt.NDArray[np.bool_] = np.logical_not(nan | inf | far)
    return keep, ", ".join(parts)


SPIKE_SIGMAS = 5.5
"""A sample this many noise sigmas (per axis) off the line between its two neighbours, further off than either
neighbour and with both bent the other way, is a tracking glitch (a marker swapped or mis-triangulated for one
frame): a real path cannot leave and come back in one sample. A 3-D normal offset is that large (chi-square, 3
degrees of freedom) less than once in a million samples."""


def isolated_jumps(t_s: FloatArray, pts: Points) -> npt.NDArray[np.bool_]:
    """(n,) True where a sample leaves its path for that sample alone (see ``SPIKE_SIGMAS``): its offset from the
    line between its neighbours (interpolated in time) exceeds ``SPIKE_SIGMAS`` robust per-axis sigmas of that
    offset and both neighbours' offsets, which point the other way. The first and the last sample have no
    neighbour to come back to: each is dropped when it misses the line through the two next to it by as much
    (the threshold scaled by that extrapolation's larger noise gain), since no sample can confirm it as motion."""
    out = np.zeros(len(pts), dtype=bool)
    if len(pts) < 5:
        return out
    dt = np.diff(t_s)
    if not (dt > 0).all():
        return out
    w = dt[:-1] / (dt[:-1] + dt[1:])
    offset = pts[1:-1] - ((1.0 - w)[:, None] * pts[:-2] + w[:, None] * pts[2:])
    scale = max(float(np.sqrt(np.mean(robust_variance(offset)))), SIGMA_MIN_M)
    size = np.linalg.norm(offset, axis=1)
    inner = slice(1, -1)
    spike = size[inner] > SPIKE_SIGMAS * scale
    spike &= (size[inner] > size[:-2]) & (size[inner] > size[2:])
    spike &= np.einsum("ij,ij->i", offset[inner], offset[:-2]) < 0
    spike &= np.einsum("ij,ij->i", offset[inner], offset[2:]) < 0
    out[2:-2] = spike
    gain_inner = float(np.mean(1.0 + w**2 + (1.0 - w) ** 2))
    for end, prev, before in ((len(pts) - 1, len(pts) - 2, len(pts) - 3), (0, 1, 2)):
        r = abs(t_s[end] - t_s[prev]) / abs(t_s[prev] - t_s[before])
        miss = pts[end] - (pts[prev] + r * (pts[prev] - pts[before]))
        gain_end = 1.0 + (1.0 + r) ** 2 + r**2
        out[end] = float(np.linalg.norm(miss)) > SPIKE_SIGMAS * scale * np.sqrt(gain_end / gain_inner)
    return out


def prepare(rec: RecordingData, sigma_floor_m: float, hand_pattern: str) -> PreparedRecording:
    """Drop NaN, infinite and absurd samples and order by time (each with a warning), name hand markers; raise
    ``FitError`` when no marker is usable."""
    raw: dict[str, tuple[StampsNs, Points]] = {n: (m.stamps_ns, m.points) for n, m in rec.markers.items()}
    for name, pose in rec.poses.items():
        if pose.role != "wrist":
            raw.setdefault(name, (pose.stamps_ns, pose.positions))
            raw.update(orientation_markers(name, pose))
    if not raw:
        msg = f"recording {rec.id} has no marker tracks (nothing to segment)"
        raise FitError(msg)
    warnings: list[str] = []
    tracks: list[Track] = []
    hand: set[str] = set()
    pattern = re.compile(hand_pattern, re.IGNORECASE)
    wrist = rec.wrist
    for name in sorted(raw):
        stamps, pts = raw[name]
        keep, dropped_words = _usable_samples(np.asarray(pts, dtype=np.float64))
        if not keep.any():
            warnings.append(f"marker {name}: every sample is NaN, infinite or beyond {MAX_COORDINATE_M:g} m; left out")
            continue
        stamps = stamps[keep]
        pts = np.asarray(pts[keep], dtype=np.float64)
        if backwards := int((np.diff(stamps) < 0).sum()):
            warnings.append(f"marker {name}: {backwards} time stamps go backwards; samples sorted by time")
        order = np.argsort(stamps, kind="stable")
        stamps = stamps[order]
        pts = pts[order]
        stale = np.concatenate([[False], (np.diff(pts, axis=0) == 0.0).all(axis=1)])
        if stale.any() and (~stale).sum() >= MIN_SAMPLES:
            warnings.append(f"marker {name}: {int(stale.sum())} repeated samples dropped (a stale value re-sent)")
            stamps = stamps[~stale]
            pts = pts[~stale]
        t_s: FloatArray = (stamps - rec.start_ns).astype(np.float64) / 1e9
        jumps = isolated_jumps(t_s, pts)
        if jumps.any() and (~jumps).sum() >= MIN_SAMPLES:
            warnings.append(f"marker {name}: {int(jumps.sum())} isolated jumps dropped (one-sample tracking glitches)")
            stamps, t_s, pts = stamps[~jumps], t_s[~jumps], pts[~jumps]
        if len(pts) < MIN_SAMPLES:
            span = (float(t_s[0]), float(t_s[-1]))
            warnings.append(f"marker {name} t={span[0]:.3f}..{span[1]:.3f} s: only {len(pts)} samples; left out")
            continue
        if dropped_words:
            warnings.append(f"marker {name}: {dropped_words} dropped")
        tracks.append(make_track(name, t_s, pts, sigma_floor_m))
        if pattern.search(name) or (wrist is not None and _rides_on_wrist(stamps, pts, wrist)):
            hand.add(name)
    if not tracks:
        msg = "no marker has enough finite samples to fit (" + "; ".join(warnings) + ")"
        raise FitError(msg)
    orientations: dict[str, tuple[FloatArray, Quats]] = {}
    for name, pose in rec.poses.items():
        ok = np.isfinite(pose.quats).all(axis=1) & (np.linalg.norm(pose.quats, axis=1) > 0.5)
        if pose.role != "wrist" and ok.sum() >= MIN_SAMPLES:
            order = np.argsort(pose.stamps_ns[ok], kind="stable")
            t_s = (pose.stamps_ns[ok][order] - rec.start_ns).astype(np.float64) / 1e9
            orientations[name] = (t_s, pose.quats[ok][order])
    return PreparedRecording(tuple(tracks), frozenset(hand), tuple(warnings), orientations)
