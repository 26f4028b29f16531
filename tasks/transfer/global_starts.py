"""Global starts of the registration: candidate similarities found without any initial guess.

In normalised space (both clouds at centroid 0 and RMS radius 1): the 24 rotations mapping principal axes onto
principal axes, FPFH + RANSAC and fast global registration (FGR), each refined by similarity ICP and scored by
the geometric mean of the two one-way fitnesses, so neither a shrunken source nor a partial target wins by
accident. Back in metres, only distinct candidates are kept, and the best get their half-turns about the
source's principal axes as siblings: near-symmetric objects (boxes, cylinders) hide their telling detail at the
coarse scale, and the fine stage judges the siblings.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import open3d as o3d

from tasks.arrays import FloatArray, Points
from tasks.transfer.clouds import (
    cloud_points,
    downsample,
    fitness,
    normaliser,
    pca_frame,
    reg,
    similarity_icp,
    with_normals,
)
from tasks.transfer.registration_types import RegistrationParams
from tasks.transfer.similarity import Similarity

COARSE_VOXEL = 0.09
"""Voxel of the global stage in normalised units (RMS radius 1): about 1 200 points on a bottle."""
FPFH_RADIUS = 5.0 * COARSE_VOXEL
NORMAL_RADIUS = 2.0 * COARSE_VOXEL

Candidate = tuple[str, Similarity]
"""A named start (``pca-<k>``, ``ransac-<k>``, ``fgr``, ``init``, ``<name>-flip<k>``) and its transform."""


def _extents(points: Points, axes: FloatArray) -> FloatArray:
    """Robust extents (1st to 99th percentile) of ``points`` along each column of ``axes``."""
    proj = points @ axes
    out: FloatArray = np.percentile(proj, 99.0, axis=0) - np.percentile(proj, 1.0, axis=0)
    return out


def pca_starts(src_n: Points, tgt_n: Points) -> list[Candidate]:
    """The 24 proper rotations mapping the source's principal axes onto the target's (normalised clouds).

    Each start's scale is the largest ratio of matched extents: a partial scan only ever shortens the target's
    extents, so the largest ratio is the one least affected by what the scan missed.
    """
    vs, vt = pca_frame(src_n), pca_frame(tgt_n)
    ext_s, ext_t = _extents(src_n, vs), _extents(tgt_n, vt)
    starts: list[Candidate] = []
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


@contextmanager
def single_threaded() -> Iterator[None]:
    """Open3d limited to one thread within the block (its previous limit restored after). Its RANSAC iterations
    run in parallel (oneAPI TBB, which ``OMP_NUM_THREADS`` does not bound) and draw from one seeded generator in
    whatever order the threads reach it, so a seed alone does not repeat a run: the same transfer was written in
    one process and refused as ambiguous in another (Open3D issue 7475)."""
    before = o3d.utility.get_max_threads()
    o3d.utility.set_max_threads(1)
    try:
        yield
    finally:
        o3d.utility.set_max_threads(before)


def _safe_similarity(matrix: FloatArray) -> Similarity:
    try:
        return Similarity.from_matrix(matrix)
    except ValueError:
        return Similarity.identity()


def scored_candidates(
    src_n: Points, tgt_n: Points, params: RegistrationParams, rng: np.random.Generator, init: Similarity | None
) -> list[tuple[float, str, Similarity]]:
    """Scored similarity candidates in normalised space, best first (score, start name, transform)."""
    src = with_normals(downsample(src_n, COARSE_VOXEL), NORMAL_RADIUS)
    tgt = with_normals(downsample(tgt_n, COARSE_VOXEL), NORMAL_RADIUS)
    starts = pca_starts(cloud_points(src), cloud_points(tgt))
    if init is not None:
        starts.insert(0, ("init", init))
    kd = o3d.geometry.KDTreeSearchParamHybrid(radius=FPFH_RADIUS, max_nn=100)
    f_src = reg.compute_fpfh_feature(src, kd)  # type: ignore[call-arg] # stub lists optional indices
    f_tgt = reg.compute_fpfh_feature(tgt, kd)  # type: ignore[call-arg] # stub lists optional indices
    checkers = [
        reg.CorrespondenceCheckerBasedOnEdgeLength(0.75),
        reg.CorrespondenceCheckerBasedOnDistance(3.0 * COARSE_VOXEL),
    ]
    with single_threaded():
        for k in range(params.ransac_runs):
            # Seeded right before each run: one seed for both runs left the second to start from whatever state
            # the first left the generator in.
            o3d.utility.random.seed(int(rng.integers(0, 2**31 - 1)))
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
        o3d.utility.random.seed(int(rng.integers(0, 2**31 - 1)))
        option = reg.FastGlobalRegistrationOption(maximum_correspondence_distance=1.5 * COARSE_VOXEL)
        fgr = reg.registration_fgr_based_on_feature_matching(src, tgt, f_src, f_tgt, option)
    starts.append(("fgr", _safe_similarity(np.asarray(fgr.transformation))))
    threshold = 1.5 * COARSE_VOXEL
    scored: list[tuple[float, str, Similarity]] = []
    for name, start in starts:
        fitted = similarity_icp(src, tgt, start, (3.0 * COARSE_VOXEL, threshold), 25)
        f_st, _ = fitness(src, tgt, fitted, threshold)
        f_ts, _ = fitness(tgt, src, fitted.inverse(), threshold / fitted.scale)
        scored.append((math.sqrt(f_st * f_ts), name, fitted))
    scored.sort(key=lambda row: -row[0])
    return scored


def distinct(a: Similarity, b: Similarity, span: float) -> bool:
    """True when two transforms differ by more than 5 degrees, 5 % of ``span`` or 5 % in scale."""
    cos = (np.trace(a.rotation.T @ b.rotation) - 1.0) / 2.0
    angle = math.degrees(math.acos(float(np.clip(cos, -1.0, 1.0))))
    shift = float(np.linalg.norm(a.translation - b.translation))
    return angle > 5.0 or shift > 0.05 * span or abs(math.log(a.scale / b.scale)) > 0.05


def global_starts(
    src: Points,
    tgt: Points,
    *,
    span_t: float,
    params: RegistrationParams,
    rng: np.random.Generator,
    init: Similarity | None,
) -> list[Candidate]:
    """Distinct candidate similarities source -> target (metres), best first, then the half-turn siblings.

    ``span_t``: the target's bounding-box diagonal (metres); ``init``: an optional extra start (metres)."""
    norm_s, norm_t = normaliser(src), normaliser(tgt)
    init_n = norm_t.compose(init.compose(norm_s.inverse())) if init is not None else None
    scored = scored_candidates(norm_s.apply_points(src), norm_t.apply_points(tgt), params, rng, init_n)

    # Back to metres: T = norm_t^-1 o X o norm_s; keep distinct candidates only.
    kept: list[Candidate] = []
    for _, name, fitted in scored:
        metric = norm_t.inverse().compose(fitted.compose(norm_s))
        if all(distinct(metric, other, span_t) for _, other in kept):
            kept.append((name, metric))
        if params.keep is not None and len(kept) >= params.keep:
            break

    centre_s = src.mean(axis=0)
    axes_s = pca_frame(src - centre_s)
    for name, metric in list(kept[: params.symmetry_candidates]):
        for k in range(3):
            flip = Similarity(1.0, 2.0 * np.outer(axes_s[:, k], axes_s[:, k]) - np.eye(3), np.zeros(3))
            about = Similarity(1.0, np.eye(3), centre_s).compose(flip.compose(Similarity(1.0, np.eye(3), -centre_s)))
            sibling = metric.compose(about)
            if all(distinct(sibling, other, span_t) for _, other in kept):
                kept.append((f"{name}-flip{k}", sibling))
    return kept
