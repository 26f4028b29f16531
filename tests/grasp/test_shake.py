"""Shake test: a wrapping grasp of a box holds, a hand that does not reach it drops it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from schemas.descriptor import Grasp
from tasks.grasp.object_model import ObjectModel, build_object_model
from tasks.grasp.shake import Motion, ShakeParams, hold_check, shake_test
from tests.grasp.surface_sampling import sample_box_surface

from .conftest import PALM_DOWN

BOX_CENTER = np.array([0.5, 0.0, 0.3])
BOX_HALF = np.array([0.025, 0.025, 0.04])


@pytest.fixture
def box() -> ObjectModel:
    """A 50 x 50 x 80 mm box (sampled surface points) standing at BOX_CENTER."""
    rng = np.random.default_rng(0)
    pts, _ = sample_box_surface(BOX_HALF, 3000, rng)
    return build_object_model(pts + BOX_CENTER, rng)


def _palm_on_top(a1: float, a2: float, above_m: float = 0.0015) -> Grasp:
    pos = BOX_CENTER + np.array([0.0, 0.0, BOX_HALF[2] + above_m])  # palm above the box top, looking down
    quat = (float(PALM_DOWN[0]), float(PALM_DOWN[1]), float(PALM_DOWN[2]), float(PALM_DOWN[3]))
    return Grasp("barrett", (a1, a2), (float(pos[0]), float(pos[1]), float(pos[2])), quat)


def test_wrapping_grasp_holds(box: ObjectModel) -> None:
    result = shake_test(box, _palm_on_top(-1.13, -1.37), hold_check(PALM_DOWN))  # spread 0, closed onto the sides
    assert result.holds
    assert result.max_shift_m < 0.005


def test_a_hand_that_does_not_reach_the_box_drops_it(box: ObjectModel) -> None:
    result = shake_test(box, _palm_on_top(-1.13, -1.37, above_m=0.15))  # the fingertips close above the box
    assert not result.holds
    assert result.max_shift_m > ShakeParams().max_shift_m  # it fell (the test stops once past the tolerance)
    assert result.survived_s < 0.5


def test_wrapping_grasp_holds_under_a_harsher_program(box: ObjectModel) -> None:
    grasp = _palm_on_top(-1.13, -1.37)
    harsh = ShakeParams(
        gravity=((0.0, 0.0, -9.81), (4.0, 3.0, -8.4)),
        motions=(
            Motion((0.6, 0.0, 0.8), 0.012, 3.5, 3.0),
            Motion((0.0, 1.0, 0.0), math.radians(8.0), 2.0, 3.0, turn=True),
        ),
    )
    result = shake_test(box, grasp, harsh)
    assert result.holds
    assert result.max_shift_m < 0.006
