"""The planner's search: the state space, contact energy, the annealing schedule and its best list, the registered
generators, and planned grasps on a box and a handle that hold under the planner's check."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.grasp.api import plan_grasp, plan_on_model
from tasks.grasp.execution import contacts_of, execute_pose, grasp_from_candidate, hand_and_object
from tasks.grasp.object_model import build_object_model
from tasks.grasp.planner import (
    ACCEPT_C,
    ACCEPT_D,
    GENERATORS,
    ILLEGAL_ENERGY,
    NEIGHBOUR_C,
    NEIGHBOUR_D,
    ROLLS_RAD,
    TIP_DISTANCES_M,
    TIP_SPREADS_RAD,
    BestList,
    PlannerParams,
    anneal,
    contact_energy,
    find_bars,
    ingber_from_uniforms,
    pinch,
    search_space,
    square_pinch,
    state_energy,
    temperature,
)
from tasks.grasp.shake import hold_check, shake_test
from tasks.hand import barrett
from tests.grasp.cases.bench import row_setup
from tests.grasp.cases.exact import labelled_model
from tests.grasp.cases.families import CENTRE, family_case
from tests.grasp.cases.grasp import PLATE_POINTS, handle_on_plate

from .conftest import HANDLE_CENTER, PALM_DOWN


def test_graspit_online_schedule() -> None:
    assert temperature(100, NEIGHBOUR_C, NEIGHBOUR_D) == pytest.approx(10.0 * math.exp(-0.24 * 10.0))
    assert temperature(1000, ACCEPT_C, ACCEPT_D) == pytest.approx(10.0 * math.exp(-0.54 * 10.0))
    draws = ingber_from_uniforms(0.05, np.random.default_rng(0).random(10000))
    assert np.all(np.abs(draws) < 1.0)
    # |y| = T((1 + 1/T)^v - 1) with v uniform: the median is at v = 1/2; cold draws are small with a heavy tail
    assert np.median(np.abs(draws)) == pytest.approx(0.05 * (21.0**0.5 - 1.0), rel=0.05)
    assert np.max(np.abs(draws)) > 0.5


def test_contact_energy_is_low_on_contact_and_illegal_inside(handle_points: tuple[Points, Points]) -> None:
    model = build_object_model(handle_points[0], np.random.default_rng(0))
    rot = Rotation.from_quat(PALM_DOWN).as_matrix()[None]
    joints = barrett.joints_from_eigengrasps(np.array([[-1.13, -1.37]]))
    touching, far, inside = (
        float(contact_energy(model, rot, (HANDLE_CENTER + np.array([0, 0, dz]))[None], joints)[0])
        for dz in (0.021, 0.2, 0.0)
    )
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
    starts = np.array([[0.0, -1.0, space.pivot_m, 0.0, 0.0, 0.0, 0.0, 0.0], [2.0, -1.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0]])
    anneal(lambda x: state_energy(model, space, x), starts, space, np.random.default_rng(0), 200, best)
    energies = [e for e, _ in best.states]
    assert len(energies) == 6
    assert energies == sorted(energies)
    assert energies[0] < float(np.min(state_energy(model, space, starts)))
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


def test_a_square_pinch_closes_thumb_and_fingers_on_a_thin_bar_at_its_widest() -> None:
    rng = np.random.default_rng(3)
    pts, centre = handle_on_plate(0.009, 0.13, 0.04, False, rng)
    seed_rot = Rotation.from_euler("x", -90, degrees=True).as_matrix()  # approach along +y, palm x along the bar
    seed_pos = centre - np.array([0.0, 0.009 + 0.04, 0.0])
    model = build_object_model(pts, rng, viewpoint=seed_pos, approach=seed_rot[:, 2])
    assert model.cylinder is not None
    prm = PlannerParams()
    space = search_space(model, seed_rot, seed_pos, prm)
    thumb_against_two = [p for p in square_pinch(model, space, prm, rng) if abs(p.state[0] + 1.13) < 1e-6]
    assert thumb_against_two
    with hand_and_object(model) as (client, hand, obj):
        for prop in thumb_against_two:
            rot, pos = space.pose(prop.state)
            assert execute_pose(client, hand, obj, model, rot, pos, 0.0, 0.0, prm.mu) is not None
            normals = contacts_of(client, hand, obj).normals_in
            assert len(normals) >= 3
            # opposed across the bar's axis: no squeeze drags the bar towards the palm or pushes it out
            assert np.all(np.abs(normals @ rot[:, 2]) < math.sin(math.radians(10.0)))


@pytest.mark.parametrize("profile", ["D", "square", "round"])
def test_a_bar_of_any_profile_is_found_from_its_points(profile: str) -> None:
    """A pull's bar, round, square or D-shaped (the latter two with no fitted cylinder), is found along its axis
    through the profile's centre at its half width, across a scan of 1 mm noise; a knob is no bar."""
    for seed in range(3):
        case = family_case(f"{profile} pull", np.random.default_rng(seed))
        name = case.name.split()
        width = float(name[2][1:]) / 2000.0  # "w<full width in mm>"
        axis = np.array([0.0, 0.0, 1.0]) if name[-1] == "vertical" else np.array([1.0, 0.0, 0.0])
        model, _, _ = row_setup(case, seed, 0)
        space = search_space(model, Rotation.from_quat(case.seed_quat).as_matrix(), case.seed_pos, PlannerParams())
        (bar,) = find_bars(model, space)
        assert abs(float(bar.axis @ axis)) > math.cos(math.radians(5.0))
        off = bar.centre - CENTRE
        assert np.linalg.norm(off - (off @ axis) * axis) < 0.004  # on the bar's axis, along it anywhere
        assert abs(bar.half_width - width) < 0.003
    knob = family_case("knob", np.random.default_rng(0))
    model, _, _ = row_setup(knob, 0, 0)
    space = search_space(model, Rotation.from_quat(knob.seed_quat).as_matrix(), knob.seed_pos, PlannerParams())
    assert find_bars(model, space) == []


