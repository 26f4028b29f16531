"""The planner: contact energy, the annealing schedule, and a force-closure grasp on a box and a handle."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.grasp.anneal import ILLEGAL_ENERGY, Schedule, ingber_draw
from tasks.grasp.api import plan_grasp
from tasks.grasp.object_model import build_object_model
from tasks.grasp.planner import contact_energy
from tasks.hand import barrett

from .conftest import HANDLE_CENTER, PALM_DOWN


def test_graspit_online_schedule() -> None:
    s = Schedule()
    assert s.neighbour_temperature(100) == pytest.approx(10.0 * math.exp(-0.24 * 10.0))
    assert s.accept_temperature(1000) == pytest.approx(10.0 * math.exp(-0.54 * 10.0))
    draws = ingber_draw(0.05, 10000, np.random.default_rng(0))
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


def test_planner_finds_force_closure_on_a_box(box_points: Points) -> None:
    seed = np.array([0.5, 0.1, 0.3 + 0.04 + 0.05])  # 50 mm above the box top, looking down
    grasp = plan_grasp(box_points, seed, PALM_DOWN, np.random.default_rng(3))
    assert grasp.hand == "barrett"
    assert grasp.quality["force_closure"] is True
    assert grasp.quality["epsilon"] > 0.0
    assert grasp.quality["volume"] > 0.0
    assert all(abs(a) <= 4.0 for a in grasp.eigengrasps)
    assert np.linalg.norm(np.array(grasp.wrist_position) - seed) < 0.2


def test_planner_is_deterministic_for_a_seeded_rng(handle_points: tuple[Points, Points]) -> None:
    seed = HANDLE_CENTER + np.array([0, 0, 0.06])
    a = plan_grasp(handle_points[0], seed, PALM_DOWN, np.random.default_rng(5))
    b = plan_grasp(handle_points[0], seed, PALM_DOWN, np.random.default_rng(5))
    assert a == b
    assert a.quality["force_closure"] is True
