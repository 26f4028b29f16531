"""Pairs of similar objects for the transfer benchmark, built with numpy alone (no code of ``tasks.transfer``).

Five families, each an object in its own frame (metres, z up, base on z = 0, front face towards -y) with its
functional axis and its grasped part:

- ``cabinet``: a box with a door slab on its front and a vertical bar handle on two posts near the free edge;
  the hinge is the door's other vertical front edge;
- ``microwave``: a box whose front holds a side-hinged door (proud of a control panel, 4 mm gap between them)
  with a vertical bar handle; the hinge is the door's outer front edge;
- ``drawer``: a chest with a drawer front (top third) and a horizontal bar handle; the axis is the pull (-y);
- ``lever``: a door leaf with a lever handle on a rose on both faces; the axis is the lever's spindle;
- ``bottle``: a bottle with a cap; the axis is the cap's (twist).

A pair is a demonstrated object (its dimensions drawn within the family's range; its full surface, 0.5 mm noise)
and a novel one: the same design stretched by 0.8-1.3 (one factor in half of the pairs, one per axis in the other
half; a bottle's radius and height), turned by any yaw and tilted by up to 20 degrees, scanned from one or two
views in front of it keeping 40-80 % of its surface, with 1-2 mm noise. The novel object's true axis is its own
geometric axis (its hinge edge, spindle, cap axis), carried into the scan's frame.

The objects are unions of boxes and cylinders sampled over every face, so a model holds the faces hidden inside
the object (a cabinet's front behind its door, a leaf's face under a lever's rose), and a scan keeps the
surface facing a view whether or not another part of the object stands in front of it (a door leaf's far lever).
``make_pair(..., occluded=True)`` leaves out what the object hides (``visible``): the demonstrated model keeps what
a camera sees from ``FULL_SCAN_VIEWS`` directions all round it, the novel object's scan what its own views see, as
depth cameras do; the objects, pose, views and noise levels are those of the same pair without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import open3d as o3d

from tests.transfer.shapes import Part, box, cylinder_side, sample_parts

FAMILIES = ("cabinet", "microwave", "drawer", "lever", "bottle")
SOURCE_NOISE_M = 5e-4
"""The demonstrated object's model: a careful full scan."""
POINTS = {"cabinet": 12_000, "microwave": 12_000, "drawer": 12_000, "lever": 20_000, "bottle": 6_000}
"""Surface samples of a full model per family (a door leaf is 3 m^2 of which the lever is 0.3 %)."""
GRAZING_COS = math.cos(math.radians(80.0))
"""A surface seen at more than 80 degrees from every view is not in the scan."""
CAMERA_DIAGONALS = 2.0
"""An occluded scan's camera stands two object diagonals from the object's centre along each view: the whole
object fits a field of view under 30 degrees."""
FLIP_RADII = 300.0
"""Hidden point removal's spherical flip radius, in camera distances (Katz, Tal and Basri 2007): a third of it
also hides the surface about a handle beyond the handle's shadow, three times it lets points 18 mm behind a door
through."""
FULL_SCAN_VIEWS = 32
"""A demonstrated object's full scan: views from 32 directions spread evenly over the sphere (a Fibonacci
lattice), about 40 degrees apart."""
OCCLUDER_SAMPLES = 5
"""The surface that hides is sampled five times as densely as the scan: hidden point removal judges points, not
surfaces, and lets points just behind a sparsely sampled surface through (a cabinet's front 18 mm behind its
door)."""


@dataclass(frozen=True)
class FamilyObject:
    """One object of a family: full surface (object frame) with its axis and grasped part."""

    family: str
    points: np.ndarray
    normals: np.ndarray
    axis_pos: np.ndarray
    axis_dir: np.ndarray
    kind: str
    """``rotation`` or ``translation``."""
    grip: np.ndarray
    """(3,) centre of the grasped part (handle, lever, cap)."""
    approach: np.ndarray
    """(3,) unit outward direction from which the hand comes to the grasped part."""


@dataclass(frozen=True)
class TransferPair:
    """A demonstrated object's model and a novel object's partial scan, with the novel object's true axis."""

    family: str
    seed: int
    source: FamilyObject
    target: np.ndarray
    """(m, 3) partial noisy scan of the novel object, metres, scan frame."""
    target_axis_pos: np.ndarray
    target_axis_dir: np.ndarray
    stretch: np.ndarray
    """(3,) per-axis size factors of the novel object against the demonstrated one (object frame)."""
    tilt_deg: float
    keep: float
    views: int
    noise_m: float
    rotation: np.ndarray
    """(3, 3) the novel object's turn from its own frame into the scan's (before the ``shift``)."""
    shift: np.ndarray
    """(3,) metres: scan frame = rotation @ (stretch * object frame) + shift."""
    occluded: bool = False
    """The model and the scan left out what the object hides from their views (``visible``)."""

    def scan_in_object_frame(self) -> np.ndarray:
        """(m, 3) the scan in the novel object's frame before its stretch, metres (the scan's noise included)."""
        out: np.ndarray = (self.target - self.shift) @ self.rotation / self.stretch
        return out


