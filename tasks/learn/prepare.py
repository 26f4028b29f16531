"""From an ingested recording to segmentation-ready marker tracks (boundary checks happen here)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Points, Quats, StampsNs
from tasks.errors import FitError
from tasks.recording.load import PoseTrack, RecordingData
from tasks.segment.tracks import Track, make_track

MIN_SAMPLES = 8
"""A marker with fewer finite samples than this cannot be fitted and is left out (with a warning)."""
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


def prepare(rec: RecordingData, sigma_floor_m: float, hand_pattern: str) -> PreparedRecording:
    """Drop NaN samples, order by time, name hand markers; raise ``FitError`` when no marker is usable."""
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
        keep = np.isfinite(pts).all(axis=1)
        if not keep.any():
            warnings.append(f"marker {name}: every sample is NaN; left out")
            continue
        stamps = stamps[keep]
        pts = np.asarray(pts[keep], dtype=np.float64)
        order = np.argsort(stamps, kind="stable")
        stamps = stamps[order]
        pts = pts[order]
        stale = np.concatenate([[False], (np.diff(pts, axis=0) == 0.0).all(axis=1)])
        if stale.any() and (~stale).sum() >= MIN_SAMPLES:
            warnings.append(f"marker {name}: {int(stale.sum())} repeated samples dropped (a stale value re-sent)")
            stamps = stamps[~stale]
            pts = pts[~stale]
        t_s: FloatArray = (stamps - rec.start_ns).astype(np.float64) / 1e9
        if len(pts) < MIN_SAMPLES:
            span = (float(t_s[0]), float(t_s[-1]))
            warnings.append(f"marker {name} t={span[0]:.3f}..{span[1]:.3f} s: only {len(pts)} samples; left out")
            continue
        if dropped := int((~keep).sum()):
            warnings.append(f"marker {name}: {dropped} NaN samples dropped")
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
