"""Registration of a source object model onto a target model as a similarity transform (open3d 0.20).

Pipeline (all clouds are (n, 3) float64 metres, each in its own object/world frame):

1. Both clouds are normalised (centroid at the origin, RMS radius 1) so that the global stage works at one
   scale whatever the two objects' sizes; the scale ratio of the radii is the first scale guess.
2. Global starts in normalised space: the 24 rotations mapping principal axes onto principal axes (PCA starts
   and their flips), FPFH + RANSAC and fast global registration (FGR), each refined by similarity ICP
   (``TransformationEstimationPointToPoint(with_scaling=True)``). Candidates are scored by the geometric mean
   of the two one-way fitnesses, so neither a shrunken source nor a partial target wins by accident.
3. The best distinct candidates are refined at fine resolution on the functional part of the source (points
   within ``crop_radius_m`` of the focus points: the grasp and the chain's axis points), or on the whole
   model, again with similarity ICP, and ranked by fitness and inlier RMSE; with ``grip`` points (the grasped
   part) also by how well the small balls around them match both ways (the handle side of a box, not its
   mirror image).

The paper (Dang & Allen) used plain ICP, which neither finds a global alignment nor estimates scale;
``plain_icp`` is that baseline, for the benchmark.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import open3d as o3d

from tasks.arrays import BoolArray, FloatArray, Points, check_points
from tasks.errors import TransferError
from tasks.transfer.plane_icp import plane_residuals, plane_similarity_icp
from tasks.transfer.similarity import Similarity

O3dCloud = o3d.geometry.PointCloud
reg = o3d.pipelines.registration

MIN_POINTS = 30
"""Fewer points than this in either model cannot be registered meaningfully."""
COARSE_VOXEL = 0.09
"""Voxel of the global stage in normalised units (RMS radius 1): about 1 200 points on a bottle."""
FPFH_RADIUS = 5.0 * COARSE_VOXEL
NORMAL_RADIUS = 2.0 * COARSE_VOXEL
MID_VOXEL_DIVISOR = 80.0
"""The whole-model point-to-point stage works at the target's bounding-box diagonal / this."""
PLANE_ICP_POINTS = 1500
SURFACE_NORMAL_SPACINGS = 3.0
SURFACE_NORMAL_NN = 12
"""Surface normals of the fine stage: the 12 nearest points within 3 median point spacings, local enough for
thin parts (a mug's handle, a wall 4 mm thick)."""
"""Raw source points used by the final point-to-plane similarity refinement."""


@dataclass(frozen=True)
class RegistrationParams:
    """Settings of ``register_models``; lengths in metres unless named otherwise."""

    crop_radius_m: float | None = None
    """Radius of the functional region around each focus point; None: ``auto_crop_frac`` x source diagonal."""
    auto_crop_frac: float = 0.18
    whole: bool = False
    """Align the whole source model instead of its functional region."""
    fine_voxel_frac: float = 1.0 / 150.0
    """Fine voxel as a fraction of the target's bounding-box diagonal."""
    keep: int = 10
    """Distinct global candidates refined on the functional part."""
    symmetry_candidates: int = 4
    """The best this many also get their half-turns about the source's principal axes refined."""
    ransac_iterations: int = 30_000
    ransac_runs: int = 2
    poor_fitness: float = 0.35
    """Below this final fitness (fraction of used source points with a target point within the threshold) the
    registration is poor."""
    poor_plane_frac: float = 0.45
    """Above this point-to-plane RMSE, as a fraction of the final correspondence threshold, it is poor as well:
    two instances of a built-in scene (other sizes, the same design) fit at 0.14-0.36, a sideboard turned by 90
    degrees at 0.44 (and its two-way score gives it away)."""
    poor_score: float = 0.55
    """Below this two-way score (how much of each model the other explains) it is poor: a partial scan of the
    same object scores 0.7 and more, another instance of a scene 0.8 and more, a sideboard turned by 90 degrees
    0.49, a shrunken source sitting on a patch of the target far less."""
    min_crop_points: int = 150
    context_weight: float = 0.3
    """Total weight of the rest of the model against the functional part's in the final refinement (0: the
    functional part alone)."""
    max_crop_rescale: float = 1.5
    """The functional-part refinement may change the whole-model scale by at most this factor (else rigid)."""
    grip_frac: float = 0.08
    """Radius of the grasped part's ball around each grip point, as a fraction of the source's diagonal ..."""
    grip_max_m: float = 0.06
    """... and at most this (metres, source frame): about what a Barrett hand closes around, so that on a door
    the lever still fills half the ball rather than a tenth of it."""
    grip_floor: float = 0.05
    """Added to both one-way fitnesses of the grip balls, so a scan missing the grasped part scores all alike."""


