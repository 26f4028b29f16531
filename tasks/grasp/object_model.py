"""The object to grasp, built from the descriptor's object model point cloud (metres, world frame).

Collision geometry: the cloud is split by k-means into compact clusters, each one convex piece: the hull of its points
and of the same points pushed 5 mm inwards along their normals (a patch of a flat face keeps thickness), the links of
one pybullet body. Small convex pieces keep concave shapes concave (the gap behind a door handle stays open), and
unlike a triangle mesh they work for a free body in the shake test. A fitted box or cylinder, or a bar's cylinder beside
the pieces of the rest, replaces them where it explains the points (``build_object_model``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pybullet as pb
from scipy.cluster.vq import kmeans2
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree
from scipy.spatial import ConvexHull, QhullError, cKDTree

from tasks.arrays import BoolArray, Points, Vector3
from tasks.errors import GraspError
from tasks.grasp.mount import find_cap, find_mount
from tasks.grasp.part_cylinders import find_cylinder, prism_vertices
from tasks.grasp.primitive_fit import MIN_POINTS, TOLERANCE_M, PrimitiveShape, fit_primitive, surface_distance, within

INWARD_OFFSET_M = 0.005
"""Thickness given to each surface patch of the point cloud, metres."""
COHERENT_COS = math.cos(math.radians(50.0))
"""A convex piece's normals stay within 50° of their mean (else its cluster is split)."""
NORMAL_FEATURE_M = 0.02
"""Weight of the normal in the split's k-means features, metres (a normal flip counts as 40 mm apart)."""
LOCAL_RADIUS_M = 0.015
CONVEX_BULGE_M = 0.0012
"""A point hidden from the viewpoint whose neighbours within 15 mm lie behind it by a median of over 1.2 mm along
its normal lies on a convex patch (the back of a bar): its normal is turned away from them. The median, not the
centroid: beside a post standing on a face most neighbours lie in the face."""
OUTSIDE_RESULTANT = 0.3
"""The viewpoint counts as outside the object when the mean of the unit directions to the points is at least
this long (a palm buried in the object has points all around it: then it is ignored)."""
MIN_PIECE_POINTS = 6
"""Fewest points of a piece made by a split."""

CAP_MARGIN_M = 0.003
"""Scan points within this of a cap's cylinder are the cap's (its 4 mm voxels' centroids lie up to 2 mm inside)."""
GROUP_SPACINGS = 3.0
"""Points within this many median point spacings of each other belong to one group (``solid_pieces``)."""


@dataclass(frozen=True, eq=False)
class ObjectModel:
    """Object for planning: ``points`` (n, 3) m world, outward unit ``normals`` (n, 3), ``center`` (3,) m
    (centroid of the part), ``radius`` m (largest distance of a part point from the centre), convex ``parts``
    (each (k, 3) m world) or a ``primitive``. ``mount`` (n,), when known (found by ``tasks.grasp.mount`` when
    ``build_object_model`` is given the approach, or given to ``mounted_model``), marks the points of the face
    the part stands on (a handle's plate, a lever's door leaf) and all behind it: an obstacle to the closing
    fingers, not part of the free body when shaken or settled; its pieces are the last ``mount_parts`` of
    ``parts``."""

    points: Points
    normals: Points
    center: Vector3
    radius: float
    parts: tuple[Points, ...] = ()
    primitive: PrimitiveShape | None = None
    mount: BoolArray | None = None
    mount_parts: int = 0
    cylinder: PrimitiveShape | None = None
    """The exact cylinder of a mounted part, its first piece, if any: a bar (``part_cylinders``) or a cap."""

    tree: cKDTree = field(init=False, repr=False)
    lower: Vector3 = field(init=False, repr=False)
    upper: Vector3 = field(init=False, repr=False)

    def __post_init__(self) -> None:
        """Build the KD-tree over the points and the bounding box (m, world)."""
        object.__setattr__(self, "tree", cKDTree(self.points))
        object.__setattr__(self, "lower", self.points.min(axis=0))
        object.__setattr__(self, "upper", self.points.max(axis=0))

    def is_mount_piece(self, piece: npt.NDArray[np.int64]) -> BoolArray:
        """(m,) whether each convex piece index (into ``parts``) belongs to the mount."""
        out: BoolArray = (np.asarray(piece) >= len(self.parts) - self.mount_parts) & (self.mount_parts > 0)
        return out

    def without_mount(self) -> ObjectModel:
        """The part alone (its points, normals and pieces), or this model when it has no mount."""
        if self.mount is None or not self.mount_parts:
            return self
        keep = ~self.mount
        parts = self.parts[: len(self.parts) - self.mount_parts]
        return ObjectModel(
            self.points[keep], self.normals[keep], self.center, self.radius, parts, cylinder=self.cylinder
        )


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


