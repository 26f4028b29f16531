"""The planner's wrist-error check (``execution.robust``): a grasp must survive the palm placed a few millimetres
and degrees off the plan, as a robot places it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.grasp.api import plan_on_model
from tasks.grasp.execution import WRIST_ERROR_M, WRIST_ERROR_RAD, displaced_poses, hand_and_object, robust
from tasks.grasp.object_model import build_object_model
from tasks.grasp.quality import DEFAULT_MU

from .conftest import PALM_DOWN


def test_displaced_poses_move_or_turn_the_palm_by_the_stated_error() -> None:
    rot = Rotation.from_euler("xyz", [20.0, -35.0, 70.0], degrees=True).as_matrix()
    pos = np.array([0.4, -0.1, 0.9])
    poses = displaced_poses(rot, pos)
    assert len(poses) == 12
    moved = [(r, p) for r, p in poses if not np.allclose(p, pos)]
    turned = [(r, p) for r, p in poses if np.allclose(p, pos)]
    assert len(moved) == len(turned) == 6
    for r, p in moved:
        np.testing.assert_allclose(r, rot)
        step = (p - pos) @ rot  # in the palm frame: along one palm axis only
        assert np.linalg.norm(step) == pytest.approx(WRIST_ERROR_M)
        assert np.count_nonzero(np.abs(step) > 1e-9) == 1
    for r, _ in turned:
        turn = Rotation.from_matrix(r @ rot.T).as_rotvec()
        assert np.linalg.norm(turn) == pytest.approx(WRIST_ERROR_RAD)
        assert np.count_nonzero(np.abs(rot.T @ turn) > 1e-9) == 1  # about one palm axis


def test_a_planned_box_grasp_survives_the_wrist_error_and_a_pressed_or_one_finger_one_does_not(
    box_points: Points,
) -> None:
    seed = np.array([0.5, 0.1, 0.3 + 0.04 + 0.05])  # 50 mm above the box top, looking down
    model = build_object_model(box_points, np.random.default_rng(3), viewpoint=seed)
    planned = plan_on_model(model, seed, PALM_DOWN, np.random.default_rng(3))
    pressed_at = np.array([planned.position[0], planned.position[1], 0.3 + 0.04 - 0.005])
    pressed = dataclasses.replace(planned, position=pressed_at)  # the palm face 5 mm into the box's top
    one_finger = dataclasses.replace(planned, fingers=planned.fingers[:1])
    with hand_and_object(model) as ids:
        assert robust(ids, model, planned, DEFAULT_MU)
        assert not robust(ids, model, pressed, DEFAULT_MU)
        assert not robust(ids, model, one_finger, DEFAULT_MU)