@dataclass(frozen=True)
class Alignment:
    """One refined alignment of the source onto the target."""

    transform: Similarity
    fitness: float
    """Fraction of the used source points (functional part or whole) with a target point within ``threshold_m``."""
    inlier_rmse_m: float
    """RMS distance of those inlier pairs, metres (target frame)."""
    plane_rmse_m: float
    """RMS point-to-plane distance of the inlier pairs (raw source points against the target's surface), metres:
    about the scan noise for a good fit, a sizeable fraction of the threshold for a wrong or unrelated one."""
    normal_agreement: float
    """Fraction of the inlier pairs whose surface normals agree (unsigned, within 25 degrees)."""
    model_score: float
    """Geometric mean of the whole models' two one-way fitnesses (how much of each the other explains)."""
    score: float
    """Ranking score: geometric mean of the source->target and the local target->source fitness."""
    start: str
    """Which global start it came from (``pca-<k>``, ``ransac-<k>``, ``fgr``, ``init``)."""


@dataclass(frozen=True)
class Registration:
    """Outcome of ``register_models``: the best alignment and the runner-ups (best first)."""

    best: Alignment
    alignments: tuple[Alignment, ...]
    threshold_m: float
    """Final correspondence threshold, metres (target frame)."""
    fine_voxel_m: float
    spacing_m: float
    """Median nearest-neighbour spacing of the target's points, metres."""
    crop_radius_m: float | None
    """Radius of the functional region used, metres (source frame); None when the whole model was used."""
    source_points_used: int
    poor: bool
    warnings: tuple[str, ...]


def _cloud(points: Points) -> O3dCloud:
    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64))
    return pcd


def _points(pcd: O3dCloud) -> Points:
    out: Points = np.asarray(pcd.points, dtype=np.float64).copy()
    return out


def _downsample(points: Points, voxel: float) -> O3dCloud:
    return _cloud(points).voxel_down_sample(voxel)


def _with_normals(pcd: O3dCloud, radius: float, max_nn: int = 30) -> O3dCloud:
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=max_nn))
    return pcd


def check_model(points: object, name: str) -> Points:
    """Validate a model cloud: (n, 3), finite rows kept, at least ``MIN_POINTS`` distinct points."""
    try:
        pts = check_points(points, name)
    except ValueError as err:
        raise TransferError(str(err)) from err
    pts = pts[np.isfinite(pts).all(axis=1)]
    if pts.shape[0] < MIN_POINTS:
        msg = f"{name}: {pts.shape[0]} finite points, need at least {MIN_POINTS}"
        raise TransferError(msg)
    extent = float(np.ptp(pts, axis=0).max())
    if not extent > 0.0:
        msg = f"{name}: all points coincide"
        raise TransferError(msg)
    return pts


def bbox_diagonal(points: Points) -> float:
    """Length of the axis-aligned bounding-box diagonal (metres)."""
    return float(np.linalg.norm(np.ptp(points, axis=0)))


def functional_mask(points: Points, focus: Points, radius_m: float) -> BoolArray:
    """Points within ``radius_m`` of any focus point (the functional region of the model)."""
    pts = check_points(points, "points")
    foc = check_points(focus, "focus")
    d2 = ((pts[:, None, :] - foc[None, :, :]) ** 2).sum(axis=2).min(axis=1)
    out: BoolArray = d2 <= radius_m**2
    return out


def _normaliser(points: Points) -> Similarity:
    """Similarity taking ``points`` to centroid 0 and RMS radius 1."""
    centroid = points.mean(axis=0)
    radius = float(np.sqrt(((points - centroid) ** 2).sum(axis=1).mean()))
    return Similarity(1.0 / radius, np.eye(3), -centroid / radius)