def visible_from(points: Points, viewpoint: Vector3, clearance_m: float = 0.0045, near_m: float = 0.008) -> BoolArray:
    """(n,) whether each point is seen from ``viewpoint`` (world, m): no other point within ``clearance_m`` of the
    line of sight (sampled every 1.5 mm up to ``near_m`` before the point; 4.5 mm: a scan of 4 mm spacing has no
    holes that wide)."""
    view = np.asarray(viewpoint, dtype=np.float64)
    rel = points - view
    dist = np.linalg.norm(rel, axis=1)
    unit = rel / np.maximum(dist, 1e-12)[:, None]
    steps = np.arange(0.0, max(float(dist.max()) - near_m, 0.0), 0.0015)
    if len(steps) == 0:
        return np.ones(len(points), dtype=bool)
    samples = view + steps[None, :, None] * unit[:, None, :]
    valid = steps[None, :] < (dist - near_m)[:, None]
    hit_dist, _ = cKDTree(points).query(samples[valid], k=1, distance_upper_bound=clearance_m)
    blocked = np.zeros(valid.shape, dtype=bool)
    blocked[valid] = np.isfinite(hit_dist)
    out: BoolArray = np.logical_not(blocked.any(axis=1))
    return out


def estimate_normals(points: Points, k: int = 16, viewpoint: Vector3 | None = None) -> Points:
    """Outward unit normals (n, 3): PCA of the k nearest neighbours, signs propagated along a minimum spanning
    tree of the kNN graph (Hoppe et al. 1992). With ``viewpoint`` (world, m; a place outside the object such as
    the demonstrated palm, from where a digitizer saw it), the points seen from it whose normals face it clearly
    (|cos| > 0.5) are the roots, their normals turned towards it, and the rest follow along the tree from them:
    a single root would flip every normal behind a wrong one. Without, or for parts the roots do not reach,
    the root is the point farthest from the centroid."""
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
    roots = np.zeros(0, dtype=np.int64)
    view = None if viewpoint is None else np.asarray(viewpoint, dtype=np.float64)
    to_view = np.zeros_like(points) if view is None else view - points
    to_view /= np.maximum(np.linalg.norm(to_view, axis=1, keepdims=True), 1e-12)
    if view is not None and float(np.linalg.norm(to_view.mean(axis=0))) >= OUTSIDE_RESULTANT:
        facing = np.einsum("ij,ij->i", normals, to_view)
        seen = visible_from(points, view)
        seen_roots = np.flatnonzero(seen & (np.abs(facing) > 0.5))
        normals[seen_roots] *= np.sign(facing[seen_roots])[:, None]
        # hidden points on a convex patch (the back of a bar) face away from most of their neighbours
        local = cKDTree(points).query_ball_point(points, LOCAL_RADIUS_M, return_sorted=False)
        bulge = np.array([float(np.median((points[i] - points[nb]) @ normals[i])) for i, nb in enumerate(local)])
        hidden_roots = np.flatnonzero(~seen & (np.abs(bulge) > CONVEX_BULGE_M))
        normals[hidden_roots] *= np.sign(bulge[hidden_roots])[:, None]
        roots = np.concatenate([seen_roots, hidden_roots])
    # node n is a virtual root joined to every seen point (tiny weight: csgraph drops zero-weight edges)
    pairs = np.concatenate([pairs, np.stack([roots, np.full(len(roots), n)], axis=1)])
    weights = np.concatenate([weights, np.full(len(roots), 1e-9)])
    graph = coo_matrix((weights, (pairs[:, 0], pairs[:, 1])), shape=(n + 1, n + 1)).tocsr()
    tree = minimum_spanning_tree(graph)
    tree = tree + tree.T
    centroid = points.mean(axis=0)
    far = np.linalg.norm(points - centroid, axis=1)
    n_comp, comp = connected_components(tree, directed=False)
    for c in range(n_comp):
        members = np.flatnonzero(comp == c)
        if comp[n] == c:
            root = n
        else:
            root = int(members[np.argmax(far[members])])
            if float(normals[root] @ (points[root] - centroid)) < 0:
                normals[root] = -normals[root]
        order, pred = breadth_first_order(tree, root, directed=False, return_predecessors=True)
        for node in order[1:]:
            parent = pred[node]
            if n in {parent, node}:
                continue
            if float(normals[node] @ normals[parent]) < 0:
                normals[node] = -normals[node]
    return np.asarray(normals, dtype=np.float64)


