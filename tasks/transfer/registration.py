"""Registration of a source object model onto a target model as a similarity transform (open3d 0.20).

Pipeline (all clouds are (n, 3) float64 metres, each in its own object/world frame):

1. Global starts (``global_starts``): PCA, FPFH + RANSAC and FGR candidates in normalised space, each refined
   by similarity ICP, the distinct ones back in metres plus their half-turn siblings.
2. Each candidate is refined here: similarity ICP on the whole model at a middle resolution, the model onto
   the target and the target onto the model (``both_ways_icp``: a whole model shrinks onto a partial scan), then a
   point-to-plane ICP with scale (``plane_icp``) on the functional part of the source (points within
   ``crop_radius_m`` of the focus points: the grasp and the chain's axis points, the rest of the model at a small
   weight), or on the whole model.
3. The refined alignments are scored and ranked (``scoring``): the whole models' two-way fit, the functional
   part's fit and, with ``grip`` points (the grasped part), how well the small balls around them match both ways
   (the handle side of a box, not its mirror image). A poor best fit is a warning.

The paper (Dang & Allen) used plain ICP, which neither finds a global alignment nor estimates scale;
``clouds.plain_icp`` is that baseline, for the benchmark.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from tasks.arrays import FloatArray, Points, check_points
from tasks.errors import TransferError
from tasks.transfer.clouds import (
    MIN_POINTS,
    O3dCloud,
    bbox_diagonal,
    check_model,
    cloud_points,
    downsample,
    fitness,
    functional_mask,
    median_spacing,
    outward_sample,
    similarity_icp,
    to_cloud,
    with_normals,
)
from tasks.transfer.global_starts import global_starts
from tasks.transfer.plane_icp import plane_residuals, plane_similarity_icp
from tasks.transfer.registration_types import Alignment, Registration, RegistrationParams
from tasks.transfer.scan_noise import scan_noise
from tasks.transfer.scoring import (
    functional_score,
    grip_score,
    poor_fit_warning,
    ranked,
    scan_explained_score,
    two_way_score,
)
from tasks.transfer.similarity import Similarity

__all__ = ["Alignment", "Registration", "RegistrationParams", "register_models"]

START_SCALE_SLACK = 1.25
"""Global starts up to 25 % outside the scale range are refined: their refinement may bring them within it."""
MID_VOXEL_DIVISOR = 80.0
"""The whole-model point-to-point stage works at the target's bounding-box diagonal / this."""
RESAMPLE_RESCALE = math.log(1.05)
"""The whole-model stage downsamples the source again when the scale moved by more than 5 %."""
PLANE_ICP_POINTS = 1500
"""Raw source points used by the final point-to-plane similarity refinement."""
OUTWARD_POINTS = 6000
"""Model points whose outward normals tell which side of a scanned surface is the camera's: the side is that of
the nearest, alike over a face, and 6000 put one within about a sixtieth of the object's diagonal."""
SURFACE_NORMAL_SPACINGS = 3.0
SURFACE_NORMAL_NN = 12
"""Surface normals of the fine stage: the 12 nearest points within 3 median point spacings, local enough for
thin parts (a mug's handle, a wall 4 mm thick) ..."""
NORMAL_NOISE_RADII = 3.0
"""... and over at least 3 of the scan's noise sigmas (``scan_noise``), with the count grown as the area: there the
disc's own spread across, r^2 / 4, is over twice the noise's along the normal; nearer, the least-variance
direction is as much the noise's as the surface's (1.5 mm of noise, points 0.5 mm apart: a normal over 3
spacings tilts by about 40 degrees)."""


def refine_planar(
    source: Points,
    target: Points,
    normals: Points,
    start: Similarity,
    *,
    threshold: float,
    max_rescale: float,
    weights: FloatArray | None = None,
    tree: cKDTree | None = None,
) -> Similarity:
    """Point-to-plane similarity ICP over shrinking distances; rigid when the scale runs away from ``start``.
    ``tree``: a KD-tree of ``target`` (built once per call when None)."""
    tree = cKDTree(target) if tree is None else tree
    fitted = start
    for dist in (4.0 * threshold, 2.0 * threshold, threshold):
        fitted = plane_similarity_icp(source, target, normals, fitted, dist, iterations=25, weights=weights, tree=tree)
    if abs(math.log(fitted.scale / start.scale)) <= math.log(max_rescale):
        return fitted
    fitted = start
    for dist in (4.0 * threshold, 2.0 * threshold, threshold):
        fitted = plane_similarity_icp(
            source, target, normals, fitted, dist, iterations=25, with_scale=False, weights=weights, tree=tree
        )
    return fitted


