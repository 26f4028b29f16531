"""Exact hold-test models of the benchmark's scenes and handles: the grasped part's collision shapes (boxes,
cylinders, spheres) as the free body and the shapes around it as its mount, each shape one convex piece (a cylinder
the 64-sided prism of ``part_cylinders.prism_vertices``, 0.03 mm from the true surface at 15 mm radius; a sphere a
400-vertex hull), so that the hold test shakes the object as it is rather than another point-cloud model of it
(``bench/grasp.py``)."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import Points, Vector3
from tasks.grasp.object_model import ObjectModel, estimate_normals, mounted_model, voxel_downsample
from tasks.grasp.part_cylinders import prism_vertices
from tasks.grasp.primitive_fit import PrimitiveShape
from tasks.scenes.surface import WorldShape, sample_shapes

SPHERE_VERTICES = 400
"""Vertices (a Fibonacci lattice) of the hull standing for a sphere."""
SURFACE_POINTS = 3000
"""Surface points of the part sampled for the model's centre and radius (the pieces are exact)."""


def primitive_model(points: Points, shape: PrimitiveShape) -> ObjectModel:
    """The exact box or cylinder ``shape`` as a hold test's model; its surface ``points`` (n, 3) world m give the
    centre and radius."""
    center = points.mean(axis=0)
    radius = float(np.linalg.norm(points - center, axis=1).max())
    return ObjectModel(points, np.zeros_like(points), center, radius, (), shape)


def labelled_model(part: Points, mount: Points, rng: np.random.Generator, *, viewpoint: Vector3) -> ObjectModel:
    """A model whose mount is known (a test object's sampled shapes): ``part`` and ``mount`` (n, 3) world m, each
    downsampled to 4 mm as the planner's model is, normals of the whole oriented away from ``viewpoint``, each cut
    into its own convex pieces (the part's first); centre and radius are the part's."""
    grip, face = voxel_downsample(part, 0.004), voxel_downsample(mount, 0.004)
    pts = np.concatenate([grip, face])
    is_mount = np.arange(len(pts)) >= len(grip)
    return mounted_model(pts, estimate_normals(pts, viewpoint=viewpoint), is_mount, rng, fit=False)


def hull_vertices(shape: WorldShape) -> Points:
    """Vertices (k, 3), world m, of the convex piece standing for ``shape``."""
    if shape.kind == "box":
        half = np.asarray(shape.size, dtype=np.float64) / 2.0
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
        local = corners * half
    elif shape.kind == "cylinder":  # the prism the planner plans a bar on (``part_cylinders.prism_vertices``)
        radius, length = shape.size
        local = prism_vertices(PrimitiveShape("cylinder", (radius, length / 2.0, 0.0), (0.0, 0.0, 0.0)))
    elif shape.kind == "sphere":
        i = np.arange(SPHERE_VERTICES) + 0.5
        polar = np.arccos(1.0 - 2.0 * i / SPHERE_VERTICES)
        azimuth = math.pi * (1.0 + math.sqrt(5.0)) * i
        local = shape.size[0] * np.column_stack(
            [np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)]
        )
    else:
        msg = f"shape kind {shape.kind!r} has no exact piece"
        raise ValueError(msg)
    out: Points = np.asarray(local @ shape.rotation.T + shape.translation, dtype=np.float64)
    return out


def distance_to(shape: WorldShape, point: np.ndarray) -> float:
    """Distance (m) from ``point`` (world) to the box bounding ``shape`` (exact for a box)."""
    local = shape.rotation.T @ (np.asarray(point, dtype=np.float64) - shape.translation)
    if shape.kind == "box":
        half = np.asarray(shape.size, dtype=np.float64) / 2.0
    elif shape.kind == "cylinder":
        half = np.array([shape.size[0], shape.size[0], shape.size[1] / 2.0])
    else:
        half = np.full(3, shape.size[0])
    return float(np.linalg.norm(np.maximum(np.abs(local) - half, 0.0)))


def exact_model(part: list[WorldShape], mount: list[WorldShape], rng: np.random.Generator) -> ObjectModel:
    """The model of ``part`` (the free body) on ``mount`` (static obstacles while the fingers close), every shape
    one exact convex piece; points are surface samples (the part's give centre and radius)."""
    grip = sample_shapes(part, SURFACE_POINTS, rng)
    face = sample_shapes(mount, SURFACE_POINTS, rng) if mount else np.zeros((0, 3))
    points = np.concatenate([grip, face])
    center = grip.mean(axis=0)
    radius = float(np.linalg.norm(grip - center, axis=1).max())
    pieces = tuple(hull_vertices(s) for s in part) + tuple(hull_vertices(s) for s in mount)
    is_mount = np.arange(len(points)) >= len(grip)
    return ObjectModel(
        points,
        np.zeros_like(points),
        center,
        radius,
        pieces,
        None,
        is_mount if mount else None,
        len(mount),
    )


def handle_shapes(
    radius: float, length: float, standoff: float, vertical: bool
) -> tuple[list[WorldShape], list[WorldShape]]:
    """The shapes of ``cases.grasp.handle_on_plate``'s handle: bar and two posts (the part), and its plate."""
    centre = np.array([0.5, 0.0, 0.5])
    axis_rot = Rotation.identity() if vertical else Rotation.from_euler("y", 90, degrees=True)
    bar = WorldShape("handle", "cylinder", (radius, length), axis_rot.as_matrix(), centre)
    post_rot = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    posts = [
        WorldShape(
            "handle",
            "cylinder",
            (0.006, standoff),
            post_rot,
            centre + axis_rot.apply([0, 0, s * (length / 2 - 0.01)]) + np.array([0, standoff / 2, 0]),
        )
        for s in (-1, 1)
    ]
    plate_half = [0.03 if vertical else length / 2 + 0.03, 0.005, length / 2 + 0.03 if vertical else 0.03]
    plate = WorldShape(
        "plate", "box", tuple(2.0 * h for h in plate_half), np.eye(3), centre + np.array([0, standoff + 0.005, 0])
    )
    return [bar, *posts], [plate]