def _coherent(
    members: npt.NDArray[np.int64], points: Points, normals: Points, rng: np.random.Generator, depth: int = 0
) -> list[npt.NDArray[np.int64]]:
    """Split a cluster (indices) in two (k-means on position and normal) until its normals lie within
    ``COHERENT_COS`` of their mean: the hull of a cluster that holds a face and a post standing on it fills the
    space between them (a door's face bulged 6 mm towards the hand next to its lever)."""
    if len(members) < 2 * MIN_PIECE_POINTS or depth >= 4:
        return [members]
    mean = normals[members].sum(axis=0)
    norm = float(np.linalg.norm(mean))
    if norm > 1e-9 and float(np.min(normals[members] @ (mean / norm))) >= COHERENT_COS:
        return [members]
    features = np.concatenate([points[members], NORMAL_FEATURE_M * normals[members]], axis=1)
    _, labels = kmeans2(features, 2, minit="++", seed=rng)
    halves = [members[labels == k] for k in (0, 1)]
    if min(len(h) for h in halves) < MIN_PIECE_POINTS:
        return [members]
    return [piece for half in halves for piece in _coherent(half, points, normals, rng, depth + 1)]


def convex_parts(
    points: Points, normals: Points, rng: np.random.Generator, points_per_part: int = 60
) -> tuple[Points, ...]:
    """Convex pieces (hull vertices, (k, 3) m) covering the cloud: k-means clusters thickened inwards."""
    n_parts = int(np.clip(len(points) // points_per_part, 1, 48))
    if n_parts == 1:
        labels = np.zeros(len(points), dtype=np.int64)
    else:
        _, labels = kmeans2(points, n_parts, minit="++", seed=rng)
    clusters: list[npt.NDArray[np.int64]] = []
    for label in np.unique(labels):
        clusters += _coherent(np.flatnonzero(labels == label), points, normals, rng)
    pieces = (_thickened_hull(points[sel], normals[sel]) for sel in clusters)
    return tuple(piece for piece in pieces if piece is not None)


def _thickened_hull(points: Points, normals: Points) -> Points | None:
    """Hull vertices (k, 3) m, world, of ``points`` and their copies ``INWARD_OFFSET_M`` in along the outward
    ``normals`` (joggled by qhull when flat); None for fewer than four or a hull qhull cannot make."""
    cloud = np.concatenate([points, points - INWARD_OFFSET_M * normals])
    if len(cloud) < 4:
        return None
    try:
        hull = ConvexHull(cloud)
    except QhullError:
        try:
            hull = ConvexHull(cloud, qhull_options="QJ")
        except QhullError:
            return None
    return np.asarray(cloud[hull.vertices], dtype=np.float64)


def build_object_model(
    points: object,
    rng: np.random.Generator,
    *,
    voxel_m: float = 0.004,
    viewpoint: Vector3 | None = None,
    approach: Vector3 | None = None,
    fit: bool = True,
) -> ObjectModel:
    """Object model for planning from (n, 3) world points (m): downsampled, normals (oriented away from
    ``viewpoint``, a place outside the object, when given), convex parts or primitive. With ``approach`` too (a
    unit vector, world: the demonstrated palm's +z), a cap the palm looks down on (``mount.find_cap``, on the
    points as given: a bottle's cap, a knob) is the part, one exact piece (``ObjectModel.cylinder``), and all
    beyond it (a neck and body, a stem and plate) the mount; else the mount the part stands on is looked for
    (``mount.find_mount``) and, when found, kept apart (``ObjectModel.mount``). Without a mount and with
    ``fit``, a box or cylinder whose surface explains the points (``tasks.grasp.primitive_fit``: a carton, a
    bottle, a can) becomes the model's ``primitive`` instead of convex pieces, as GraspIt plans on shape primitives
    (Miller et al. 2003): the pieces' edges and seams fall differently with each k-means draw, and a fingertip that
    catches on a seam holds in the planner's check where the real smooth surface lets it slide."""
    scan = check_object_points(points)
    pts = voxel_downsample(scan, voxel_m)
    if len(pts) < MIN_POINTS:
        msg = f"object_points: {len(pts)} points after {voxel_m * 1000:.0f} mm voxels, need {MIN_POINTS}"
        raise GraspError(msg)
    nrm = estimate_normals(pts, viewpoint=viewpoint)
    if approach is not None and viewpoint is not None:
        cap = find_cap(scan, viewpoint, approach)
        on_cap = np.zeros(len(pts), dtype=bool) if cap is None else within(cap, pts, CAP_MARGIN_M)
        if MIN_POINTS <= int(on_cap.sum()) < len(pts):  # a cap, and something beyond it
            return mounted_model(pts, nrm, ~on_cap, rng, cylinder=cap)
        mount = find_mount(pts, viewpoint, approach)
        if mount.any() and int((~mount).sum()) >= MIN_POINTS:
            return mounted_model(pts, nrm, mount, rng, fit=fit)
    center, radius = _centre_and_radius(pts)
    fitted = fit_primitive(pts, nrm) if fit else None
    if fitted is not None:
        return ObjectModel(pts, nrm, center, radius, (), fitted.shape)
    return ObjectModel(pts, nrm, center, radius, convex_parts(pts, nrm, rng))


def _centre_and_radius(points: Points) -> tuple[Vector3, float]:
    """The centroid (3,) m of ``points`` and their largest distance (m) from it."""
    center = points.mean(axis=0)
    return center, float(np.linalg.norm(points - center, axis=1).max())


def mounted_model(
    points: Points,
    normals: Points,
    mount: BoolArray,
    rng: np.random.Generator,
    *,
    fit: bool = True,
    cylinder: PrimitiveShape | None = None,
) -> ObjectModel:
    """A model with a mount: the part's pieces then the mount's convex pieces; the part's centre and radius. The
    part is the prism of a known ``cylinder`` (a cap: the scan's points are voxel centroids, up to 2 mm inside its
    rim and top) when given; else, with ``fit``, a cylinder explaining much of it (a bar, a lever's arm:
    ``part_cylinders.find_cylinder``) is one exact piece and the rest of the part convex pieces; else its convex
    pieces."""
    grip, grip_normals = points[~mount], normals[~mount]
    if cylinder is not None:
        pieces: tuple[Points, ...] = (prism_vertices(cylinder),)
    elif fit:
        cylinder, pieces = _part_pieces(grip, grip_normals, rng)
    else:
        pieces = convex_parts(grip, grip_normals, rng)
    mount_pieces = convex_parts(points[mount], normals[mount], rng)
    center, radius = _centre_and_radius(grip)
    parts = pieces + mount_pieces
    return ObjectModel(points, normals, center, radius, parts, None, mount, len(mount_pieces), cylinder)


def _part_pieces(
    points: Points, normals: Points, rng: np.random.Generator
) -> tuple[PrimitiveShape | None, tuple[Points, ...]]:
    """The cylinder found in a part (``part_cylinders``), if any, and the part's pieces: its prism first, then the
    convex pieces of the points it leaves unexplained."""

    found = find_cylinder(points, normals, rng)
    if found is None:
        return None, convex_parts(points, normals, rng)
    rest = surface_distance(found.shape, points) > TOLERANCE_M
    others = solid_pieces(points[rest], normals[rest], rng) if rest.sum() >= MIN_PIECE_POINTS else ()
    return found.shape, (prism_vertices(found.shape), *others)


def solid_pieces(points: Points, normals: Points, rng: np.random.Generator) -> tuple[Points, ...]:
    """Convex pieces (hull vertices, (k, 3) m, world) of the points of a mounted part its bar leaves unexplained
    (``_part_pieces``): per connected group (``GROUP_SPACINGS``), the group's hull thickened inwards as one solid
    piece when its points lie on that hull (``_on_hull``: a handle's post), else its k-means pieces
    (``convex_parts``: a lever's rose and neck). A scan sees a post's faces, not its inside: cut into k-means
    patches, each 5 mm thick, a post would weigh half its volume in the hold check. Groups of fewer than
    ``MIN_PIECE_POINTS`` points are left out."""
    tree = cKDTree(points)
    spacing = float(np.median(tree.query(points, k=2)[0][:, 1]))
    pairs = tree.query_pairs(GROUP_SPACINGS * spacing, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points), len(points)))
    _, labels = connected_components(graph, directed=False)
    pieces: list[Points] = []
    for label in np.unique(labels):
        group = np.flatnonzero(labels == label)
        if len(group) < MIN_PIECE_POINTS:
            continue
        solid = _thickened_hull(points[group], normals[group]) if _on_hull(points[group]) else None
        pieces += [solid] if solid is not None else convex_parts(points[group], normals[group], rng)
    return tuple(pieces)


