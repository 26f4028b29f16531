"""Grasps slid along a bar: when no grasp near the demonstration holds a mounted part whose bar was found
(``part_cylinders``), the demonstrated palm moved along the bar and held back on its approach.

Where along a handle's bar or a lever's arm the demonstrator's hand closed says little: the bar is held anywhere
along it. Three fingertips on a lever's round arm near the demonstrated palm can let the arm roll out under a
long shake, while the palm slid 25-50 mm along the arm and held back 20 mm, fingers 1 and 2 face to face (spread
π/2), closes round the arm and holds it within a few millimetres and degrees. The palm keeps the demonstrated
orientation; the fingers close from the open hand without an approach to contact, as the hold test closes them.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Vector3
from tasks.grasp.object_model import ObjectModel
from tasks.grasp.planner import ApproachSpace, GraspCandidate, PlannerParams, execute_states, pivot_distance
from tasks.hand import barrett

SLIDES_M = (0.025, 0.05)
"""Distances (m) the palm is slid along the bar, either way, nearest first."""
HOLD_BACKS_M = (0.0, 0.02)
"""Distances (m) the palm is held back on the demonstrated approach, at each slide."""
SLIDE_SPREADS_RAD = (0.0, math.pi / 2)
"""Spreads (rad) tried at each pose, in this order."""
MIN_ALONG = 0.5
"""The bar's axis makes at most 60° with the palm's plane (its component across the approach at least this long),
else sliding along it would move the palm towards or away from the part."""


def slide_candidates(
    model: ObjectModel, seed_rot: FloatArray, seed_pos: Vector3, params: PlannerParams
) -> Iterator[GraspCandidate]:
    """The grasps of the demonstrated palm (rotation (3, 3), position (3,) m, world) slid ``SLIDES_M`` either way
    along the model's bar (``ObjectModel.cylinder``, its axis projected across the approach) and held back
    ``HOLD_BACKS_M``, at ``SLIDE_SPREADS_RAD``, executed in pybullet without the approach to contact; nearest the
    demonstrated palm first, their offsets from it; each pose is executed only when the one before has been drawn
    (a planner stops at the first that holds). None without a bar or when the bar points along the approach."""
    if model.cylinder is None:
        return
    approach = seed_rot[:, 2]
    axis = Rotation.from_quat(model.cylinder.quat_xyzw).apply([0.0, 0.0, 1.0])
    across = axis - float(axis @ approach) * approach
    if float(np.linalg.norm(across)) < MIN_ALONG:
        return
    across /= np.linalg.norm(across)
    space = ApproachSpace(seed_rot, seed_pos, pivot_distance(model, seed_rot, seed_pos, params.max_pivot_m))
    poses = sorted(
        ((slide * sign, back) for slide in SLIDES_M for sign in (1.0, -1.0) for back in HOLD_BACKS_M),
        key=lambda p: math.hypot(*p),
    )
    for slide, back in poses:
        shifted = ApproachSpace(seed_rot, seed_pos + slide * across, space.pivot_m)
        picks = [
            (np.array([barrett.spread_amplitude(spread), 0.0, space.pivot_m + back, 0.0, 0.0]), 0.0)
            for spread in SLIDE_SPREADS_RAD
        ]
        yield from execute_states(model, shifted, picks, params, 0.0, demo=space)
