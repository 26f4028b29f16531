"""The benchmark's exact hold-test models (``tests/grasp/cases/exact.py``): a handle's bar, posts and plate and a
scene's grasped part on the shapes around it, each one exact convex piece; a grasp planned on a scanned handle
holds its exact shapes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.grasp.api import plan_grasp
from tasks.grasp.shake import hold_check, shake_test
from tasks.scenes.catalog import build_scene
from tests.grasp.cases.exact import exact_model, handle_shapes, hull_vertices
from tests.grasp.cases.grasp import grasped_shapes, handle_on_plate, scene_cases


def test_a_handles_exact_model_is_its_bar_and_posts_on_its_plate() -> None:
    part, mount = handle_shapes(0.012, 0.14, 0.04, False)
    model = exact_model(part, mount, np.random.default_rng(0))
    assert len(model.parts) == 4 and model.mount_parts == 1
    bar = model.parts[0]  # along world x through (0.5, 0, 0.5), radius 12 mm, 140 mm long
    np.testing.assert_allclose(np.hypot(bar[:, 1], bar[:, 2] - 0.5), 0.012, atol=1e-9)
    np.testing.assert_allclose(np.abs(bar[:, 0] - 0.5), 0.07, atol=1e-9)
    plate = model.parts[3]  # 10 mm thick, its near face 40 mm behind the bar's axis
    np.testing.assert_allclose(sorted(set(np.round(plate[:, 1], 6))), [0.04, 0.05], atol=1e-9)
    assert len(model.without_mount().parts) == 3


def test_a_scenes_exact_model_is_its_part_on_the_shapes_near_the_palm() -> None:
    scene = build_scene("door", 0)
    case = next(c for c in scene_cases(range(1)) if c.name == "door seed 0")
    model = case.truth(np.random.default_rng(0))
    lever = grasped_shapes(scene)
    assert len(model.parts) - model.mount_parts == len(lever) == 3
    for piece, shape in zip(model.parts, lever, strict=False):
        np.testing.assert_allclose(piece, hull_vertices(shape))
    # the door leaf is in the mount: a piece over 0.8 m wide
    assert any(np.ptp(p, axis=0).max() > 0.8 for p in model.parts[len(lever) :])


@pytest.mark.slow
def test_a_grasp_planned_on_a_scanned_handle_holds_its_exact_shapes() -> None:
    rng = np.random.default_rng(8)
    pts, centre = handle_on_plate(0.012, 0.14, 0.04, True, rng)
    x, z = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])  # palm x along the bar, looking at the plate
    palm = Rotation.from_matrix(np.stack([x, np.cross(z, x), z], axis=1)).as_quat()
    grasp = plan_grasp(pts, centre - np.array([0.0, 0.05, 0.0]), palm, np.random.default_rng(0))
    assert grasp.quality["force_closure"]
    model = exact_model(*handle_shapes(0.012, 0.14, 0.04, True), np.random.default_rng(0))
    assert shake_test(model, grasp, hold_check(np.asarray(grasp.wrist_orientation))).holds
