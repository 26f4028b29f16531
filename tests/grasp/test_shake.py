"""Shake test: a wrapping grasp of a handle holds, an open hand drops it."""

from __future__ import annotations

import numpy as np

from schemas.descriptor import Grasp
from tasks.arrays import Points
from tasks.grasp.object_model import build_object_model
from tasks.grasp.shake import ShakeParams, shake_test

from .conftest import HANDLE_CENTER, PALM_DOWN


def _grasp_on_top(a1: float, a2: float) -> Grasp:
    pos = HANDLE_CENTER + np.array([0.0, 0.0, 0.0215])  # palm 1.5 mm above the 20 mm radius handle
    quat = (float(PALM_DOWN[0]), float(PALM_DOWN[1]), float(PALM_DOWN[2]), float(PALM_DOWN[3]))
    return Grasp("barrett", (a1, a2), (float(pos[0]), float(pos[1]), float(pos[2])), quat)


def test_wrapping_grasp_holds(handle_points: tuple[Points, Points]) -> None:
    model = build_object_model(handle_points[0], np.random.default_rng(0))
    result = shake_test(model, _grasp_on_top(-1.13, -1.37))  # spread 0, fingers open, then closed to contact
    assert result.holds
    assert result.max_shift_m < 0.005


def test_open_hand_drops(handle_points: tuple[Points, Points]) -> None:
    model = build_object_model(handle_points[0], np.random.default_rng(0))
    result = shake_test(model, _grasp_on_top(-1.13, -1.37), ShakeParams(close=False))
    assert not result.holds
    assert result.max_shift_m > 0.05  # it fell
