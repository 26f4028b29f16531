"""The object to grasp, built from the descriptor's object model point cloud (metres, world frame).

Collision geometry: the cloud is split by k-means into compact clusters and each cluster becomes one convex
piece, the hull of its points and of the same points pushed 5 mm inwards along their normals (so a patch of a
flat face still has thickness). The pieces are the links of one pybullet body (fixed joints). Small convex
pieces keep concave shapes concave (the gap behind a door handle stays open), which one convex hull would fill,
and unlike a triangle mesh they also work for a free (dynamic) body in the shake test. Normals are the
PCA normals of the k nearest neighbours, oriented by propagation along a minimum spanning tree (Hoppe et al.;
open3d's tangent-plane orientation does the same but took 0.7 s on 1300 points
here, this 20 ms). A known primitive (box or cylinder) may be given instead for benchmarks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt
import pybullet as pb
from scipy.cluster.vq import kmeans2
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree
from scipy.spatial import ConvexHull, QhullError, cKDTree

from tasks.arrays import FloatArray, Points, Vector3
from tasks.errors import GraspError

MIN_POINTS = 30
"""Fewest object points a grasp is planned on."""
INWARD_OFFSET_M = 0.005
"""Thickness given to each surface patch of the point cloud, metres."""


@dataclass(frozen=True)
class PrimitiveShape:
    """A known shape in the world: ``kind`` box (``size`` = half extents, m) or cylinder (radius, half height,
    axis = local z); ``position`` (3,) m and ``quat_xyzw`` (4,) of its centre frame."""

    kind: Literal["box", "cylinder"]
    size: tuple[float, float, float]
    position: tuple[float, float, float]
    quat_xyzw: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class ObjectModel:
    """Object for planning: ``points`` (n, 3) m world, outward unit ``normals`` (n, 3), ``center`` (3,) m
    (centroid), ``radius`` m (largest distance of a point from the centre), convex ``parts`` (each (k, 3) m
    world) or a ``primitive``."""

    points: Points
    normals: Points
    center: Vector3
    radius: float
    parts: tuple[Points, ...] = ()
    primitive: PrimitiveShape | None = None
    tree: cKDTree = field(init=False, repr=False)
    lower: Vector3 = field(init=False, repr=False)
    upper: Vector3 = field(init=False, repr=False)

    def __post_init__(self) -> None:
        """Build the KD-tree over the points and the bounding box (m, world)."""
        object.__setattr__(self, "tree", cKDTree(self.points))
        object.__setattr__(self, "lower", self.points.min(axis=0))
        object.__setattr__(self, "upper", self.points.max(axis=0))


def check_object_points(points: object, name: str = "object_points") -> Points:
    """(n, 3) finite float64 object points or ``GraspError`` naming what is wrong."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        msg = f"{name}: expected shape (n, 3), got {arr.shape}"
        raise GraspError(msg)
    arr = arr[np.all(np.isfinite(arr), axis=1)]
    if len(arr) < MIN_POINTS:
        msg = f"{name}: {len(arr)} finite object points, need at least {MIN_POINTS}"
        raise GraspError(msg)
    return arr


def voxel_downsample(points: Points, voxel_m: float) -> Points:
    """Centroids of the occupied ``voxel_m`` cells (deterministic, sorted by cell)."""
    keys = np.floor(points / voxel_m).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, inverse, points)
    return sums / counts[:, None]


