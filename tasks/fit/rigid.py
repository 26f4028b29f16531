"""Orientation of a rigid part from its markers (Kabsch / Umeyama, ``scipy``'s ``Rotation.align_vectors``).

Markers that move together are one rigid part. On a common time grid the part's orientation relative to its
first configuration is the rotation that best maps the centred first configuration onto the centred current
one. In a rotation it turns by the joint angle about the joint axis; in a translation it does not turn. The
excess residual of a model orientation over the best one (m^2, summed over markers) is the evidence the model
choice uses, and the screw axis of the motion (direction from the turn, point from the centroid's motion) is a
start for the geometric circle fit that a short, noisy arc alone cannot give.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Points, Vector3
from tasks.fit.geometry import perpendicular_basis, unit
from tasks.fit.interpolate import bracketed, positions_at
from tasks.fit.noise import noise_sigma

MIN_MARKERS = 3
"""Markers needed to fix an orientation."""
MIN_SPREAD_M = 0.005
"""Second singular value (rms, m) the centred marker configuration needs: collinear markers fix no turn about
their line."""
REFERENCE_SAMPLES = 5
"""Grid samples averaged into the reference configuration (the part barely moves at a motion's start)."""
MIN_TURN_RAD = 0.05
"""A net turn below this fixes no axis direction worth having (rad)."""
TURN_SIGMAS = 5.0
"""A net turn must exceed this many of its noise sigmas (about the worst-determined direction) to fix an axis."""


@dataclass(frozen=True)
class PartMotion:
    """A rigid part on a time grid: times (s), per-sample rotation vectors (rad, world frame) of the turn since
    the reference configuration, centroids (m), the reference configuration centred (m, (k, 3)), and per-sample
    squared residuals (m^2, summed over markers) of the best rotation, of no turn, and the markers at each time."""

    t_s: FloatArray
    rotvecs: FloatArray
    centroids: Points
    reference: Points
    rss_best: FloatArray
    rss_no_turn: FloatArray
    current: FloatArray


def kabsch(reference: Points, current: FloatArray) -> FloatArray:
    """(g, 3, 3) rotations that best map the centred (m, 3) ``reference`` onto each centred (g, m, 3) ``current``
    configuration (least squares, proper rotations; Kabsch 1976), batched over g."""
    cov = np.einsum("gmi,mj->gij", current, reference)
    u, _, vt = np.linalg.svd(cov)
    sign = np.sign(np.linalg.det(u @ vt))
    sign[sign == 0] = 1.0
    u[:, :, 2] *= sign[:, None]
    out: FloatArray = u @ vt
    return out


def part_motion(times: list[FloatArray], tracks: list[Points]) -> PartMotion | None:
    """Orientation over time of the rigid part carried by markers (times in s, (n_m, 3) points in m), or None
    with fewer than ``MIN_MARKERS`` markers seen together, or a configuration too nearly collinear."""
    if len(tracks) < MIN_MARKERS:
        return None
    longest = max(range(len(times)), key=lambda i: len(times[i]))
    grid = times[longest]
    ok = np.all([bracketed(t, grid) for t in times], axis=0)  # occlusions are not interpolated across
    if ok.sum() < REFERENCE_SAMPLES + 2:
        return None
    pts = np.stack([positions_at(t, p, grid[ok]) for t, p in zip(times, tracks, strict=True)], axis=1)  # (g, m, 3)
    centroids = pts.mean(axis=1)
    centred = pts - centroids[:, None, :]
    reference = centred[:REFERENCE_SAMPLES].mean(axis=0)
    reference -= reference.mean(axis=0)
    if float(np.linalg.svd(reference, compute_uv=False)[1]) / np.sqrt(len(reference)) < MIN_SPREAD_M:
        return None
    rots = kabsch(reference, centred)
    rotvecs = Rotation.from_matrix(rots).as_rotvec()
    rss_best = ((centred - np.einsum("gij,mj->gmi", rots, reference)) ** 2).sum(axis=(1, 2))
    rss_no_turn = ((centred - reference[None]) ** 2).sum(axis=(1, 2))
    return PartMotion(grid[ok], rotvecs, centroids, reference, rss_best, rss_no_turn, centred)


def rss_about_axis(motion: PartMotion, axis_dir: Vector3) -> FloatArray:
    """Per-sample squared residual (m^2) of the part turned only about ``axis_dir``, by the angle that fits best
    (the turn's component along the axis, then the best angle of that one-parameter family)."""
    d = unit(axis_dir)
    ref = motion.reference
    ref_perp = ref - np.outer(ref @ d, d)
    cur = motion.current
    cur_perp = cur - np.einsum("gm,i->gmi", cur @ d, d)
    cross = (np.cross(ref_perp[None], cur_perp) @ d).sum(axis=1)
    dot = (ref_perp[None] * cur_perp).sum(axis=(1, 2))
    angle = np.arctan2(cross, dot)
    rots = Rotation.from_rotvec(np.outer(angle, d)).as_matrix()
    out: FloatArray = ((cur - np.einsum("gij,mj->gmi", rots, ref)) ** 2).sum(axis=(1, 2))
    return out


def net_turn(motion: PartMotion) -> FloatArray:
    """Rotation vector (rad, world) of the part from its reference to its last configuration (the median over
    the last ``REFERENCE_SAMPLES`` samples' rotations)."""
    tail = Rotation.from_rotvec(motion.rotvecs[-REFERENCE_SAMPLES:])
    out: FloatArray = tail.mean().as_rotvec()
    return out


@dataclass(frozen=True)
class ScrewAxis:
    """Axis of a part's turn: unit direction (right-hand rule), point nearest the start centroid (m), net turn
    (rad) and the direction's standard deviation (rad) at noise ``sigma_m``."""

    dir: Vector3
    pos: Vector3
    turn_rad: float
    dir_std_rad: float


def screw_axis(motion: PartMotion) -> ScrewAxis | None:
    """The screw axis of the part's motion (orientations for the direction, the centroids' motion for the
    point), or None when its net turn is under ``MIN_TURN_RAD`` or ``TURN_SIGMAS`` noise sigmas. The direction's
    std comes from the Kabsch residual's noise, each sample's turn information across the axis, and the error of
    the reference configuration every turn is measured from."""
    turns = np.linalg.norm(motion.rotvecs, axis=1)
    moving = turns > 0.5 * float(turns.max())
    dof = max(3 * len(motion.reference) - 6, 1)
    sigma2 = float(np.mean(motion.rss_best)) / dof
    ref = motion.reference
    info_ref = (ref**2).sum() * np.eye(3) - ref.T @ ref  # Kabsch turn information, m^2 per sigma^2
    noise_rad = float(np.sqrt(sigma2 / max(float(np.linalg.eigvalsh(info_ref)[0]), 1e-12)))
    # a rigid body's pose stream turns all its points together: its orientation noise leaves no Kabsch residual,
    # so the turn's own scatter from sample to sample bounds the noise from below
    seen_rad = noise_sigma(motion.rotvecs, motion.t_s)
    threshold = max(MIN_TURN_RAD, TURN_SIGMAS * max(noise_rad, seen_rad) / np.sqrt(REFERENCE_SAMPLES))
    if float(np.linalg.norm(net_turn(motion))) < threshold or moving.sum() < 2:
        return None
    scatter = motion.rotvecs[moving].T @ motion.rotvecs[moving]
    d = unit(np.linalg.eigh(scatter)[1][:, 2])
    if float(np.dot(net_turn(motion), d)) < 0:
        d = -d
    # centroid c_t = R_t (c_0 - o) + o + slide d: (I - R_t) o = c_t - R_t c_0 - slide d, solved across the axis
    rows = []
    rhs = []
    c0 = motion.centroids[:REFERENCE_SAMPLES].mean(axis=0)
    e1, e2 = perpendicular_basis(d)
    plane = np.column_stack([e1, e2])
    tilt_cov = np.zeros((2, 2))
    turn_sq = 0.0
    turn_sum = 0.0
    for g in np.flatnonzero(moving):
        rot = Rotation.from_rotvec(motion.rotvecs[g]).as_matrix()
        b = motion.centroids[g] - rot @ c0
        rows.append(np.eye(3) - rot)
        rhs.append(b - float(np.dot(b, d)) * d)
        cur = motion.current[g]
        info = (cur**2).sum() * np.eye(3) - cur.T @ cur  # Kabsch turn information, m^2 per sigma^2
        theta = float(np.dot(motion.rotvecs[g], d))
        tilt_cov += theta**2 * np.linalg.pinv(plane.T @ info @ plane)
        turn_sq += theta**2
        turn_sum += abs(theta)
    a = np.concatenate([*rows, d[None, :]])
    sol, *_ = np.linalg.lstsq(a, np.concatenate([*rhs, [float(np.dot(c0, d))]]), rcond=None)
    # the reference configuration's own error turns every sample's rotation alike: a bias b across the axis tilts
    # the direction by b * sum|theta| / sum theta^2, however many samples follow
    ref_cov = np.linalg.pinv(plane.T @ info_ref @ plane) / REFERENCE_SAMPLES
    turn_sq = max(turn_sq, 1e-12)
    bias_gain = (turn_sum / turn_sq) ** 2
    dir_var = sigma2 * (np.trace(tilt_cov) / turn_sq**2 + bias_gain * float(np.trace(ref_cov)))
    seen_var = 2.0 * seen_rad**2 * (1.0 / turn_sq + bias_gain / REFERENCE_SAMPLES)
    dir_std = float(np.sqrt(max(dir_var, seen_var)))
    return ScrewAxis(d, sol, float(np.dot(net_turn(motion), d)), dir_std)