def functional_region(
    src: Points, focus: Points | None, params: RegistrationParams, warnings: list[str]
) -> tuple[np.ndarray, float | None]:
    """Indices of the source points the refinement uses and the crop radius (metres; None: the whole model).

    The radius grows by 1.5 until the region holds ``params.min_crop_points``; a region still under
    ``MIN_POINTS`` falls back to the whole model with a warning."""
    if params.whole or focus is None or len(focus) == 0:
        return np.arange(src.shape[0]), None
    foc = check_points(focus, "focus")
    crop_radius = params.crop_radius_m or params.auto_crop_frac * bbox_diagonal(src)
    mask = functional_mask(src, foc, crop_radius)
    while int(mask.sum()) < min(params.min_crop_points, src.shape[0]) and crop_radius < bbox_diagonal(src):
        crop_radius *= 1.5
        mask = functional_mask(src, foc, crop_radius)
    used_idx = np.flatnonzero(mask)
    if used_idx.shape[0] < MIN_POINTS:
        warnings.append("functional region too small; aligned the whole model")
        return np.arange(src.shape[0]), None
    return used_idx, crop_radius


@dataclass(frozen=True)
class FineTarget:
    """The target prepared for the refinement: clouds at three resolutions, surface normals, thresholds."""

    points: Points
    normals: Points
    """(n, 3) unit surface normals of ``points`` (unsigned)."""
    fine: O3dCloud
    fine_points: Points
    mid: O3dCloud
    fine_voxel: float
    mid_voxel: float
    threshold: float
    """Final correspondence threshold, metres."""
    spacing: float
    """Median nearest-neighbour spacing of the target's points, metres."""
    tree: cKDTree
    """KD-tree of ``points``, built once for every start's refinement."""
    fine_tree: cKDTree
    """KD-tree of ``fine_points``, built once for every alignment's scoring."""


def prepare_target(tgt: Points, params: RegistrationParams) -> FineTarget:
    """Downsampled clouds, normals and thresholds of the target (metres)."""
    span_t = bbox_diagonal(tgt)
    spacing = median_spacing(tgt)
    fine_voxel = max(params.fine_voxel_frac * span_t, spacing)
    threshold = max(1.5 * fine_voxel, 2.0 * spacing)
    tgt_fine = downsample(tgt, fine_voxel)
    fine_points = cloud_points(tgt_fine)
    normals = surface_normals(tgt, spacing)
    mid_voxel = max(span_t / MID_VOXEL_DIVISOR, spacing)
    mid = downsample(tgt, mid_voxel)
    return FineTarget(
        tgt,
        normals,
        tgt_fine,
        fine_points,
        mid,
        fine_voxel,
        mid_voxel,
        threshold,
        spacing,
        cKDTree(tgt),
        cKDTree(fine_points),
    )


def surface_normals(points: Points, spacing_m: float) -> Points:
    """(n, 3) unit surface normals (unsigned) of model points whose median spacing is ``spacing_m``: the fine
    stage's neighbourhood (``SURFACE_NORMAL_NN`` points within ``SURFACE_NORMAL_SPACINGS`` spacings, or the
    points within ``NORMAL_NOISE_RADII`` noise sigmas, as many more as the area, on a scan whose noise is large
    against its spacing)."""
    least = SURFACE_NORMAL_SPACINGS * spacing_m
    radius = max(least, NORMAL_NOISE_RADII * scan_noise(points, spacing_m))
    count = math.ceil(SURFACE_NORMAL_NN * (radius / least) ** 2 - 1e-9)
    cloud = with_normals(to_cloud(points), radius, max_nn=count)
    out: Points = np.asarray(cloud.normals, dtype=np.float64)
    return out


def both_ways_icp(
    src: Points,
    tgt_mid: O3dCloud,
    start: Similarity,
    voxel: float,
    threshold: float,
    *,
    forward: tuple[Similarity, float] | None = None,
) -> tuple[Similarity, float]:
    """Similarity ICP of the source (``src`` metres, voxel-downsampled to ``voxel`` in target metres) onto the
    target and of the target onto the source (inverted), from ``start``; the one with the better two-way score
    and that score (distances in target metres).

    Point-to-point ICP with scale shrinks a whole model onto a partial scan (the points of the faces the scan
    missed pull towards its edges); the scan's own points all have a counterpart on a whole model, so fitting
    the scan onto the model keeps the scale. A partial source is the mirror case, hence both. When the scale
    moves by more than 5 %, the source is downsampled again at the new scale and fitted once more: voxel
    centroids at a coarser spacing sit further inside a box's edges and shrink it (1.6 % on a cabinet).
    ``forward``: the first round's model-onto-target fit from ``start`` and its score, when already computed."""
    best, best_score = start, -1.0
    for round_ in range(2):
        begin = best
        src_mid = downsample(src, voxel / begin.scale)
        if round_ == 0 and forward is not None:
            scored = [(forward[1], forward[0])]
        else:
            ahead = similarity_icp(src_mid, tgt_mid, begin, (4.0 * voxel, threshold), 30)
            scored = [(two_way_score(src_mid, tgt_mid, ahead, threshold), ahead)]
        distances = (4.0 * voxel / begin.scale, threshold / begin.scale)
        back = similarity_icp(tgt_mid, src_mid, begin.inverse(), distances, 30).inverse()
        scored.append((two_way_score(src_mid, tgt_mid, back, threshold), back))
        best_score, best = max(scored, key=lambda r: r[0])
        if abs(math.log(best.scale / begin.scale)) <= RESAMPLE_RESCALE:
            break
    return best, best_score


