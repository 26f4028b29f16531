"""A lying cylinder and the hand closed kinematically above it: a grasp whose static closing shows no force
closure while the squeezing fingers hold the cylinder (shared by the settling and squeezing tests)."""

from __future__ import annotations

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from tasks.grasp.object_model import ObjectModel, build_object_model, load_object
from tasks.grasp.planner import GraspCandidate, PlannerParams, evaluate_pose
from tasks.hand import barrett
from tests.grasp.surface_sampling import sample_cylinder_surface

CENTRE = np.array([0.5, 0.0, 0.3])
RADIUS = 0.03
PALM_DOWN = Rotation.from_euler("x", 180, degrees=True)
"""The palm's +z (approach) along world -z, its x axis along the cylinder."""


def lying_cylinder() -> ObjectModel:
    """A cylinder of 30 mm radius, 160 mm long, lying along world x at CENTRE, as its scan's convex pieces
    (``fit=False``: on the fitted cylinder the static closing already shows a force closure, epsilon 0.001)."""
    rng = np.random.default_rng(0)
    pts, _ = sample_cylinder_surface(RADIUS, 0.08, 3000, rng)
    lying = Rotation.from_euler("y", 90, degrees=True).apply(pts) + CENTRE
    return build_object_model(lying, rng, viewpoint=CENTRE + np.array([0.0, 0.0, 0.2]), fit=False)


def closed_above(model: ObjectModel, gap_m: float) -> GraspCandidate:
    """The hand closed kinematically (spread 0, no approach) with the palm ``gap_m`` (m) above the cylinder; its
    closeness is ``gap_m``."""
    client = pb.connect(pb.DIRECT)
    try:
        obj = load_object(client, model)
        hand = barrett.load_hand(client)
        pos = CENTRE + np.array([0.0, 0.0, RADIUS + gap_m])
        out = evaluate_pose(
            client, hand, obj, model, PALM_DOWN.as_matrix(), pos, 0.0, PlannerParams(approach_max_m=0.0)
        )
    finally:
        pb.disconnect(client)
    assert out is not None
    final_pos, _, closed, quality = out
    return GraspCandidate(np.zeros(5), final_pos, PALM_DOWN.as_quat(), closed, quality, 0.0, gap_m, 0.0, 0.0, near=True)
