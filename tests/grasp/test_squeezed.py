"""Grasps whose static closing shows no force closure but whose squeezing fingers hold the part: the planner's pass
over them on mounted parts (``api.DYNAMIC_CHECKS``), their squeezed quality, and the neighbourhood's limit."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.grasp.api import part_near, plan_on_model
from tasks.grasp.candidate_grasp import grasp_from_candidate
from tasks.grasp.hold_budget import squeezed
from tasks.grasp.hold_check import hold_check
from tasks.grasp.object_model import ObjectModel, build_object_model
from tasks.grasp.planner import ApproachSpace, PlannerParams, demo_offset, is_near, is_reach
from tasks.grasp.shake import shake_test
from tasks.scenes.catalog import build_scene
from tasks.scenes.kinematics import truth_descriptor
from tasks.simulate.api import simulate_descriptor
from tasks.synth.record import OBJECT_MODEL_POINTS
from tasks.synth.scan import scan_object_model
from tests.grasp.lying_cylinder import closed_above, lying_cylinder


@pytest.fixture(scope="module")
def cylinder() -> ObjectModel:
    """A cylinder of 30 mm radius, 160 mm long, lying along world x (``lying_cylinder``)."""
    return lying_cylinder()


def test_squeezing_shows_the_closure_the_static_closing_misses(cylinder: ObjectModel) -> None:
    cand = closed_above(cylinder, 0.01)
    assert not cand.quality.force_closure
    held = squeezed((cand, cylinder), 0.5)
    assert held is not None
    assert held.quality.force_closure and held.quality.epsilon > 0.05
    np.testing.assert_array_equal(held.position, cand.position)  # the pose the hold check tested, unchanged
    empty = closed_above(cylinder, 0.15)  # the fingers close on nothing
    assert squeezed((empty, cylinder), 0.5) is None


def test_poses_on_the_neighbourhood_limit_count_as_near() -> None:
    rot = np.eye(3)
    seed = np.array([0.0, 0.0, 0.0])
    space = ApproachSpace(rot, seed, 0.05)
    params = PlannerParams()
    on_limit = demo_offset(rot, seed - params.near_position_m * rot[:, 2], space, params)
    assert is_near(on_limit, params) and is_reach(on_limit, params)
    beyond = demo_offset(rot, seed - (params.near_position_m + 1e-4) * rot[:, 2], space, params)
    assert not is_near(beyond, params) and not is_reach(beyond, params)


@pytest.mark.slow
def test_door_lever_held_by_squeezing_fingers_and_executed() -> None:
    """Door seed 1, modelled as ``pbd synth`` records it and the learn stage builds it (the mount looked for along
    the demonstrated approach): the lever's arm is planned on as a cylinder and the grasp holds under the planner's
    check and opens the door in simulation. On convex pieces alone (``fit=False``) no static force closure near
    the demonstration holds, and the squeezed grasp with fingers 1 and 2 face to face does."""
    scene = build_scene("door", 1)
    truth = truth_descriptor(scene)
    assert truth.grasp is not None
    demo_pos = np.array(truth.grasp.wrist_position)
    demo_quat = np.array(truth.grasp.wrist_orientation)
    model_rng = np.random.default_rng(np.random.SeedSequence(1).spawn(3)[2])
    points = scan_object_model(scene, OBJECT_MODEL_POINTS, model_rng)
    approach = Rotation.from_quat(demo_quat).as_matrix()[:, 2]
    part = part_near(points, demo_pos)
    rng = np.random.default_rng(7)
    model = build_object_model(part, rng, viewpoint=demo_pos, approach=approach)
    assert model.mount is not None and model.cylinder is not None
    grasp = grasp_from_candidate(plan_on_model(model, demo_pos, demo_quat, rng))
    assert grasp.quality["force_closure"] is True
    assert shake_test(model, grasp, hold_check(np.asarray(grasp.wrist_orientation))).holds
    result = simulate_descriptor(dataclasses.replace(truth, grasp=grasp), scene="door", rng=np.random.default_rng(1))
    assert result.grasped
    assert result.success
    rng = np.random.default_rng(7)
    pieces = build_object_model(part, rng, viewpoint=demo_pos, approach=approach, fit=False)
    squeezed_grasp = grasp_from_candidate(plan_on_model(pieces, demo_pos, demo_quat, rng))
    assert squeezed_grasp.quality["force_closure"] is True
    assert squeezed_grasp.quality["closed_dofs"][0] == pytest.approx(math.pi / 2, abs=0.05)
    assert shake_test(pieces, squeezed_grasp, hold_check(np.asarray(squeezed_grasp.wrist_orientation))).holds
