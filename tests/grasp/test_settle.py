"""Settling a wrap: the squeezing fingers pull a lying cylinder into the palm, a force closure the static
closing misses."""

from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest
from scipy.spatial.transform import Rotation

from tasks.grasp import barrett
from tasks.grasp.object_model import ObjectModel, build_object_model, load_object, sample_cylinder_surface
from tasks.grasp.planner import GraspCandidate, PlannerParams, evaluate_pose
from tasks.grasp.settle import MAX_SHIFT_M, settle, settled_wraps

CENTRE = np.array([0.5, 0.0, 0.3])
RADIUS = 0.03
PALM_DOWN = Rotation.from_euler("x", 180, degrees=True)
"""The palm's +z (approach) along world -z, its x axis along the cylinder."""


@pytest.fixture(scope="module")
def cylinder() -> ObjectModel:
    """A cylinder of 30 mm radius, 160 mm long, lying along world x at CENTRE."""
    rng = np.random.default_rng(0)
    pts, _ = sample_cylinder_surface(RADIUS, 0.08, 3000, rng)
    lying = Rotation.from_euler("y", 90, degrees=True).apply(pts) + CENTRE
    return build_object_model(lying, rng, viewpoint=CENTRE + np.array([0.0, 0.0, 0.2]))


def _candidate(model: ObjectModel, gap_m: float) -> GraspCandidate:
    """The hand closed kinematically (spread 0, no approach) with the palm ``gap_m`` above the cylinder."""
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


def test_the_squeeze_pulls_the_part_into_the_palm(cylinder: ObjectModel) -> None:
    cand = _candidate(cylinder, 0.01)
    assert not cand.quality.force_closure  # statically the fingertips only push the cylinder away
    done = settle(cylinder, cand.position, cand.quat_xyzw, 0.0, 0.5)
    assert done.quality.force_closure
    assert done.quality.epsilon > 0.05
    assert done.palm_contact
    assert 0.003 < done.shift_m < MAX_SHIFT_M
    # the settled palm, with the cylinder back in place, lies on it: 10 mm lower, same orientation
    assert done.position[2] == pytest.approx(CENTRE[2] + RADIUS, abs=0.004)
    turn = (PALM_DOWN.inv() * Rotation.from_quat(done.quat_xyzw)).magnitude()
    assert np.degrees(turn) < 5.0


def test_wraps_come_back_near_and_far_pulls_do_not(cylinder: ObjectModel) -> None:
    seed_rot = PALM_DOWN.as_matrix()
    near, far = _candidate(cylinder, 0.01), _candidate(cylinder, 0.03)
    wraps = settled_wraps([near], cylinder, near.position, seed_rot, 0.02, np.radians(15.0))
    assert len(wraps) == 1
    assert wraps[0].quality.force_closure and wraps[0].near
    assert wraps[0].offset_m < 0.005  # on the demonstrated approach
    assert settled_wraps([far], cylinder, far.position, seed_rot, 0.02, np.radians(15.0)) == []  # pulled 60 mm