def _pca_frame(points: Points) -> FloatArray:
    """Principal axes (columns, largest variance first) of a centred cloud."""
    _, vecs = np.linalg.eigh(np.cov(points.T))
    out: FloatArray = vecs[:, ::-1]
    return out


def _extents(points: Points, axes: FloatArray) -> FloatArray:
    """Robust extents (1st to 99th percentile) of ``points`` along each column of ``axes``."""
    proj = points @ axes
    out: FloatArray = np.percentile(proj, 99.0, axis=0) - np.percentile(proj, 1.0, axis=0)
    return out


def _pca_starts(src_n: Points, tgt_n: Points) -> list[tuple[str, Similarity]]:
    """The 24 proper rotations mapping the source's principal axes onto the target's (normalised clouds).

    Each start's scale is the largest ratio of matched extents: a partial scan only ever shortens the target's
    extents, so the largest ratio is the one least affected by what the scan missed.
    """
    vs, vt = _pca_frame(src_n), _pca_frame(tgt_n)
    ext_s, ext_t = _extents(src_n, vs), _extents(tgt_n, vt)
    starts: list[tuple[str, Similarity]] = []
    for perm in itertools.permutations(range(3)):
        ratio = float(np.clip(max(ext_t[perm[i]] / max(ext_s[i], 1e-9) for i in range(3)), 0.5, 2.0))
        for signs in itertools.product((1.0, -1.0), repeat=3):
            mapping = np.zeros((3, 3))
            for i, (j, s) in enumerate(zip(perm, signs, strict=True)):
                mapping[j, i] = s
            rot = vt @ mapping @ vs.T
            if np.linalg.det(rot) < 0:
                continue
            starts.append((f"pca-{len(starts)}", Similarity(ratio, rot, np.zeros(3))))
    return starts


def _similarity_icp(
    source: O3dCloud, target: O3dCloud, init: Similarity, distances: tuple[float, ...], iterations: int = 40
) -> Similarity:
    """Similarity ICP (point to point with scale) over a schedule of shrinking correspondence distances."""
    estimation = reg.TransformationEstimationPointToPoint(with_scaling=True)
    criteria = reg.ICPConvergenceCriteria(relative_fitness=1e-7, relative_rmse=1e-7, max_iteration=iterations)
    current = init
    for dist in distances:
        result = reg.registration_icp(source, target, dist, current.matrix(), estimation, criteria)
        try:
            current = Similarity.from_matrix(np.asarray(result.transformation))
        except ValueError:  # degenerate estimate (no correspondences): keep the last good one
            break
    return current


def _refine_planar(
    source: Points,
    target: Points,
    normals: Points,
    start: Similarity,
    *,
    threshold: float,
    max_rescale: float,
    weights: FloatArray | None = None,
) -> Similarity:
    """Point-to-plane similarity ICP over shrinking distances; rigid when the scale runs away from ``start``."""
    fitted = start
    for dist in (4.0 * threshold, 2.0 * threshold, threshold):
        fitted = plane_similarity_icp(source, target, normals, fitted, dist, iterations=25, weights=weights)
    if abs(math.log(fitted.scale / start.scale)) <= math.log(max_rescale):
        return fitted
    fitted = start
    for dist in (4.0 * threshold, 2.0 * threshold, threshold):
        fitted = plane_similarity_icp(
            source, target, normals, fitted, dist, iterations=25, with_scale=False, weights=weights
        )
    return fitted


def _fitness(source: O3dCloud, target: O3dCloud, transform: Similarity, dist: float) -> tuple[float, float]:
    """(fitness, inlier RMSE) of ``transform(source)`` against ``target`` within ``dist``."""
    ev = reg.evaluate_registration(source, target, dist, transform.matrix())
    return float(ev.fitness), float(ev.inlier_rmse)


