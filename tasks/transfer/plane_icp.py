"""Point-to-plane ICP that estimates scale as well (a similarity), for the final refinement.

open3d's ``TransformationEstimationPointToPoint(with_scaling=True)`` estimates scale, but point-to-point
residuals on sparse samples bias the scale (a source point is pulled to the nearest target *sample*, not to
the surface); open3d's point-to-plane estimator has no scale. This solves the linearised point-to-plane
problem with 7 unknowns (small rotation w, translation t, relative scale change sigma) per iteration:

    n_i . ((1 + sigma) R(w) (p_i - c) + c + t - q_i) = 0

with p_i the current source points, q_i their nearest target points (within ``max_distance_m``), n_i the
target normals and c the centroid of the matched source points. Huber weights damp the outliers.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from tasks.arrays import FloatArray, Points
from tasks.transfer.similarity import Similarity

NORMAL_AGREEMENT_DEG = 25.0
"""Paired normals closer than this count as agreeing (normals are unsigned)."""
MAX_SCALE_STEP = 0.1
"""Largest relative scale change per iteration (keeps a bad start from flipping the scale's sign)."""


def _rotation_from_vector(w: np.ndarray) -> np.ndarray:
    """Rodrigues' formula: rotation of angle |w| about w/|w|."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-15:
        return np.eye(3)
    k = w / angle
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    out: np.ndarray = np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)
    return out


def plane_similarity_icp(
    source: Points,
    target: Points,
    target_normals: Points,
    init: Similarity,
    max_distance_m: float,
    *,
    iterations: int = 30,
    with_scale: bool = True,
    min_matches: int = 12,
    weights: FloatArray | None = None,
    tree: cKDTree | None = None,
) -> Similarity:
    """Refine ``init`` (source -> target, metres) by point-to-plane ICP with scale; ``init`` when it cannot.

    ``weights``: (n,) per source point (default 1), multiplied into the Huber weights; ``tree``: a KD-tree of
    ``target`` (built here when None; a dense scan's tree costs more than an ICP run, so callers refining many
    starts pass one)."""
    tree = cKDTree(target) if tree is None else tree
    current = init
    huber = max_distance_m / 3.0
    for _ in range(iterations):
        moved = current.apply_points(source)
        dist, idx = tree.query(moved, distance_upper_bound=max_distance_m)
        ok = np.isfinite(dist)
        if int(ok.sum()) < min_matches:
            return current
        p, q, n = moved[ok], target[idx[ok]], target_normals[idx[ok]]
        prior = weights[ok] if weights is not None else np.ones(len(p))
        centre = (p * prior[:, None]).sum(axis=0) / prior.sum()
        pc = p - centre
        residual = np.einsum("ij,ij->i", n, q - p)
        cols = [np.cross(pc, n), n]
        if with_scale:
            cols.append(np.einsum("ij,ij->i", n, pc)[:, None])
        a = np.hstack(cols)
        w = prior * np.minimum(1.0, huber / np.maximum(np.abs(residual), 1e-12))
        aw = a * w[:, None]
        try:
            x = np.linalg.solve(aw.T @ a + 1e-12 * np.eye(a.shape[1]), aw.T @ residual)
        except np.linalg.LinAlgError:
            return current
        sigma = float(np.clip(x[6], -MAX_SCALE_STEP, MAX_SCALE_STEP)) if with_scale else 0.0
        rot = _rotation_from_vector(x[:3])
        # delta(y) = c + (1 + sigma) R (y - c) + t
        delta = Similarity(1.0 + sigma, rot, centre + x[3:6] - (1.0 + sigma) * rot @ centre)
        current = delta.compose(current)
        if np.linalg.norm(x[:3]) < 1e-7 and np.linalg.norm(x[3:6]) < 1e-8 and abs(sigma) < 1e-7:
            break
    return current


def plane_residuals(
    source: Points,
    source_normals: Points,
    target: Points,
    target_normals: Points,
    transform: Similarity,
    *,
    max_distance_m: float,
) -> tuple[float, float]:
    """After ``transform``: (RMS point-to-plane distance of the pairs within ``max_distance_m``, metres;
    fraction of those pairs whose normals agree within ``NORMAL_AGREEMENT_DEG``); (inf, 0) without pairs."""
    moved = transform.apply_points(source)
    dist, idx = cKDTree(target).query(moved, distance_upper_bound=max_distance_m)
    ok = np.isfinite(dist)
    if not ok.any():
        return float("inf"), 0.0
    t_normals = target_normals[idx[ok]]
    resid = np.einsum("ij,ij->i", t_normals, moved[ok] - target[idx[ok]])
    turned = source_normals[ok] @ transform.rotation.T
    agree = np.abs(np.einsum("ij,ij->i", turned, t_normals)) >= np.cos(np.radians(NORMAL_AGREEMENT_DEG))
    return float(np.sqrt(np.mean(resid**2))), float(agree.mean())