def whole_model_fits(
    src: Points, tgt_mid: O3dCloud, start: Similarity, voxel: float, threshold: float
) -> list[tuple[Similarity, float, float]]:
    """Whole-model fits of one start to refine further, each with its two-way score and that score over the
    scanned surface (``scan_explained_score``): the model onto the target
    (``similarity_icp``), and ``both_ways_icp``'s fit as well when its scale differs from that one's by more than
    5 %. Both are kept because neither scale is always right: a whole model fitted onto a partial scan shrinks
    (a cabinet), while two scans of objects of other proportions (a recorded bottle onto another) fitted both ways
    take the body's scale, 28 % off the cap's, from which the cap's refinement does not come back."""
    mid = downsample(src, voxel / start.scale)
    forward = similarity_icp(mid, tgt_mid, start, (4.0 * voxel, threshold), 30)
    forward_score = two_way_score(mid, tgt_mid, forward, threshold)
    fits = [(forward, forward_score)]
    both, both_score = both_ways_icp(src, tgt_mid, start, voxel, threshold, forward=(forward, forward_score))
    if abs(math.log(both.scale / forward.scale)) > RESAMPLE_RESCALE:
        fits.append((both, both_score))
    return [
        (fit, score, scan_explained_score(downsample(src, voxel / fit.scale), tgt_mid, fit, threshold))
        for fit, score in fits
    ]


@dataclass(frozen=True)
class ScoredPart:
    """What an alignment is scored on (source frame, metres): the whole model, the points used (the functional
    part or the whole), the focus points and crop radius (None: the whole model), the grip points, and a raw
    sample of the used points with their surface normals."""

    model: Points
    used: Points
    focus: Points | None
    crop_radius: float | None
    grip: Points | None
    raw_sample: Points
    raw_normals: Points
    outward: tuple[Points, Points]
    """An even sample of the whole model and its outward normals (``clouds.outward_normals``)."""


def score_fit(
    part: ScoredPart,
    fitted: Similarity,
    model_score: float,
    start: str,
    *,
    explained_score: float,
    fine: FineTarget,
    params: RegistrationParams,
    sample_scale: float,
    region_scale: float,
) -> Alignment:
    """``fitted`` (source onto target) scored on ``part`` against ``fine``: the functional part's fitness and RMSE,
    its surface RMSE and normal agreement, and the ranking score led by the whole models' fit over the scanned
    surface ``explained_score`` (``model_score``: their two-way fit, kept for the report). The used points are
    downsampled to the fine voxel at ``sample_scale`` (target over source size); the scan's functional region is
    sized at ``region_scale`` (the same for every alignment ranked together)."""
    threshold = fine.threshold
    score = explained_score
    used_fine = downsample(part.used, fine.fine_voxel / sample_scale)
    if part.focus is not None and part.crop_radius is not None:
        score = functional_score(
            explained_score,
            fitted,
            used_fine=used_fine,
            outward=part.outward,
            tgt_fine_pts=fine.fine_points,
            tgt_fine_tree=fine.fine_tree,
            focus=part.focus,
            crop_radius=part.crop_radius,
            region_scale=region_scale,
            threshold=threshold,
        )
    if part.grip is not None:
        score *= grip_score(part.model, fine.fine_points, part.grip, fitted, params=params, threshold=threshold)
    fit, rmse = fitness(used_fine, fine.fine, fitted, threshold)
    plane_rmse, agreement = plane_residuals(
        part.raw_sample, part.raw_normals, fine.points, fine.normals, fitted, max_distance_m=threshold
    )
    return Alignment(fitted, fit, rmse, plane_rmse, agreement, model_score, score, start, explained_score)