def estimate_normals(points: Points, k: int = 16) -> Points:
    """Outward unit normals (n, 3): PCA of the k nearest neighbours, signs propagated along a minimum spanning
    tree of the kNN graph (Hoppe et al. 1992) from the point farthest from the centroid, which faces outwards."""
    n = len(points)
    k = min(k, n)
    _, idx = cKDTree(points).query(points, k)
    nb = points[idx] - points[idx].mean(axis=1, keepdims=True)
    _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", nb, nb))
    normals = np.ascontiguousarray(vecs[:, :, 0])
    rows = np.repeat(np.arange(n), k - 1)
    cols = idx[:, 1:].reshape(-1)
    pairs = np.unique(np.sort(np.stack([rows, cols], axis=1), axis=1), axis=0)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    weights = 1.0 + 1e-6 - np.abs(np.einsum("ij,ij->i", normals[pairs[:, 0]], normals[pairs[:, 1]]))
    graph = coo_matrix((weights, (pairs[:, 0], pairs[:, 1])), shape=(n, n)).tocsr()
    tree = minimum_spanning_tree(graph)
    tree = tree + tree.T
    centroid = points.mean(axis=0)
    far = np.linalg.norm(points - centroid, axis=1)
    n_comp, comp = connected_components(tree, directed=False)
    for c in range(n_comp):
        members = np.flatnonzero(comp == c)
        root = int(members[np.argmax(far[members])])
        if float(normals[root] @ (points[root] - centroid)) < 0:
            normals[root] = -normals[root]
        order, pred = breadth_first_order(tree, root, directed=False, return_predecessors=True)
        for node in order[1:]:
            if float(normals[node] @ normals[pred[node]]) < 0:
                normals[node] = -normals[node]
    return np.asarray(normals, dtype=np.float64)


