"""The planner's search: the state space, contact energy, the annealing schedule and its best list, the registered
generators, and planned grasps on a box and a handle that hold under the planner's check."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.grasp.api import plan_grasp, plan_on_model
from tasks.grasp.candidate_grasp import grasp_from_candidate
from tasks.grasp.generators import GENERATORS
from tasks.grasp.hold_check import hold_check
from tasks.grasp.object_model import build_object_model, labelled_model
from tasks.grasp.planner import (
    ILLEGAL_ENERGY,
    BestList,
    PlannerParams,
    Schedule,
    anneal,
    contact_energy,
    ingber_from_uniforms,
    search_space,
    state_energy,
)
from tasks.grasp.shake import shake_test
from tasks.hand import barrett
from tests.grasp.cases.grasp import PLATE_POINTS, handle_on_plate

from .conftest import HANDLE_CENTER, PALM_DOWN


def test_graspit_online_schedule() -> None:
    s = Schedule()
    assert s.neighbour_temperature(100) == pytest.approx(10.0 * math.exp(-0.24 * 10.0))
    assert s.accept_temperature(1000) == pytest.approx(10.0 * math.exp(-0.54 * 10.0))
    draws = ingber_from_uniforms(0.05, np.random.default_rng(0).random(10000))
    assert np.all(np.abs(draws) < 1.0)
    # |y| = T((1 + 1/T)^v - 1) with v uniform: the median is at v = 1/2; cold draws are small with a heavy tail
    assert np.median(np.abs(draws)) == pytest.approx(0.05 * (21.0**0.5 - 1.0), rel=0.05)
    assert np.max(np.abs(draws)) > 0.5


def test_contact_energy_is_low_on_contact_and_illegal_inside(handle_points: tuple[Points, Points]) -> None:
    model = build_object_model(handle_points[0], np.random.default_rng(0))
    rot = Rotation.from_quat(PALM_DOWN).as_matrix()
    dofs = barrett.dofs_from_eigengrasps(-1.13, -1.37)
    touching = contact_energy(model, rot, HANDLE_CENTER + np.array([0, 0, 0.021]), dofs)
    far = contact_energy(model, rot, HANDLE_CENTER + np.array([0, 0, 0.2]), dofs)
    inside = contact_energy(model, rot, HANDLE_CENTER + np.array([0, 0, 0.0]), dofs)
    assert touching < far
    assert inside == ILLEGAL_ENERGY


def test_a_state_and_its_palm_pose_map_onto_each_other(handle_points: tuple[Points, Points]) -> None:
    model = build_object_model(handle_points[0], np.random.default_rng(0))
    seed_rot = Rotation.from_quat(PALM_DOWN).as_matrix()
    space = search_space(model, seed_rot, HANDLE_CENTER + np.array([0, 0, 0.06]), PlannerParams())
    assert space.pivot_m == pytest.approx(0.04, abs=0.003)  # the bar's top, 20 mm above its axis
    x = np.array([barrett.spread_amplitude(0.4), 0.0, 0.05, 0.1, -0.2, 0.15, 0.01, -0.02])
    rot, pos = space.pose(x)
    np.testing.assert_allclose(space.state(rot, pos, 0.4), x, atol=1e-9)


def test_annealing_keeps_the_best_unique_states(handle_points: tuple[Points, Points]) -> None:
    model = build_object_model(handle_points[0], np.random.default_rng(0))
    seed_rot = Rotation.from_quat(PALM_DOWN).as_matrix()
    space = search_space(model, seed_rot, HANDLE_CENTER + np.array([0, 0, 0.06]), PlannerParams())
    best = BestList(6, space.upper - space.lower)
    start = np.array([0.0, -1.0, space.pivot_m, 0.0, 0.0, 0.0, 0.0, 0.0])
    anneal(lambda x: state_energy(model, space, x), start, space, np.random.default_rng(0), 200, best)
    energies = [e for e, _ in best.states]
    assert len(energies) == 6
    assert energies == sorted(energies)
    assert energies[0] < state_energy(model, space, start)
    for i, (_, a) in enumerate(best.states):
        for _, b in best.states[i + 1 :]:
            assert np.any(np.abs(a - b) >= 0.1 * (space.upper - space.lower))


def test_fingertip_generators_propose_only_where_their_mechanism_applies(box_points: Points) -> None:
    rng = np.random.default_rng(0)
    pts, centre = handle_on_plate(0.012, 0.14, 0.035, True, rng)
    seed_rot = Rotation.from_euler("x", -90, degrees=True).as_matrix()  # approach along +y, towards the plate
    seed_pos = centre - np.array([0.0, 0.012 + 0.04, 0.0])
    handle = labelled_model(pts[:-PLATE_POINTS], pts[-PLATE_POINTS:], rng, viewpoint=seed_pos)
    box = build_object_model(box_points, rng)
    prm = PlannerParams(steps=20, chains=1)
    for model, tips in ((handle, True), (box, False)):
        space = search_space(model, seed_rot, seed_pos, prm)
        proposed = {name: make(model, space, prm, rng) for name, make in GENERATORS.items()}
        assert proposed["demonstrated"]
        assert proposed["annealed"]
        assert bool(proposed["pinch"]) == tips
        for props in proposed.values():
            assert all(space.inside(p.state) for p in props)


def test_planner_finds_a_force_closure_on_a_box_that_holds(box_points: Points) -> None:
    seed = np.array([0.5, 0.1, 0.3 + 0.04 + 0.05])  # 50 mm above the box top, looking down
    model = build_object_model(box_points, np.random.default_rng(3), viewpoint=seed)
    grasp = grasp_from_candidate(plan_on_model(model, seed, PALM_DOWN, np.random.default_rng(3)))
    assert grasp.hand == "barrett"
    assert grasp.quality["force_closure"] is True
    assert grasp.quality["epsilon"] > 0.0
    assert all(abs(a) <= 4.0 for a in grasp.eigengrasps)
    assert np.linalg.norm(np.array(grasp.wrist_position) - seed) < 0.1
    assert shake_test(model, grasp, hold_check(np.array(grasp.wrist_orientation))).holds


def test_planner_is_deterministic_for_a_seeded_rng(handle_points: tuple[Points, Points]) -> None:
    seed = HANDLE_CENTER + np.array([0, 0, 0.06])
    a = plan_grasp(handle_points[0], seed, PALM_DOWN, np.random.default_rng(5))
    b = plan_grasp(handle_points[0], seed, PALM_DOWN, np.random.default_rng(5))
    assert a == b
    assert a.quality["force_closure"] is True