def _distinct(a: Similarity, b: Similarity, span: float) -> bool:
    """True when two transforms differ by more than 5 degrees, 5 % of ``span`` or 5 % in scale."""
    cos = (np.trace(a.rotation.T @ b.rotation) - 1.0) / 2.0
    angle = math.degrees(math.acos(float(np.clip(cos, -1.0, 1.0))))
    shift = float(np.linalg.norm(a.translation - b.translation))
    return angle > 5.0 or shift > 0.05 * span or abs(math.log(a.scale / b.scale)) > 0.05


def _global_candidates(
    src_n: Points, tgt_n: Points, params: RegistrationParams, rng: np.random.Generator, init: Similarity | None
) -> list[tuple[float, str, Similarity]]:
    """Scored similarity candidates in normalised space, best first (score, start name, transform)."""
    src = _with_normals(_downsample(src_n, COARSE_VOXEL), NORMAL_RADIUS)
    tgt = _with_normals(_downsample(tgt_n, COARSE_VOXEL), NORMAL_RADIUS)
    starts = _pca_starts(_points(src), _points(tgt))
    if init is not None:
        starts.insert(0, ("init", init))
    o3d.utility.random.seed(int(rng.integers(0, 2**31 - 1)))
    kd = o3d.geometry.KDTreeSearchParamHybrid(radius=FPFH_RADIUS, max_nn=100)
    f_src = reg.compute_fpfh_feature(src, kd)  # type: ignore[call-arg] # stub lists optional indices
    f_tgt = reg.compute_fpfh_feature(tgt, kd)  # type: ignore[call-arg] # stub lists optional indices
    checkers = [
        reg.CorrespondenceCheckerBasedOnEdgeLength(0.75),
        reg.CorrespondenceCheckerBasedOnDistance(3.0 * COARSE_VOXEL),
    ]
    for k in range(params.ransac_runs):
        result = reg.registration_ransac_based_on_feature_matching(
            src,
            tgt,
            f_src,
            f_tgt,
            k % 2 == 1,
            3.0 * COARSE_VOXEL,
            reg.TransformationEstimationPointToPoint(with_scaling=False),
            3,
            checkers,
            reg.RANSACConvergenceCriteria(params.ransac_iterations, 0.999),
        )
        starts.append((f"ransac-{k}", _safe_similarity(np.asarray(result.transformation))))
    fgr = reg.registration_fgr_based_on_feature_matching(
        src, tgt, f_src, f_tgt, reg.FastGlobalRegistrationOption(maximum_correspondence_distance=1.5 * COARSE_VOXEL)
    )
    starts.append(("fgr", _safe_similarity(np.asarray(fgr.transformation))))
    threshold = 1.5 * COARSE_VOXEL
    scored: list[tuple[float, str, Similarity]] = []
    for name, start in starts:
        fitted = _similarity_icp(src, tgt, start, (3.0 * COARSE_VOXEL, threshold), 25)
        f_st, _ = _fitness(src, tgt, fitted, threshold)
        f_ts, _ = _fitness(tgt, src, fitted.inverse(), threshold / fitted.scale)
        scored.append((math.sqrt(f_st * f_ts), name, fitted))
    scored.sort(key=lambda row: -row[0])
    return scored


def _grip_score(
    src: Points, tgt: Points, grip: Points, fitted: Similarity, *, params: RegistrationParams, threshold: float
) -> float:
    """Two-way match of the balls around the grip points (source and carried into the target), in (0, 1]."""
    radius = min(params.grip_frac * bbox_diagonal(src), params.grip_max_m)
    ball_s = src[functional_mask(src, grip, radius)]
    ball_t = tgt[functional_mask(tgt, fitted.apply_points(grip), radius * fitted.scale)]
    g_st = _fitness(_cloud(ball_s), _cloud(tgt), fitted, threshold)[0] if len(ball_s) else 0.0
    g_ts = _fitness(_cloud(ball_t), _cloud(src), fitted.inverse(), threshold / fitted.scale)[0] if len(ball_t) else 0.0
    floor = params.grip_floor
    return math.sqrt((g_st + floor) * (g_ts + floor)) / (1.0 + floor)


