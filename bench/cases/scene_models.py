"""Object models of the built-in scenes (``tasks.scenes``) for the transfer benchmark and tests.

A scene instance's model is what the digitizer of a ``pbd synth`` recording scans
(``tasks.scenes.surface.sample_object_model``: world frame at the demonstration's start, metres), with its true
chain and grasp (``tasks.scenes.kinematics.truth_descriptor``) and outward normals for partial scans.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from schemas.descriptor import Descriptor
from tasks.arrays import Points
from tasks.rotations import matrix_from_quat
from tasks.transfer.carry import focus_points, grip_points
from tasks.transfer.similarity import Similarity

NORMAL_NEIGHBOURS = 12
"""Neighbours of the normal estimate (about the surface sampler's local spacing)."""


@dataclass(frozen=True)
class SceneModel:
    """One scene instance's object model (world frame, metres) with its true descriptor and focus points."""

    name: str
    seed: int
    points: Points
    normals: Points
    """(n, 3) unit normals pointing away from the model's centroid (for view-direction partial scans)."""
    truth: Descriptor
    focus: Points
    """(k, 3) model points nearest the true grasp and axis points, as ``pbd transfer`` picks them."""
    grip: Points
    """(1, 3) model point nearest the true wrist position (the grasped part)."""
    placement: Similarity
    """World from the scene's base frame (rigid): where this instance stands."""


def outward_normals(points: Points) -> Points:
    """Unit normals of a surface sample (n, 3), each turned to point away from the sample's centroid."""
    import open3d as o3d

    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=NORMAL_NEIGHBOURS))
    normals = np.asarray(pcd.normals, dtype=np.float64).copy()
    away = points - points.mean(axis=0)
    flip = np.einsum("ij,ij->i", normals, away) < 0.0
    normals[flip] *= -1.0
    out: Points = normals
    return out


def scene_model(name: str, seed: int, n_points: int, rng: np.random.Generator) -> SceneModel:
    """The object model of instance ``seed`` of built-in scene ``name``: ``n_points`` surface samples (no noise)."""
    from tasks.scenes.catalog import build_scene
    from tasks.scenes.kinematics import truth_descriptor
    from tasks.scenes.surface import sample_object_model

    scene = build_scene(name, seed)
    points = sample_object_model(scene, n_points, rng)
    truth = truth_descriptor(scene)
    normals = outward_normals(points)
    placement = Similarity(1.0, matrix_from_quat(scene.base_orientation), np.asarray(scene.base_position))
    focus, grip = focus_points(truth, points), grip_points(truth, points)
    return SceneModel(name, seed, points, normals, truth, focus, grip, placement)