def test_a_box_is_a_bar_along_either_edge_square_to_the_approach(box_points: Points) -> None:
    """Looked down on, the fitted box is pinched across either pair of upright faces: a bar along each horizontal
    edge, as wide as the box across it."""
    seed = np.array([0.5, 0.1, 0.3 + 0.04 + 0.05])
    model = build_object_model(box_points, np.random.default_rng(3), viewpoint=seed)
    assert model.primitive is not None and model.primitive.kind == "box"
    space = search_space(model, Rotation.from_quat(PALM_DOWN).as_matrix(), seed, PlannerParams())
    bars = find_bars(model, space)
    assert len(bars) == 2
    for bar in bars:
        assert abs(float(bar.axis[2])) < 0.05
        across = np.cross(bar.axis, [0.0, 0.0, 1.0])
        extent = box_points @ across
        assert abs(bar.half_width - 0.5 * float(extent.max() - extent.min())) < 0.003
    assert square_pinch(model, space, PlannerParams(), np.random.default_rng(0))


def test_a_cap_is_pinched_from_its_axis_too() -> None:
    """Beside the pinches from the demonstrated palm, a bottle cap is pinched from its axis: palms looking along the
    cap's axis from a point on it, before its top, at every distance and fingertip spread; a bar across the approach
    gets only the pinches from the demonstrated palm."""
    case = family_case("bottle cap", np.random.default_rng(4))
    model, _, _ = row_setup(case, 4, 0)
    assert model.cylinder is not None
    space = search_space(model, Rotation.from_quat(case.seed_quat).as_matrix(), case.seed_pos, PlannerParams())
    axis = Rotation.from_quat(model.cylinder.quat_xyzw).apply([0.0, 0.0, 1.0])
    centre = np.asarray(model.cylinder.position)
    centred = []
    for prop in pinch(model, space, PlannerParams(), np.random.default_rng(0)):
        rot, pos = space.pose(prop.state)
        off = pos - centre
        if (
            abs(float(rot[:, 2] @ axis)) > math.cos(math.radians(0.1))
            and np.linalg.norm(off - (off @ axis) * axis) < 1e-6
        ):
            assert float((centre - pos) @ rot[:, 2]) > float(model.cylinder.size[1])  # before the top, looking at it
            centred.append(prop)
    assert len(centred) == len(TIP_DISTANCES_M) * len(TIP_SPREADS_RAD)
    pull = family_case("round pull", np.random.default_rng(0))
    model, _, _ = row_setup(pull, 0, 0)
    assert model.cylinder is not None
    space = search_space(model, Rotation.from_quat(pull.seed_quat).as_matrix(), pull.seed_pos, PlannerParams())
    proposals = pinch(model, space, PlannerParams(), np.random.default_rng(0))
    assert len(proposals) == len(ROLLS_RAD) * len(TIP_DISTANCES_M) * len(TIP_SPREADS_RAD)