def register_models(
    source: Points,
    target: Points,
    *,
    focus: Points | None = None,
    grip: Points | None = None,
    params: RegistrationParams | None = None,
    init: Similarity | None = None,
    rng: np.random.Generator,
) -> Registration:
    """Register ``source`` (metres, source frame) onto ``target`` (metres, target frame) as a similarity.

    ``focus``: (k, 3) points of the source's functional part (grasp position, axis points); with
    ``params.whole`` or no focus the whole model is used in the refinement. ``grip``: (g, 3) points of the grasped
    part (the model point nearest the wrist): alignments are also ranked by how well the small balls around them
    match both ways, which tells a box's handle side from its mirror image. ``init``: an optional extra start
    (source to target, metres). Raises ``TransferError`` for unusable clouds.
    """
    params = params or RegistrationParams()
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)  # its warnings would go to stdout
    src = check_model(source, "source model")
    tgt = check_model(target, "target model")
    lo, hi = params.scale_range
    kept = [
        (name, start)
        for name, start in global_starts(src, tgt, span_t=bbox_diagonal(tgt), params=params, rng=rng, init=init)
        if lo / START_SCALE_SLACK <= start.scale <= hi * START_SCALE_SLACK
    ]

    warnings: list[str] = []
    used_idx, crop_radius = functional_region(src, focus, params, warnings)
    used = src[used_idx]
    fine = prepare_target(tgt, params)
    threshold, mid_threshold = fine.threshold, 1.5 * fine.mid_voxel
    # raw points (not voxel centroids, which sit inside curved surfaces and bias the scale)
    pick = rng.permutation(used.shape[0])[:PLANE_ICP_POINTS]
    raw_sample = used[pick]
    raw_normals = surface_normals(src, median_spacing(src))[used_idx[pick]]
    # the functional part leads the final refinement; the rest of the model keeps it from tilting where the
    # part alone is ambiguous (a cap seen from one side), with ``context_weight`` of the part's total weight
    refine_points, refine_weights = raw_sample, None
    if crop_radius is not None and params.context_weight > 0.0:
        context = src[rng.permutation(src.shape[0])[:PLANE_ICP_POINTS]]
        refine_points = np.vstack([raw_sample, context])
        refine_weights = np.concatenate(
            [np.ones(len(raw_sample)), np.full(len(context), params.context_weight * len(raw_sample) / len(context))]
        )
    foc = check_points(focus, "focus") if crop_radius is not None and focus is not None else None
    grip_pts = check_points(grip, "grip") if grip is not None and len(grip) > 0 else None
    alignments: list[Alignment] = []
    whole = [
        (name, fit)
        for name, start in kept
        for fit in whole_model_fits(src, fine.mid, start, fine.mid_voxel, mid_threshold)
    ]
    part = ScoredPart(
        src,
        used if foc is not None else src,
        foc,
        crop_radius,
        grip_pts,
        raw_sample,
        raw_normals,
        outward_sample(src, OUTWARD_POINTS),
    )
    refined = [
        refine_planar(
            refine_points,
            tgt,
            fine.normals,
            whole_fit,
            threshold=threshold,
            max_rescale=params.max_crop_rescale,
            weights=refine_weights,
            tree=fine.tree,
        )
        for _, (whole_fit, _, _) in whole
    ]
    # every alignment is asked to explain a scan region of one size: that of the scale whose whole model explains
    # the scanned surface best
    in_range = [
        (explained, fitted.scale)
        for (_, (_, _, explained)), fitted in zip(whole, refined, strict=True)
        if lo <= fitted.scale <= hi
    ]
    region_scale = max(in_range)[1] if in_range else 1.0
    for (name, (whole_fit, model_score, explained)), fitted in zip(whole, refined, strict=True):
        alignments.append(
            score_fit(
                part,
                fitted,
                model_score,
                name,
                explained_score=explained,
                fine=fine,
                params=params,
                sample_scale=whole_fit.scale,
                region_scale=region_scale,
            )
        )
    order = ranked([a for a in alignments if lo <= a.transform.scale <= hi])
    if not order:
        msg = (
            f"no alignment of the models at a scale within {lo:g}..{hi:g} (target size over source size; "
            "--scale-range LO HI to allow others)"
        )
        raise TransferError(msg)
    best = order[0]
    warning = poor_fit_warning(best, params, threshold)
    if warning is not None:
        warnings.append(warning)
    return Registration(
        best=best,
        alignments=tuple(order),
        threshold_m=threshold,
        fine_voxel_m=fine.fine_voxel,
        spacing_m=fine.spacing,
        crop_radius_m=crop_radius,
        source_points_used=int(used.shape[0]),
        poor=warning is not None,
        warnings=tuple(warnings),
    )