def convex_parts(
    points: Points, normals: Points, rng: np.random.Generator, points_per_part: int = 60
) -> tuple[Points, ...]:
    """Convex pieces (hull vertices, (k, 3) m) covering the cloud: k-means clusters thickened inwards."""
    n_parts = int(np.clip(len(points) // points_per_part, 1, 48))
    if n_parts == 1:
        labels = np.zeros(len(points), dtype=np.int64)
    else:
        _, labels = kmeans2(points, n_parts, minit="++", seed=rng)
    parts: list[Points] = []
    for label in np.unique(labels):
        sel = labels == label
        cloud = np.concatenate([points[sel], points[sel] - INWARD_OFFSET_M * normals[sel]])
        if len(cloud) < 4:
            continue
        try:
            hull = ConvexHull(cloud)
        except QhullError:
            try:
                hull = ConvexHull(cloud, qhull_options="QJ")
            except QhullError:
                continue
        parts.append(np.asarray(cloud[hull.vertices], dtype=np.float64))
    return tuple(parts)


def build_object_model(
    points: object,
    rng: np.random.Generator,
    *,
    voxel_m: float = 0.004,
    normals: Points | None = None,
    primitive: PrimitiveShape | None = None,
) -> ObjectModel:
    """Object model for planning from (n, 3) world points (m): downsampled, normals, convex parts or primitive."""
    pts = check_object_points(points)
    if normals is None:
        pts = voxel_downsample(pts, voxel_m)
        if len(pts) < MIN_POINTS:
            msg = f"object_points: {len(pts)} points after {voxel_m * 1000:.0f} mm voxels, need {MIN_POINTS}"
            raise GraspError(msg)
        nrm = estimate_normals(pts)
    else:
        nrm = np.asarray(normals, dtype=np.float64)
        if nrm.shape != pts.shape:
            msg = f"normals: expected shape {pts.shape}, got {nrm.shape}"
            raise GraspError(msg)
    center = pts.mean(axis=0)
    radius = float(np.linalg.norm(pts - center, axis=1).max())
    parts = () if primitive is not None else convex_parts(pts, nrm, rng)
    return ObjectModel(pts, nrm, center, radius, parts, primitive)


def crop_points(points: Points, center: Vector3, radius_m: float) -> Points:
    """Points within ``radius_m`` of ``center`` (world, metres)."""
    kept: Points = points[np.linalg.norm(points - center, axis=1) <= radius_m]
    return kept


def _hull_volume(vertices: Points) -> float:
    try:
        return float(ConvexHull(vertices).volume)
    except QhullError:
        return 0.0


def load_object(client_id: int, model: ObjectModel, *, mass_kg: float = 0.0, friction: float = 0.8) -> int:
    """Create the object in pybullet (static when ``mass_kg`` is 0); returns the body id. World frame."""
    if model.primitive is not None:
        prim = model.primitive
        if prim.kind == "box":
            shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(prim.size), physicsClientId=client_id)
        else:
            shape = pb.createCollisionShape(
                pb.GEOM_CYLINDER, radius=prim.size[0], height=2 * prim.size[1], physicsClientId=client_id
            )
        body = int(
            pb.createMultiBody(mass_kg, shape, -1, list(prim.position), list(prim.quat_xyzw), physicsClientId=client_id)
        )
    else:
        if not model.parts:
            msg = "object model has no collision parts"
            raise GraspError(msg)
        volumes = np.array([max(_hull_volume(p), 1e-9) for p in model.parts])
        masses = mass_kg * volumes / volumes.sum()
        shapes = []
        centres = []
        for part in model.parts:
            c = part.mean(axis=0)
            centres.append(c)
            shapes.append(
                pb.createCollisionShape(pb.GEOM_MESH, vertices=(part - c).tolist(), physicsClientId=client_id)
            )
        base_pos = model.center
        n = len(shapes)
        body = int(
            pb.createMultiBody(
                baseMass=float(masses[0]),
                baseCollisionShapeIndex=shapes[0],
                basePosition=(centres[0]).tolist(),
                linkMasses=[float(m) for m in masses[1:]],
                linkCollisionShapeIndices=shapes[1:],
                linkVisualShapeIndices=[-1] * (n - 1),
                linkPositions=[(c - centres[0]).tolist() for c in centres[1:]],
                linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * (n - 1),
                linkInertialFramePositions=[[0.0, 0.0, 0.0]] * (n - 1),
                linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * (n - 1),
                linkParentIndices=[0] * (n - 1),
                linkJointTypes=[pb.JOINT_FIXED] * (n - 1),
                linkJointAxis=[[0.0, 0.0, 1.0]] * (n - 1),
                physicsClientId=client_id,
            )
        )
        del base_pos
    for link in range(-1, pb.getNumJoints(body, physicsClientId=client_id)):
        pb.changeDynamics(body, link, lateralFriction=friction, physicsClientId=client_id)
    return body


def sample_box_surface(half: FloatArray, n: int, rng: np.random.Generator) -> tuple[Points, Points]:
    """``n`` points uniformly on a box surface (half extents, m, centred at the origin) and outward normals."""
    h = np.asarray(half, dtype=np.float64)
    areas = np.array([h[1] * h[2], h[1] * h[2], h[0] * h[2], h[0] * h[2], h[0] * h[1], h[0] * h[1]])
    face = rng.choice(6, size=n, p=areas / areas.sum())
    pts = rng.uniform(-h, h, size=(n, 3))
    nrm = np.zeros((n, 3))
    axis = face // 2
    sign = np.where(face % 2 == 0, 1.0, -1.0)
    pts[np.arange(n), axis] = sign * h[axis]
    nrm[np.arange(n), axis] = sign
    return pts, nrm


def sample_cylinder_surface(
    radius: float, half_height: float, n: int, rng: np.random.Generator
) -> tuple[Points, Points]:
    """``n`` points on a closed cylinder (axis z, centred at the origin) and outward normals."""
    side = 2 * math.pi * radius * 2 * half_height
    cap = math.pi * radius**2
    kind = rng.choice(3, size=n, p=np.array([side, cap, cap]) / (side + 2 * cap))
    theta = rng.uniform(0, 2 * math.pi, n)
    r = np.where(kind == 0, radius, radius * np.sqrt(rng.uniform(0, 1, n)))
    z = np.where(kind == 0, rng.uniform(-half_height, half_height, n), np.where(kind == 1, half_height, -half_height))
    pts = np.stack([r * np.cos(theta), r * np.sin(theta), z], axis=1)
    nrm = np.where(
        (kind == 0)[:, None],
        np.stack([np.cos(theta), np.sin(theta), np.zeros(n)], axis=1),
        np.stack([np.zeros(n), np.zeros(n), np.where(kind == 1, 1.0, -1.0)], axis=1),
    )
    return pts, nrm


def transform_points(points: Points, rot: FloatArray, trans: npt.ArrayLike) -> Points:
    """``rot @ p + trans`` for each row of (n, 3) ``points``."""
    out: Points = np.asarray(points @ rot.T + np.asarray(trans, dtype=np.float64), dtype=np.float64)
    return out
