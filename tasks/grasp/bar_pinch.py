"""Fingertip pinches square to a bar: the palm's approach at right angles to the bar found in a mounted part
(``ObjectModel.cylinder``, ``part_cylinders``), through its axis, the fingers closing across it.

The pinches of ``pinch.py`` keep the demonstrated palm's orientation, which the demonstrator holds 10-15° off the
bar's square; tilted, the three fingertips meet a round bar at different heights and a squeeze rolls it out. Square
to the bar, a palm 0-60 mm before it puts the fingers against the plate behind a bar that stands close to it, and
the fingertips close on the bar's sides at its widest only in a window of palm distances 10-15 mm wide, around
the middle of the fingertips' reach (80 mm); the pinches are checked from there outwards.

The palm may be rolled and tilted up to ``MAX_TILT_RAD`` off the demonstrated one, which the demonstration does
not fix for a bar: a hand wraps a bar at any roll about the square. These pinches come only after every grasp
near the demonstration failed the planner's hold check (``tasks.grasp.api``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Vector3
from tasks.grasp.object_model import ObjectModel
from tasks.grasp.pinch import PINCH_SPREADS_RAD, spread_rank
from tasks.grasp.planner import ApproachSpace, GraspCandidate, PlannerParams, execute_states, pivot_distance
from tasks.hand import barrett

SQUARE_STEP_M = 0.005
SQUARE_DISTANCES_M = tuple(round(0.06 + SQUARE_STEP_M * i, 3) for i in range(9))
"""Palm distances (m) from the bar's near surface: 60-100 mm in 5 mm steps (the window is 10-15 mm wide)."""
SQUARE_SPREADS_RAD = PINCH_SPREADS_RAD
"""Spreads (rad) tried, in this order: the fingertip pinches' (``pinch.PINCH_SPREADS_RAD``)."""
MAX_TILT_RAD = math.radians(45.0)
"""The bar's square is used only when the demonstrated approach is within 45° of it."""


def square_space(model: ObjectModel, seed_rot: FloatArray, seed_pos: Vector3) -> ApproachSpace | None:
    """The approach space of palms square to the model's bar: rotation with +z the demonstrated approach (seed
    rotation (3, 3), world) less its component along the bar, +x along the bar (the sign nearer the demonstrated
    palm's x); the pivot on the bar's near surface where the line through its axis point nearest the demonstrated
    approach meets it; None without a bar or when the approach is more than ``MAX_TILT_RAD`` off its square."""
    bar = model.cylinder
    if bar is None:
        return None
    axis = Rotation.from_quat(bar.quat_xyzw).apply([0.0, 0.0, 1.0])
    approach = seed_rot[:, 2]
    square = approach - float(approach @ axis) * axis
    if float(np.linalg.norm(square)) < math.cos(MAX_TILT_RAD):
        return None
    z = square / float(np.linalg.norm(square))
    x = axis if float(axis @ seed_rot[:, 0]) >= 0.0 else -axis
    rot = np.stack([x, np.cross(z, x), z], axis=1)
    centre = np.asarray(bar.position, dtype=np.float64)
    half = float(bar.size[1])
    along = float(np.clip((np.asarray(seed_pos) - centre) @ axis, -half, half))  # nearest the demonstrated palm
    on_axis = centre + along * axis
    front = on_axis - z * float(bar.size[0])
    back = 0.2  # the space's seed palm; only its pivot, ``front``, matters: a state's distance is taken from it
    return ApproachSpace(rot, front - z * back, back)


def square_pinches(
    model: ObjectModel, seed_rot: FloatArray, seed_pos: Vector3, params: PlannerParams
) -> list[GraspCandidate]:
    """The fingertip pinches square to the model's bar (``square_space``) from ``SQUARE_DISTANCES_M`` at
    ``SQUARE_SPREADS_RAD``, executed in pybullet without the approach to contact, their offsets from the
    demonstrated palm (rotation (3, 3), position (3,) m, world); in the order of ``SQUARE_SPREADS_RAD``, each
    spread's distances from the middle of ``SQUARE_DISTANCES_M`` outwards (``_order``). Empty without a bar."""
    space = square_space(model, seed_rot, seed_pos)
    if space is None:
        return []
    demo = ApproachSpace(seed_rot, seed_pos, pivot_distance(model, seed_rot, seed_pos, params.max_pivot_m))
    picks = [
        (np.array([barrett.spread_amplitude(spread), 0.0, distance, 0.0, 0.0]), 0.0)
        for spread in SQUARE_SPREADS_RAD
        for distance in SQUARE_DISTANCES_M
    ]
    found = execute_states(model, space, picks, params, approach_max_m=0.0, demo=demo)
    return sorted(found, key=_order)


def _order(cand: GraspCandidate) -> tuple[int, float]:
    """Sort key of a square pinch: spread (``SQUARE_SPREADS_RAD`` order), then distance from the middle of
    ``SQUARE_DISTANCES_M`` (the middle of the fingertips' reach) outwards, the nearer of two equally far first."""
    spread, step = _key(cand)
    return spread, abs(step - (len(SQUARE_DISTANCES_M) - 1) / 2.0) + 0.1 * step


def _key(cand: GraspCandidate) -> tuple[int, int]:
    """(spread index in ``SQUARE_SPREADS_RAD``, distance step in ``SQUARE_DISTANCES_M``) of a square pinch."""
    step = round((float(cand.state[2]) - SQUARE_DISTANCES_M[0]) / SQUARE_STEP_M)
    return spread_rank(float(cand.closed[0])), step