def _on_hull(points: Points) -> bool:
    """Whether 95 % of ``points`` (m) lie within ``primitive_fit.TOLERANCE_M`` (the tolerance a box or cylinder is
    fitted to) of the boundary of their convex hull: False for a flat or degenerate set."""

    try:
        hull = ConvexHull(points)
    except QhullError:
        return False
    depth = -np.max(points @ hull.equations[:, :3].T + hull.equations[:, 3], axis=1)
    return float(np.percentile(depth, 95)) <= TOLERANCE_M


def _hull_volume(vertices: Points) -> float:
    try:
        return float(ConvexHull(vertices).volume)
    except QhullError:
        return 0.0


def load_object(client_id: int, model: ObjectModel, *, mass_kg: float = 0.0, friction: float = 0.8) -> int:
    """Create the object in pybullet (static when ``mass_kg`` is 0); returns the body id. World frame. A model's
    ``cylinder`` is Bullet's round cylinder, its prism only weighing it: a prism's flats seat a fingertip's flat pad and
    hold a roll that the round bar lets go, or not, as the arbitrary phase of its 64 facets falls."""
    prim = model.primitive
    if prim is not None:
        size = {"halfExtents": list(prim.size)} if prim.kind == "box" else {"radius": prim.size[0]}
        kind = pb.GEOM_BOX if prim.kind == "box" else pb.GEOM_CYLINDER
        shape = pb.createCollisionShape(kind, height=2 * prim.size[1], physicsClientId=client_id, **size)
        body = pb.createMultiBody(
            mass_kg, shape, -1, list(prim.position), list(prim.quat_xyzw), physicsClientId=client_id
        )
    elif not model.parts:
        msg = "object model has no collision parts"
        raise GraspError(msg)
    else:
        masses = np.zeros(len(model.parts))  # static: no hulls to compute (most loads in a plan are)
        if mass_kg > 0.0:  # the mass spread over the pieces by their hull volumes
            volumes = np.array([max(_hull_volume(p), 1e-9) for p in model.parts])
            masses = mass_kg * volumes / volumes.sum()
        centres = [part.mean(axis=0) for part in model.parts]
        shapes = []
        if (bar := model.cylinder) is not None:  # the first part, the bar or cap, collides round, not as its prism
            shapes.append(
                pb.createCollisionShape(
                    pb.GEOM_CYLINDER,
                    radius=bar.size[0],
                    height=2.0 * bar.size[1],
                    collisionFramePosition=(np.asarray(bar.position) - centres[0]).tolist(),
                    collisionFrameOrientation=list(bar.quat_xyzw),
                    physicsClientId=client_id,
                )
            )
        shapes += [
            pb.createCollisionShape(pb.GEOM_MESH, vertices=(part - c).tolist(), physicsClientId=client_id)
            for part, c in zip(model.parts[len(shapes) :], centres[len(shapes) :], strict=True)
        ]
        n = len(shapes)
        body = pb.createMultiBody(
            baseMass=float(masses[0]),
            baseCollisionShapeIndex=shapes[0],
            basePosition=centres[0].tolist(),
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
    for link in range(-1, pb.getNumJoints(body, physicsClientId=client_id)):
        pb.changeDynamics(body, link, lateralFriction=friction, physicsClientId=client_id)
    return int(body)
