"""Fingertip pinches square to a bar (``bar_pinch.py``): the palm's approach at right angles to the bar through its
axis, the fingers closing across it, whatever the demonstrated palm's tilt and roll; the first pinches the planner
checks when no grasp near the demonstration holds a handle."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.grasp.bar_pinch import SQUARE_DISTANCES_M, SQUARE_SPREADS_RAD, square_pinches, square_space
from tasks.grasp.object_model import ObjectModel, build_object_model
from tasks.grasp.planner import PlannerParams
from tests.grasp.bench_object import plan_bench_object
from tests.grasp.test_pinch import BAR_CENTRE, BAR_RADIUS_M, PALM_ROT, SEED_POS, handle_points

TURNED = PALM_ROT * Rotation.from_euler("z", 20, degrees=True) * Rotation.from_euler("x", 10, degrees=True)
"""A demonstrated palm rolled 20° about its approach and tilted 10° along the bar, as a demonstrator holds it."""


@pytest.fixture(scope="module")
def handle_model() -> ObjectModel:
    """``test_pinch``'s handle and plate as the learn stage models them, seen from the turned palm."""
    part, plate = handle_points(np.random.default_rng(0))
    return build_object_model(
        np.concatenate([part, plate]), np.random.default_rng(7), viewpoint=SEED_POS, approach=TURNED.apply([0, 0, 1])
    )


def test_square_space_faces_the_bar_at_right_angles(handle_model: ObjectModel) -> None:
    """The palm x lies along the bar (the sign of the demonstrated palm's x), +z square to it towards the plate
    from the demonstrated side (the tilt about the bar is kept), and the pivot on the bar's near surface through
    its axis: the turned palm's 20° roll and its tilt along the bar are undone."""
    assert handle_model.cylinder is not None
    space = square_space(handle_model, TURNED.as_matrix(), SEED_POS)
    assert space is not None
    x, z = space.seed_rot[:, 0], space.seed_rot[:, 2]
    assert abs(float(x @ [1.0, 0.0, 0.0])) == pytest.approx(1.0, abs=0.01)  # along the bar (world x)
    assert float(x @ TURNED.apply([1.0, 0.0, 0.0])) > 0.0
    assert abs(float(z @ [1.0, 0.0, 0.0])) < 0.01  # square to the bar
    demonstrated = TURNED.apply([0.0, 0.0, 1.0])
    assert float(z @ demonstrated) == pytest.approx(float(np.linalg.norm(demonstrated[1:])), abs=0.01)
    pivot = space.seed_pos + z * space.pivot_m
    to_axis = BAR_CENTRE - pivot
    assert float(to_axis @ z) == pytest.approx(BAR_RADIUS_M, abs=0.002)  # on the bar's near surface
    assert float(np.linalg.norm(to_axis - float(to_axis @ z) * z - float(to_axis[0]) * np.array([1.0, 0, 0]))) < 0.002


def test_no_square_space_without_a_bar_or_along_it(handle_model: ObjectModel) -> None:
    """Without a bar there is no square; nor when the approach runs within 45° of the bar's axis."""
    bare = ObjectModel(handle_model.points, handle_model.normals, handle_model.center, handle_model.radius)
    assert square_space(bare, TURNED.as_matrix(), SEED_POS) is None
    along = Rotation.from_matrix(np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]))
    assert square_space(handle_model, along.as_matrix(), SEED_POS) is None


def test_square_pinches_are_held_back_on_the_square_middle_first(handle_model: ObjectModel) -> None:
    """Each pinch's palm lies on the square through the bar's axis, 60-100 mm before the bar, not moved on to
    contact; spread 0 first, each spread's distances from 80 mm outwards."""
    space = square_space(handle_model, TURNED.as_matrix(), SEED_POS)
    assert space is not None
    found = square_pinches(handle_model, TURNED.as_matrix(), SEED_POS, PlannerParams())
    assert len(found) >= len(SQUARE_DISTANCES_M)
    z = space.seed_rot[:, 2]
    front = space.seed_pos + z * space.pivot_m
    order = []
    for cand in found:
        rel = front - np.asarray(cand.position)
        assert np.linalg.norm(rel - float(rel @ z) * z) < 1e-6  # on the square through the axis
        distance = float(rel @ z)
        assert min(SQUARE_DISTANCES_M) - 1e-6 <= distance <= max(SQUARE_DISTANCES_M) + 1e-6
        spread = int(np.argmin([abs(float(cand.closed[0]) - s) for s in SQUARE_SPREADS_RAD]))
        order.append((spread, abs(distance - 0.08)))
    assert order == sorted(order, key=lambda o: (o[0], round(o[1], 4)))


@pytest.mark.slow
def test_benchmark_handle_that_no_near_grasp_holds_is_held_by_a_square_pinch() -> None:
    """The benchmark's handle r12 l140 (seed 11), 19 mm before its plate: fingers closing from near the demonstrated
    palm meet the plate first, and at the eleventh session no grasp the planner tried held it. The planned grasp is
    a pinch square to the bar with a force closure, 60-100 mm before it, and it holds the exact handle under the
    benchmark's hold test."""
    planned = plan_bench_object(11, "handle r12 l140mm horizontal")
    grasp = planned.grasp
    assert grasp.quality["force_closure"] is True
    x = Rotation.from_quat(grasp.wrist_orientation).apply([1.0, 0.0, 0.0])
    assert abs(float(x[0])) == pytest.approx(1.0, abs=0.01)  # along the bar (world x): square to it
    held_back = float((planned.seed_pos - np.asarray(grasp.wrist_position)) @ planned.approach)
    assert held_back > 0.03  # a pinch: the palm behind the demonstrated one
    assert math.degrees(grasp.quality["demo_angle_rad"]) > 5.0  # not the demonstrated orientation
    assert planned.holds
