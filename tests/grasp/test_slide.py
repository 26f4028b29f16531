"""Grasps slid along a bar (``slide.py``): on a handle whose bar was found, the demonstrated palm moved along the bar
and held back on its approach, in the demonstrated orientation, the shortest slides first; none without a bar."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.grasp.object_model import build_object_model
from tasks.grasp.planner import PlannerParams
from tasks.grasp.slide import HOLD_BACKS_M, SLIDES_M, slide_candidates
from tests.grasp.cases.grasp import handle_on_plate

PALM = Rotation.from_matrix(np.column_stack([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]))
"""Palm x along world x (a horizontal bar), approach (+z) along world +y towards the plate."""


def test_slides_lie_along_the_bar_held_back_shortest_first() -> None:
    rng = np.random.default_rng(2)
    pts, centre = handle_on_plate(0.012, 0.16, 0.04, False, rng)
    seed = centre - np.array([0.0, 0.05, 0.0])
    model = build_object_model(pts, rng, viewpoint=seed, approach=np.array([0.0, 1.0, 0.0]))
    assert model.cylinder is not None
    found = list(slide_candidates(model, PALM.as_matrix(), seed, PlannerParams()))
    assert 8 <= len(found) <= 2 * 2 * len(SLIDES_M) * len(HOLD_BACKS_M)
    moves = []
    for cand in found:
        rel = cand.position - seed
        assert abs(rel[2]) < 1e-4  # along the fitted bar (world x) and the approach (world y)
        assert min(abs(abs(rel[0]) - s) for s in SLIDES_M) < 1e-4
        # held back, never advanced (an open hand in collision is backed off up to 20 mm, ``planner.evaluate_pose``)
        assert min(HOLD_BACKS_M) - 1e-4 <= -rel[1] <= max(HOLD_BACKS_M) + 0.02 + 1e-4
        assert cand.angle_rad == pytest.approx(0.0, abs=1e-6)
        assert cand.offset_m == pytest.approx(float(np.hypot(rel[0], rel[1])), abs=1e-6)
        moves.append(abs(float(rel[0])))
    assert moves[0] == pytest.approx(min(SLIDES_M), abs=1e-4)  # the shortest slide first
    assert moves == sorted(moves, key=lambda m: round(m, 3))


def test_no_slides_without_a_bar() -> None:
    rng = np.random.default_rng(3)
    pts, centre = handle_on_plate(0.012, 0.16, 0.04, False, rng)
    seed = centre - np.array([0.0, 0.05, 0.0])
    model = build_object_model(pts, rng, viewpoint=seed, approach=np.array([0.0, 1.0, 0.0]), fit=False)
    assert model.cylinder is None
    assert list(slide_candidates(model, PALM.as_matrix(), seed, PlannerParams())) == []