def _safe_similarity(matrix: FloatArray) -> Similarity:
    try:
        return Similarity.from_matrix(matrix)
    except ValueError:
        return Similarity.identity()


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
    norm_s, norm_t = _normaliser(src), _normaliser(tgt)
    init_n = norm_t.compose(init.compose(norm_s.inverse())) if init is not None else None
    scored = _global_candidates(norm_s.apply_points(src), norm_t.apply_points(tgt), params, rng, init_n)

    # Back to metres: T = norm_t^-1 o X o norm_s; keep distinct candidates only.
    span_t = bbox_diagonal(tgt)
    kept: list[tuple[str, Similarity]] = []
    for _, name, fitted in scored:
        metric = norm_t.inverse().compose(fitted.compose(norm_s))
        if all(_distinct(metric, other, span_t) for _, other in kept):
            kept.append((name, metric))
        if len(kept) >= params.keep:
            break

    # near-symmetric objects (boxes, cylinders) hide their telling detail at the coarse scale: add the turns by
    # half a revolution about the source's own principal axes of the best candidates, for the fine stage to judge
    centre_s = src.mean(axis=0)
    axes_s = _pca_frame(src - centre_s)
    for name, metric in list(kept[: params.symmetry_candidates]):
        for k in range(3):
            flip = Similarity(1.0, 2.0 * np.outer(axes_s[:, k], axes_s[:, k]) - np.eye(3), np.zeros(3))
            about = Similarity(1.0, np.eye(3), centre_s).compose(flip.compose(Similarity(1.0, np.eye(3), -centre_s)))
            sibling = metric.compose(about)
            if all(_distinct(sibling, other, span_t) for _, other in kept):
                kept.append((f"{name}-flip{k}", sibling))

    warnings: list[str] = []
    crop_radius: float | None = None
    used_idx = np.arange(src.shape[0])
    if not params.whole and focus is not None and len(focus) > 0:
        foc = check_points(focus, "focus")
        crop_radius = params.crop_radius_m or params.auto_crop_frac * bbox_diagonal(src)
        mask = functional_mask(src, foc, crop_radius)
        while int(mask.sum()) < min(params.min_crop_points, src.shape[0]) and crop_radius < bbox_diagonal(src):
            crop_radius *= 1.5
            mask = functional_mask(src, foc, crop_radius)
        used_idx = np.flatnonzero(mask)
        if used_idx.shape[0] < MIN_POINTS:
            warnings.append("functional region too small; aligned the whole model")
            used_idx, crop_radius = np.arange(src.shape[0]), None
    used = src[used_idx]

    spacing = float(np.median(np.asarray(_cloud(tgt).compute_nearest_neighbor_distance())))
    fine_voxel = max(params.fine_voxel_frac * span_t, spacing)
    threshold = max(1.5 * fine_voxel, 2.0 * spacing)
    tgt_fine = _downsample(tgt, fine_voxel)
    tgt_fine_pts = _points(tgt_fine)
    tgt_full = _with_normals(_cloud(tgt), SURFACE_NORMAL_SPACINGS * spacing, max_nn=SURFACE_NORMAL_NN)
    tgt_normals = np.asarray(tgt_full.normals, dtype=np.float64)
    mid_voxel = max(span_t / MID_VOXEL_DIVISOR, spacing)
    tgt_mid = _downsample(tgt, mid_voxel)
    mid_threshold = 1.5 * mid_voxel
    # raw points (not voxel centroids, which sit inside curved surfaces and bias the scale)
    pick = rng.permutation(used.shape[0])[:PLANE_ICP_POINTS]
    raw_sample = used[pick]
    src_spacing = float(np.median(np.asarray(_cloud(src).compute_nearest_neighbor_distance())))
    src_cloud = _with_normals(_cloud(src), SURFACE_NORMAL_SPACINGS * src_spacing, max_nn=SURFACE_NORMAL_NN)
    raw_normals = np.asarray(src_cloud.normals, dtype=np.float64)[used_idx[pick]]
    # the functional part leads the final refinement; the rest of the model keeps it from tilting where the
    # part alone is ambiguous (a cap seen from one side), with ``context_weight`` of the part's total weight
    refine_points, refine_weights = raw_sample, None
    if crop_radius is not None and params.context_weight > 0.0:
        context = src[rng.permutation(src.shape[0])[:PLANE_ICP_POINTS]]
        refine_points = np.vstack([raw_sample, context])
        refine_weights = np.concatenate(
            [np.ones(len(raw_sample)), np.full(len(context), params.context_weight * len(raw_sample) / len(context))]
        )
    alignments: list[Alignment] = []
    for name, start in kept:
        whole_mid = _downsample(src, mid_voxel / start.scale)
        fitted = _similarity_icp(whole_mid, tgt_mid, start, (4.0 * mid_voxel, mid_threshold), 30)
        f_st, _ = _fitness(whole_mid, tgt_mid, fitted, mid_threshold)
        f_ts, _ = _fitness(tgt_mid, whole_mid, fitted.inverse(), mid_threshold / fitted.scale)
        score = model_score = math.sqrt(f_st * f_ts)
        whole_fine = _downsample(src, fine_voxel / fitted.scale)
        used_fine = whole_fine
        if crop_radius is not None and focus is not None:
            used_fine = _downsample(used, fine_voxel / fitted.scale)
        fitted = _refine_planar(
            refine_points,
            tgt,
            tgt_normals,
            fitted,
            threshold=threshold,
            max_rescale=params.max_crop_rescale,
            weights=refine_weights,
        )
        if crop_radius is not None and focus is not None:
            centres = fitted.apply_points(check_points(focus, "focus"))
            local = tgt_fine_pts[functional_mask(tgt_fine_pts, centres, crop_radius * fitted.scale)]
            c_st, _ = _fitness(used_fine, tgt_fine, fitted, threshold)
            c_ts = 0.0
            if local.shape[0] > 0:
                c_ts, _ = _fitness(_cloud(local), used_fine, fitted.inverse(), threshold / fitted.scale)
            score = score ** (1.0 / 3.0) * (c_st**0.75 * c_ts**0.25) ** (2.0 / 3.0)  # the functional part leads
        if grip is not None and len(grip) > 0:
            score *= _grip_score(
                src, tgt_fine_pts, check_points(grip, "grip"), fitted, params=params, threshold=threshold
            )
        fitness, rmse = _fitness(used_fine, tgt_fine, fitted, threshold)
        plane_rmse, agreement = plane_residuals(
            raw_sample, raw_normals, tgt, tgt_normals, fitted, max_distance_m=threshold
        )
        alignments.append(Alignment(fitted, fitness, rmse, plane_rmse, agreement, model_score, score, name))
    alignments.sort(key=lambda a: (-round(a.score, 2), a.inlier_rmse_m))
    best = alignments[0]
    poor = (
        best.fitness < params.poor_fitness
        or best.plane_rmse_m > params.poor_plane_frac * threshold
        or best.model_score < params.poor_score
    )
    if poor:
        warnings.append(
            f"poor registration: fitness {best.fitness:.2f} (want >= {params.poor_fitness}), "
            f"surface RMSE {best.plane_rmse_m * 1e3:.2f} mm (want <= {params.poor_plane_frac * threshold * 1e3:.2f}), "
            f"two-way score {best.model_score:.2f} (want >= {params.poor_score})"
        )
    return Registration(
        best=best,
        alignments=tuple(alignments),
        threshold_m=threshold,
        fine_voxel_m=fine_voxel,
        spacing_m=spacing,
        crop_radius_m=crop_radius,
        source_points_used=int(used.shape[0]),
        poor=poor,
        warnings=tuple(warnings),
    )


def plain_icp(source: Points, target: Points, *, max_distance_m: float | None = None) -> Similarity:
    """The paper's baseline: rigid point-to-point ICP from the identity, no scale (metres)."""
    src = check_model(source, "source model")
    tgt = check_model(target, "target model")
    span = bbox_diagonal(tgt)
    voxel = span / 150.0
    dist = max_distance_m if max_distance_m is not None else 0.1 * span
    s, t = _downsample(src, voxel), _downsample(tgt, voxel)
    result = reg.registration_icp(
        s, t, dist, np.eye(4), reg.TransformationEstimationPointToPoint(), reg.ICPConvergenceCriteria(max_iteration=100)
    )
    return Similarity.from_matrix(np.asarray(result.transformation))
