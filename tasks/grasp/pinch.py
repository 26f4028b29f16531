"""Fingertip pinches held back on the demonstrated approach: the planner's last resort when no grasp near the
demonstration holds.

The Barrett fingers are 126 mm long on knuckles 50 mm either side of the palm centre: the fingertips close at
80-100 mm in front of the palm, and a finger curled round a bar reaches 45 mm or more in front of it. On a handle
standing 18-30 mm in front of its plate, fingers that wrap the bar from a palm near it therefore meet the plate,
and a finger the mount stops cannot squeeze (``shake.grip``): no palm from touching the bar to 30 mm before it
holds such a handle. Held back on the demonstrated approach, 60-100 mm from where it meets the part, the open
fingertips close on the bar's sides, clear of the plate, and pinch it.

The palm keeps the demonstrated orientation and lies on the demonstrated approach (the approach distance d of
GraspIt!'s search space, whose range reaches 200 mm); it is not moved on to contact, since the fingertips, not the
palm, are to touch. The fingers close from the open hand (``barrett.OPEN_FINGER_RAD``) as in execution.
"""

from __future__ import annotations

import math

import numpy as np

from tasks.arrays import FloatArray, Vector3
from tasks.grasp.object_model import ObjectModel
from tasks.grasp.planner import ApproachSpace, GraspCandidate, PlannerParams, execute_states, pivot_distance
from tasks.hand import barrett

PINCH_DISTANCES_M = (0.06, 0.07, 0.08, 0.09, 0.10)
"""Palm distances (m) from where the demonstrated approach meets the part: the fingertips of the open hand close
80-100 mm in front of the palm, so a bar 20-30 mm across is pinched at its sides from 70-90 mm."""
PINCH_SPREADS_RAD = (0.0, math.pi / 2)
"""Spreads (rad), in order of preference: fingers 1 and 2 opposite the thumb (three fingertips across the bar, two
against one, which resist its turning about the pinch), then face to face (two opposed fingertips leave the bar
free to turn about the line between them)."""


def pinch_candidates(
    model: ObjectModel,
    seed_rot: FloatArray,
    seed_pos: Vector3,
    params: PlannerParams,
    rolls_rad: tuple[float, ...] = (0.0,),
) -> list[GraspCandidate]:
    """The fingertip pinches of ``model`` from palms on the demonstrated approach (seed palm rotation (3, 3) and
    position (3,) m, world) at ``PINCH_DISTANCES_M`` from the part with ``PINCH_SPREADS_RAD``, the palm rolled
    ``rolls_rad`` (rad) about the approach, executed in pybullet without the approach to contact; in the order of
    ``PINCH_SPREADS_RAD``, each nearest the demonstration first."""
    space = ApproachSpace(seed_rot, seed_pos, pivot_distance(model, seed_rot, seed_pos, params.max_pivot_m))
    picks = [
        (np.array([barrett.spread_amplitude(spread), 0.0, distance, roll, 0.0]), 0.0)
        for roll in rolls_rad
        for distance in PINCH_DISTANCES_M
        for spread in PINCH_SPREADS_RAD
    ]
    found = execute_states(model, space, picks, params, approach_max_m=0.0)
    return sorted(found, key=lambda c: (spread_rank(float(c.closed[0])), c.closeness))


ROLLED_PINCH_RAD = (math.radians(-15.0), math.radians(15.0))
"""Rolls (rad) about the demonstrated approach of the last pinches tried (the demonstrated approach's rolls,
``planner.LINE_POSES``). Rolled about the approach, the fingertips meet a bar along other lines of its surface,
where contacts that lay in one plane and showed no force closure, even squeezed, may close."""
NEIGHBOUR_STEP_M = 0.005
NEIGHBOUR_ROLL_RAD = math.radians(15.0)
"""Steps of ``pinch_neighbours``: the palm 5 mm nearer or farther on the approach, rolled 15° either way about it
(the demonstrated approach's rolls, ``planner.LINE_POSES``)."""


def pinch_neighbours(
    model: ObjectModel, seed_rot: FloatArray, seed_pos: Vector3, params: PlannerParams, held: GraspCandidate
) -> list[GraspCandidate]:
    """The pinches next to ``held`` (a pinch that held the part but showed no force closure, even squeezed):
    its spread with the palm rolled ``NEIGHBOUR_ROLL_RAD`` either way, moved ``NEIGHBOUR_STEP_M`` along the
    approach, or both (rad, m; the seed palm rotation (3, 3) and position (3,) m, world, as in
    ``pinch_candidates``), in that order. Two fingertips against the thumb on a bar touch it on two lines; rolled
    or moved, their contacts fall apart along it and may close."""
    space = ApproachSpace(seed_rot, seed_pos, pivot_distance(model, seed_rot, seed_pos, params.max_pivot_m))
    moves, rolls = (-NEIGHBOUR_STEP_M, NEIGHBOUR_STEP_M), (-1.0, 1.0)
    steps = [(0.0, r) for r in rolls] + [(m, 0.0) for m in moves] + [(m, r) for m in moves for r in rolls]
    picks = []
    for move, roll in steps:
        x = held.state.copy()
        x[2] += move
        x[3] += roll * NEIGHBOUR_ROLL_RAD
        picks.append((x, 0.0))
    return execute_states(model, space, picks, params, approach_max_m=0.0)


def spread_rank(spread_rad: float) -> int:
    """Index of the ``PINCH_SPREADS_RAD`` entry nearest ``spread_rad``."""
    return int(np.argmin([abs(spread_rad - s) for s in PINCH_SPREADS_RAD]))
