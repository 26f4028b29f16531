"""Point-cloud helpers of the registration (open3d 0.20): conversion, checks, regions, normalisation, fitness.

All clouds are (n, 3) float64 metres in their own object or world frame unless a name says otherwise.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d

from tasks.arrays import BoolArray, FloatArray, IntArray, Points, check_points
from tasks.errors import TransferError
from tasks.transfer.similarity import Similarity

O3dCloud = o3d.geometry.PointCloud
reg = o3d.pipelines.registration

MIN_POINTS = 30
"""Fewer points than this in either model cannot be registered meaningfully."""


def to_cloud(points: Points) -> O3dCloud:
    """An open3d cloud of (n, 3) points (copied, float64)."""
    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64))
    return pcd


def cloud_points(pcd: O3dCloud) -> Points:
    """The (n, 3) points of an open3d cloud (a copy)."""
    out: Points = np.asarray(pcd.points, dtype=np.float64).copy()
    return out


def downsample(points: Points, voxel: float) -> O3dCloud:
    """Voxel-grid centroids of ``points`` (``voxel`` in the points' units)."""
    return to_cloud(points).voxel_down_sample(voxel)


def with_normals(pcd: O3dCloud, radius: float, max_nn: int = 30) -> O3dCloud:
    """``pcd`` with normals estimated from at most ``max_nn`` neighbours within ``radius`` (in place)."""
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=max_nn))
    return pcd


OUTWARD_NN = 20
"""Neighbours of each point in the outward normals' fit and orientation graph: a sampled surface's local plane
is fitted over a few rings of neighbours."""


def outward_normals(points: Points) -> Points:
    """(n, 3) unit normals of a closed model's points (metres), pointing out of the object: open3d's consistent
    tangent-plane orientation (Hoppe et al. 1992) over ``OUTWARD_NN`` neighbours, with the sign that points most
    of them away from the centroid."""
    pcd = to_cloud(points)
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(OUTWARD_NN))
    pcd.orient_normals_consistent_tangent_plane(OUTWARD_NN)
    normals: Points = np.asarray(pcd.normals, dtype=np.float64)
    if np.mean(np.sum((points - points.mean(axis=0)) * normals, axis=1) > 0.0) < 0.5:
        normals = -normals
    return normals


def even_indices(n: int, count: int) -> IntArray:
    """At most ``count`` indices into ``n`` items, at even steps through them (no random draw)."""
    out: IntArray = np.linspace(0, n - 1, min(n, count)).astype(np.int64)
    return out


def even_sample(points: Points, count: int) -> Points:
    """At most ``count`` of ``points`` picked at even steps through the array (``even_indices``)."""
    out: Points = points[even_indices(points.shape[0], count)]
    return out


def outward_sample(points: Points, count: int) -> tuple[Points, Points]:
    """An even sample of at most ``count`` of a closed model's ``points`` (metres) and their outward normals."""
    sample = even_sample(points, count)
    return sample, outward_normals(sample)


def median_spacing(points: Points) -> float:
    """Median nearest-neighbour distance of ``points`` (their units)."""
    return float(np.median(np.asarray(to_cloud(points).compute_nearest_neighbor_distance())))


def check_model(points: object, name: str) -> Points:
    """Validate a model cloud: (n, 3), finite rows kept, at least ``MIN_POINTS`` distinct points; a point listed
    again (a mesh's vertex repeated for each face it bounds) is kept once, in its first place: a cloud whose
    points come in pairs would have a median spacing of 0, and its surface normals no neighbourhood."""
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
    _, first = np.unique(pts, axis=0, return_index=True)
    if len(first) < pts.shape[0]:
        pts = pts[np.sort(first)]
        if pts.shape[0] < MIN_POINTS:
            msg = f"{name}: {pts.shape[0]} distinct points, need at least {MIN_POINTS}"
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


def normaliser(points: Points) -> Similarity:
    """Similarity taking ``points`` to centroid 0 and RMS radius 1."""
    centroid = points.mean(axis=0)
    radius = float(np.sqrt(((points - centroid) ** 2).sum(axis=1).mean()))
    return Similarity(1.0 / radius, np.eye(3), -centroid / radius)


def pca_frame(points: Points) -> FloatArray:
    """Principal axes (columns, largest variance first) of a centred cloud."""
    _, vecs = np.linalg.eigh(np.cov(points.T))
    out: FloatArray = vecs[:, ::-1]
    return out


def fitness(source: O3dCloud, target: O3dCloud, transform: Similarity, dist: float) -> tuple[float, float]:
    """(fitness, inlier RMSE) of ``transform(source)`` against ``target`` within ``dist``."""
    ev = reg.evaluate_registration(source, target, dist, transform.matrix())
    return float(ev.fitness), float(ev.inlier_rmse)


def similarity_icp(
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


def plain_icp(source: Points, target: Points, *, max_distance_m: float | None = None) -> Similarity:
    """The paper's baseline: rigid point-to-point ICP from the identity, no scale (metres)."""
    src = check_model(source, "source model")
    tgt = check_model(target, "target model")
    span = bbox_diagonal(tgt)
    voxel = span / 150.0
    dist = max_distance_m if max_distance_m is not None else 0.1 * span
    s, t = downsample(src, voxel), downsample(tgt, voxel)
    result = reg.registration_icp(
        s, t, dist, np.eye(4), reg.TransformationEstimationPointToPoint(), reg.ICPConvergenceCriteria(max_iteration=100)
    )
    return Similarity.from_matrix(np.asarray(result.transformation))
