"""Scoring and ranking of refined alignments, and the judgement of a poor registration.

An alignment's ranking score combines the whole models' fit over the scanned surface, the functional part's fit
both ways where the scan saw it and the two-way match of the small balls around the grasped part (which tells a
box's handle side from its mirror image). Lengths in metres, target frame unless named otherwise.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from tasks.arrays import Points
from tasks.transfer.clouds import O3dCloud, bbox_diagonal, cloud_points, fitness, functional_mask, to_cloud
from tasks.transfer.registration_types import Alignment, RegistrationParams
from tasks.transfer.similarity import Similarity


def two_way_score(source: O3dCloud, target: O3dCloud, fitted: Similarity, threshold: float) -> float:
    """Geometric mean of the source->target and target->source fitnesses within ``threshold`` (target units)."""
    f_st, _ = fitness(source, target, fitted, threshold)
    f_ts, _ = fitness(target, source, fitted.inverse(), threshold / fitted.scale)
    return math.sqrt(f_st * f_ts)


SEEN_REACH = 3.0
"""Source points farther than this many correspondence thresholds from every scanned point lie on surface the
scan did not see (an object's unseen side is its thickness away); nearer ones the fit is judged on: a misfit moves
a surface by about a threshold, which the fit's own pairs reach."""


def _seen_fit(points: Points, scan_tree: cKDTree, threshold: float) -> float | None:
    """Of ``points`` within ``SEEN_REACH`` thresholds of a scanned point (``scan_tree``), the fraction within
    ``threshold`` of one (target metres); None without such points."""
    to_scan, _ = scan_tree.query(points, distance_upper_bound=SEEN_REACH * threshold)
    seen = np.isfinite(to_scan)
    return float(np.mean(to_scan[seen] <= threshold)) if seen.any() else None


def _covered(scan: Points, points: Points, threshold: float) -> float:
    """The fraction of ``scan`` with one of ``points`` within ``threshold`` (target metres)."""
    to_points, _ = cKDTree(points).query(scan, distance_upper_bound=threshold)
    return float(np.mean(np.isfinite(to_points)))


def seen_fitness(
    part: Points, outward: tuple[Points, Points], scan: Points, scan_tree: cKDTree, threshold: float
) -> float:
    """The fraction of the points ``part`` (target metres) a camera that took ``scan`` would have seen that lie
    on it (within ``threshold``). A point off the scan was seen only when it lies in front of the scanned surface
    nearest it, on its outer side (the outward normal of the model points ``outward`` nearest that scanned point,
    both placed as the part is): there it would have hidden the surface. Behind it, it lies inside the object; a
    part placed right but seen from one side leaves its other side there. 0 without seen points."""
    if len(part) == 0:
        return 0.0
    to_scan, nearest = scan_tree.query(part)
    on = to_scan <= threshold
    off = ~on
    front = 0
    if off.any():
        model, normals = outward
        hit = scan[nearest[off]]
        _, k = cKDTree(model).query(hit)
        front = int(np.count_nonzero(np.sum((part[off] - hit) * normals[k], axis=1) > 0.0))
    seen = int(np.count_nonzero(on)) + front
    return float(np.count_nonzero(on) / seen) if seen else 0.0


def scan_explained_score(source: O3dCloud, target: O3dCloud, fitted: Similarity, threshold: float) -> float:
    """How well ``fitted(source)`` explains the scan ``target`` where the scan saw it (target metres): the geometric
    mean of the target->source fitness within ``threshold`` (every scanned point has a counterpart on a whole
    model) and the source->target fitness over the source points within ``SEEN_REACH`` thresholds of a scanned
    point. ``two_way_score`` counts the source's unseen side as unexplained, so a scan of 40 % of an object
    scores at most about the square root of 0.4 however right the fit; this does not. 0 without such points."""
    src = fitted.apply_points(cloud_points(source))
    tgt = cloud_points(target)
    if len(src) == 0 or len(tgt) == 0:
        return 0.0
    seen = _seen_fit(src, cKDTree(tgt), threshold)
    if seen is None:
        return 0.0
    return math.sqrt(seen * _covered(tgt, src, threshold))


def functional_score(
    explained_score: float,
    fitted: Similarity,
    *,
    used_fine: O3dCloud,
    outward: tuple[Points, Points],
    tgt_fine_pts: Points,
    tgt_fine_tree: cKDTree,
    focus: Points,
    crop_radius: float,
    region_scale: float,
    threshold: float,
) -> float:
    """Ranking score led by the functional part: the cube root of the product of ``explained_score`` (the whole
    models' fit over the scanned surface), the part's fit onto the scan over the points a camera would have seen
    (``seen_fitness``) and the fit of the scan's region around the carried focus points back onto the part. Both
    directions of the part count only what the scan shows: its hidden side is no evidence against an alignment.
    The scan's region has the radius ``crop_radius`` (source metres) times ``region_scale`` for every alignment
    judged together, so a shrunken alignment is asked to explain as much of the scan as a full-sized one is, not
    a region shrunk with it. ``outward``: model points and their outward normals (source frame). Lengths in target
    metres unless named."""
    part = fitted.apply_points(cloud_points(used_fine))
    if len(part) == 0:
        return 0.0
    placed = (fitted.apply_points(outward[0]), outward[1] @ fitted.rotation.T)
    c_st = seen_fitness(part, placed, tgt_fine_pts, tgt_fine_tree, threshold)
    local = tgt_fine_pts[functional_mask(tgt_fine_pts, fitted.apply_points(focus), crop_radius * region_scale)]
    c_ts = _covered(local, part, threshold) if local.shape[0] > 0 else 0.0
    return float((explained_score * c_st * c_ts) ** (1.0 / 3.0))


def grip_score(
    src: Points, tgt: Points, grip: Points, fitted: Similarity, *, params: RegistrationParams, threshold: float
) -> float:
    """Two-way match of the balls around the grip points (source and carried into the target) within
    ``params.grip_threshold_factor`` x ``threshold`` (target metres), in (0, 1]."""
    threshold *= params.grip_threshold_factor
    radius = min(params.grip_frac * bbox_diagonal(src), params.grip_max_m)
    ball_s = src[functional_mask(src, grip, radius)]
    ball_t = tgt[functional_mask(tgt, fitted.apply_points(grip), radius * fitted.scale)]
    g_st = fitness(to_cloud(ball_s), to_cloud(tgt), fitted, threshold)[0] if len(ball_s) else 0.0
    g_ts = 0.0
    if len(ball_t):
        g_ts = fitness(to_cloud(ball_t), to_cloud(src), fitted.inverse(), threshold / fitted.scale)[0]
    floor = params.grip_floor
    return math.sqrt((g_st + floor) * (g_ts + floor)) / (1.0 + floor)


def ranked(alignments: list[Alignment]) -> list[Alignment]:
    """Best first: by score to two decimals, then by inlier RMSE."""
    return sorted(alignments, key=lambda a: (-round(a.score, 2), a.inlier_rmse_m))


def poor_fit_warning(best: Alignment, params: RegistrationParams, threshold: float) -> str | None:
    """The warning when the best alignment fits poorly (fitness, surface RMSE against ``threshold``, the two-way
    score or the ranking score beyond the limits of ``params``), else None."""
    poor = (
        best.fitness < params.poor_fitness
        or best.plane_rmse_m > params.poor_plane_frac * threshold
        or best.explained_score < params.poor_score
        or best.score < params.poor_rank_score
    )
    if not poor:
        return None
    return (
        f"poor registration: fitness {best.fitness:.2f} (want >= {params.poor_fitness}), "
        f"surface RMSE {best.plane_rmse_m * 1e3:.2f} mm (want <= {params.poor_plane_frac * threshold * 1e3:.2f}), "
        f"two-way score over the scanned surface {best.explained_score:.2f} (want >= {params.poor_score}), "
        f"functional and grip score {best.score:.2f} (want >= {params.poor_rank_score})"
    )
