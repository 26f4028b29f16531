"""Planning on a fitted primitive: a scanned box or cylinder becomes the model's primitive, a handle on its plate
keeps its convex pieces, and the grasp planned on the fit holds the exact shape."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.grasp.api import plan_grasp
from tasks.grasp.object_model import build_object_model
from tasks.grasp.primitive_fit import PrimitiveShape
from tasks.grasp.shake import hold_check, shake_test
from tests.grasp.cases.exact import primitive_model
from tests.grasp.cases.grasp import handle_on_plate
from tests.grasp.surface_sampling import sample_box_surface, sample_cylinder_surface

CENTRE = np.array([0.5, 0.0, 0.4])


def _scan_of_box(rng: np.random.Generator) -> tuple[np.ndarray, Rotation]:
    """A 40 x 60 x 100 mm box turned 25° about z and 10° about x at CENTRE, 3000 points with 0.3 mm noise."""
    turn = Rotation.from_euler("zx", [25.0, 10.0], degrees=True)
    pts, _ = sample_box_surface(np.array([0.02, 0.03, 0.05]), 3000, rng)
    return turn.apply(pts) + CENTRE + rng.normal(0.0, 0.0003, pts.shape), turn


def test_a_scanned_box_becomes_its_fitted_box_and_fit_false_keeps_pieces() -> None:
    rng = np.random.default_rng(4)
    pts, turn = _scan_of_box(rng)
    model = build_object_model(pts, rng, viewpoint=CENTRE + np.array([0.0, -0.2, 0.0]))
    assert model.primitive is not None and model.primitive.kind == "box"
    assert model.parts == ()
    np.testing.assert_allclose(sorted(model.primitive.size), [0.02, 0.03, 0.05], atol=0.001)
    np.testing.assert_allclose(model.primitive.position, CENTRE, atol=0.001)
    # each face direction of the fit is one of the true box's, within 2°
    fitted = Rotation.from_quat(model.primitive.quat_xyzw).as_matrix()
    cosines = np.abs(fitted.T @ turn.as_matrix())
    assert np.all(cosines.max(axis=1) > np.cos(np.radians(2.0)))
    pieces = build_object_model(pts, rng, viewpoint=CENTRE + np.array([0.0, -0.2, 0.0]), fit=False)
    assert pieces.primitive is None and len(pieces.parts) > 4


def test_a_handle_on_its_plate_keeps_its_convex_pieces() -> None:
    rng = np.random.default_rng(5)
    pts, centre = handle_on_plate(0.012, 0.14, 0.04, True, rng)
    palm = centre - np.array([0.0, 0.06, 0.0])
    model = build_object_model(pts, rng, viewpoint=palm, approach=np.array([0.0, 1.0, 0.0]))
    assert model.primitive is None
    assert model.mount is not None and model.mount_parts > 0
    bar_alone = build_object_model(pts[:1500], rng, viewpoint=palm)  # the bar without posts or plate: a cylinder
    assert bar_alone.primitive is not None and bar_alone.primitive.kind == "cylinder"
    assert abs(bar_alone.primitive.size[0] - 0.012) < 0.001


@pytest.mark.slow
def test_a_grasp_planned_on_a_fitted_cylinder_holds_the_exact_cylinder() -> None:
    rng = np.random.default_rng(6)
    pts, _ = sample_cylinder_surface(0.03, 0.07, 3000, rng)
    scan = pts + CENTRE + rng.normal(0.0, 0.0003, pts.shape)
    # the palm 40 mm in front of the upright cylinder, looking along +y, its x axis along the cylinder
    x, z = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])
    palm_rot = Rotation.from_matrix(np.stack([x, np.cross(z, x), z], axis=1))
    palm = CENTRE - np.array([0.0, 0.07, 0.0])
    model = build_object_model(scan, np.random.default_rng(0), viewpoint=palm, approach=z)
    assert model.primitive is not None and model.primitive.kind == "cylinder"
    grasp = plan_grasp(scan, palm, palm_rot.as_quat(), np.random.default_rng(0))
    assert grasp.quality["force_closure"]
    exact = PrimitiveShape("cylinder", (0.03, 0.07, 0.0), (float(CENTRE[0]), float(CENTRE[1]), float(CENTRE[2])))
    truth = primitive_model(scan, exact)
    assert shake_test(truth, grasp, hold_check(np.asarray(grasp.wrist_orientation))).holds