def _cylinder(radius: float, length: float, centre: np.ndarray, axis: int) -> list[Part]:
    """A closed cylinder about coordinate ``axis`` (side and both caps)."""
    c = np.asarray(centre, dtype=np.float64)
    u, v = [a for a in range(3) if a != axis]

    def side(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        phi = rng.uniform(0.0, 2.0 * np.pi, n)
        nrm = np.zeros((n, 3))
        nrm[:, u], nrm[:, v] = np.cos(phi), np.sin(phi)
        pts = c + radius * nrm
        pts[:, axis] += rng.uniform(-length / 2, length / 2, n)
        return pts, nrm

    out = [Part(2.0 * np.pi * radius * length, side)]
    for sign in (-1.0, 1.0):

        def cap(n: int, rng: np.random.Generator, sign: float = sign) -> tuple[np.ndarray, np.ndarray]:
            r = radius * np.sqrt(rng.random(n))
            phi = rng.uniform(0.0, 2.0 * np.pi, n)
            pts = np.tile(c, (n, 1))
            pts[:, u] += r * np.cos(phi)
            pts[:, v] += r * np.sin(phi)
            pts[:, axis] += sign * length / 2
            nrm = np.zeros((n, 3))
            nrm[:, axis] = sign
            return pts, nrm

        out.append(Part(np.pi * radius**2, cap))
    return out


def _bar_handle(centre: np.ndarray, length: float, along: int, standoff: float) -> list[Part]:
    """A bar of square section 16 mm along coordinate ``along``, ``standoff`` in front (-y) of its mount face,
    on two posts; ``centre`` is the bar's centre."""
    size = np.full(3, 0.016)
    size[along] = length
    patches = box(size, centre)
    for sign in (-1.0, 1.0):
        post = centre.copy()
        post[along] += sign * (length / 2 - 0.015)
        post[1] += standoff / 2
        patches += box(np.array([0.012, standoff, 0.012]), post)
    return patches


def cabinet(d: np.ndarray) -> tuple[list[Part], np.ndarray, np.ndarray, str, np.ndarray]:
    """Patches, axis point, axis direction, kind and grip of a cabinet of size ``d`` = (w, depth, h)."""
    w, depth, h = d
    door_t = 0.018
    front = -depth / 2 - door_t
    patches = box(d, np.array([0.0, 0.0, h / 2]))
    patches += box(np.array([w - 0.006, door_t, h - 0.006]), np.array([0.0, -depth / 2 - door_t / 2, h / 2]))
    grip = np.array([w / 2 - 0.05, front - 0.035, 0.55 * h])
    patches += _bar_handle(grip, 0.4 * h, 2, 0.035)
    return patches, np.array([-w / 2, front, h / 2]), np.array([0.0, 0.0, -1.0]), "rotation", grip


def microwave(d: np.ndarray) -> tuple[list[Part], np.ndarray, np.ndarray, str, np.ndarray]:
    """A microwave-like box of size ``d``: door on the left 70 % of the front, control panel beside it."""
    w, depth, h = d
    door_w, gap = 0.7 * w, 0.004
    door_t, panel_t = 0.022, 0.012
    front = -depth / 2 - door_t
    patches = box(d, np.array([0.0, 0.0, h / 2]))
    patches += box(
        np.array([door_w, door_t, h - 0.01]), np.array([-w / 2 + door_w / 2, -depth / 2 - door_t / 2, h / 2])
    )
    panel_w = w - door_w - gap
    patches += box(
        np.array([panel_w, panel_t, h - 0.01]), np.array([w / 2 - panel_w / 2, -depth / 2 - panel_t / 2, h / 2])
    )
    grip = np.array([-w / 2 + door_w - 0.035, front - 0.03, h / 2])
    patches += _bar_handle(grip, 0.6 * h, 2, 0.03)
    return patches, np.array([-w / 2, front, h / 2]), np.array([0.0, 0.0, -1.0]), "rotation", grip


def drawer(d: np.ndarray) -> tuple[list[Part], np.ndarray, np.ndarray, str, np.ndarray]:
    """A chest of size ``d`` with a drawer front on its top third and a horizontal bar handle."""
    w, depth, h = d
    front_t, front_h = 0.02, h / 3
    patches = box(d, np.array([0.0, 0.0, h / 2]))
    patches += box(
        np.array([w - 0.006, front_t, front_h - 0.006]), np.array([0.0, -depth / 2 - front_t / 2, h - front_h / 2])
    )
    grip = np.array([0.0, -depth / 2 - front_t - 0.03, h - front_h / 2])
    patches += _bar_handle(grip, 0.4 * w, 0, 0.03)
    return patches, grip, np.array([0.0, -1.0, 0.0]), "translation", grip


def lever(d: np.ndarray) -> tuple[list[Part], np.ndarray, np.ndarray, str, np.ndarray]:
    """A door leaf of size ``d`` = (w, thickness, h) with a lever on a rose on each face, 65 mm from the edge."""
    w, t, h = d
    patches = box(d, np.array([0.0, 0.0, h / 2]))
    spindle = np.array([w / 2 - 0.065, 0.0, 0.47 * h])
    for sign in (-1.0, 1.0):
        face = sign * t / 2
        patches += _cylinder(0.027, 0.01, spindle + np.array([0.0, face + sign * 0.005, 0.0]), 1)
        patches += _cylinder(0.009, 0.05, spindle + np.array([0.0, face + sign * 0.035, 0.0]), 1)
        patches += box(np.array([0.13, 0.014, 0.02]), spindle + np.array([-0.055, face + sign * 0.055, 0.0]))
    grip = spindle + np.array([-0.07, -t / 2 - 0.055, 0.0])
    return patches, spindle + np.array([0.0, -t / 2, 0.0]), np.array([0.0, -1.0, 0.0]), "rotation", grip


def bottle(d: np.ndarray) -> tuple[list[Part], np.ndarray, np.ndarray, str, np.ndarray]:
    """A bottle: ``d`` = (radius, radius, body height); shoulder, neck and a cap 20 mm tall."""
    r, _, body = d
    neck_r, cap_r = 0.37 * r, 0.45 * r
    shoulder, neck, cap = 0.25 * body, 0.12 * body, 0.12 * body
    z1, z2 = body + shoulder, body + shoulder + neck
    patches = [
        *_cylinder(r, body, np.array([0.0, 0.0, body / 2]), 2)[:2],  # side and bottom
        cylinder_side(r, body, z1, neck_r),
        cylinder_side(neck_r, z1, z2),
        *_cylinder(cap_r, cap, np.array([0.0, 0.0, z2 + cap / 2]), 2),
    ]
    return (
        patches,
        np.array([0.0, 0.0, z2 + cap]),
        np.array([0.0, 0.0, 1.0]),
        "rotation",
        np.array([0, 0, z2 + cap / 2]),
    )


BUILDERS = {"cabinet": cabinet, "microwave": microwave, "drawer": drawer, "lever": lever, "bottle": bottle}
SIZES = {
    "cabinet": ((0.3, 0.5), (0.3, 0.45), (0.5, 0.8)),
    "microwave": ((0.42, 0.55), (0.32, 0.42), (0.25, 0.33)),
    "drawer": ((0.4, 0.6), (0.35, 0.5), (0.3, 0.5)),
    "lever": ((0.7, 0.9), (0.035, 0.045), (1.9, 2.1)),
    "bottle": ((0.028, 0.04), (0.0, 0.0), (0.12, 0.2)),
}
"""Ranges of the demonstrated object's dimensions per family (metres)."""
APPROACH = {
    "cabinet": (0.0, -1.0, 0.0),
    "microwave": (0.0, -1.0, 0.0),
    "drawer": (0.0, -1.0, 0.0),
    "lever": (0.0, -1.0, 0.0),
    "bottle": (0.0, 0.0, 1.0),
}


def build(family: str, dims: np.ndarray, stretch: np.ndarray, n: int, rng: np.random.Generator) -> FamilyObject:
    """The object of ``family`` with dimensions ``dims`` stretched per axis by ``stretch`` (its whole geometry,
    handle included), ``n`` surface samples."""
    patches, pos, direction, kind, grip = BUILDERS[family](dims)
    points, normals = sample_parts(patches, n, rng)
    points = points * stretch
    normals = normals / stretch
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return FamilyObject(
        family, points, normals, pos * stretch, direction, kind, grip * stretch, np.array(APPROACH[family])
    )


def rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix of ``angle`` radians about unit ``axis`` (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * kx @ kx


def view_directions(family: str, views: int, rng: np.random.Generator) -> np.ndarray:
    """(views, 3) unit directions from the object towards the scanner (object frame): in front of it (the
    handle's side), from level to 45 degrees above; a bottle from any side."""
    out = []
    base = rng.uniform(0.0, 2.0 * np.pi) if family == "bottle" else -np.pi / 2 + rng.uniform(-1.0, 1.0)
    for k in range(views):
        azimuth = base + k * rng.uniform(0.5, 1.5) * (1 if rng.random() < 0.5 else -1)
        elevation = rng.uniform(0.0, math.radians(45.0))
        out.append(
            [math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation)]
        )
    return np.array(out)


def visible(points: np.ndarray, occluders: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(n,) bool: the ``points`` (n, 3, object frame, metres) a camera along any of the unit ``directions``
    (towards the camera) reaches before the object's surface, sampled by ``points`` and ``occluders`` (m, 3):
    open3d's hidden point removal from a camera ``CAMERA_DIAGONALS`` away from the points' centre."""
    centre = points.mean(axis=0)
    distance = CAMERA_DIAGONALS * float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.vstack([points, occluders])))
    out = np.zeros(len(points), dtype=bool)
    for direction in directions:
        _, index = cloud.hidden_point_removal(centre + distance * direction, FLIP_RADII * distance)
        index = np.asarray(index, dtype=np.intp)
        out[index[index < len(points)]] = True
    return out


def hiding_surface(family: str, seed: int, dims: np.ndarray, stretch: np.ndarray, n: int, *, stream: int) -> np.ndarray:
    """(``OCCLUDER_SAMPLES`` x n, 3) surface samples of the object (object frame, metres) that hide what lies behind
    them, drawn from a generator of their own (``stream``), so the pair's own draws stay as they are."""
    rng = np.random.default_rng([FAMILIES.index(family), seed, stream])
    return build(family, dims, stretch, OCCLUDER_SAMPLES * n, rng).points


def sphere_directions(count: int) -> np.ndarray:
    """(count, 3) unit directions spread evenly over the sphere (a Fibonacci lattice)."""
    k = np.arange(count) + 0.5
    z = 1.0 - 2.0 * k / count
    phi = math.pi * (3.0 - math.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def make_pair(family: str, seed: int, points: int | None = None, *, occluded: bool = False) -> TransferPair:
    """Pair number ``seed`` of ``family`` (deterministic); ``points``: surface samples of each full model instead
    of ``POINTS[family]`` (the random draws after the sampling then differ: another pair); ``occluded``: the model
    and the scan leave out what the object hides from their views (the same objects, pose and views)."""
    rng = np.random.default_rng([FAMILIES.index(family), seed])
    dims = np.array([rng.uniform(lo, hi) for lo, hi in SIZES[family]])
    if family == "bottle":
        dims[1] = dims[0]
    n = POINTS[family] if points is None else points
    source = build(family, dims, np.ones(3), n, rng)
    outer = np.ones(len(source.points), dtype=bool)
    if occluded:
        hiding = hiding_surface(family, seed, dims, np.ones(3), n, stream=2)
        outer = visible(source.points, hiding, sphere_directions(FULL_SCAN_VIEWS))
    source = FamilyObject(
        source.family,
        (source.points + rng.normal(scale=SOURCE_NOISE_M, size=source.points.shape))[outer],
        source.normals[outer],
        source.axis_pos,
        source.axis_dir,
        source.kind,
        source.grip,
        source.approach,
    )
    per_axis = bool(seed % 2)
    stretch = rng.uniform(0.8, 1.3, size=3) if per_axis else np.full(3, rng.uniform(0.8, 1.3))
    if family == "bottle":
        stretch[1] = stretch[0]
    novel = build(family, dims, stretch, n, rng)
    tilt_deg = float(rng.uniform(0.0, 20.0))
    tilt_axis = np.array([*rng.normal(size=2), 0.0])
    rot = rotation_about(np.array([0.0, 0.0, 1.0]), rng.uniform(0.0, 2.0 * np.pi))
    rot = rotation_about(tilt_axis, math.radians(tilt_deg)) @ rot
    shift = rng.uniform(-1.0, 1.0, size=3)
    keep = float(rng.uniform(0.4, 0.8))
    views = int(rng.integers(1, 3))
    directions = view_directions(family, views, rng)
    facing = (novel.normals @ directions.T).max(axis=1)
    order = np.lexsort((rng.random(len(facing)), -facing))  # most facing first, ties in random order
    seen = np.zeros(len(facing), dtype=bool)
    seen[order[: int(keep * len(facing))]] = True
    seen &= facing > GRAZING_COS
    if occluded:
        seen &= visible(novel.points, hiding_surface(family, seed, dims, stretch, n, stream=1), directions)
    keep = float(seen.mean())
    noise = float(rng.uniform(1e-3, 2e-3))
    scan = novel.points[seen] @ rot.T + shift + rng.normal(scale=noise, size=(int(seen.sum()), 3))
    return TransferPair(
        family,
        seed,
        source,
        scan,
        rot @ novel.axis_pos + shift,
        rot @ novel.axis_dir,
        stretch,
        tilt_deg,
        keep,
        views,
        noise,
        rot,
        shift,
        occluded,
    )
