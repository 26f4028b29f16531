"""Cylinders found in a part's points: the bar of a handle on its plate is found to a fraction of a millimetre and
planned on as one exact piece; a box, a plate and a sphere give none."""

from __future__ import annotations

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from tasks.grasp.object_model import (
    ObjectModel,
    PrimitiveShape,
    build_object_model,
    estimate_normals,
    load_object,
    voxel_downsample,
)
from tasks.grasp.part_cylinders import find_cylinder, prism_vertices
from tests.grasp.cases.exact import labelled_model
from tests.grasp.cases.grasp import handle_on_plate
from tests.grasp.surface_sampling import sample_box_surface

PALM_OFFSET = np.array([0.0, -0.06, 0.0])
"""The demonstrated palm 60 mm in front (-y) of a handle's bar, looking along +y."""


def _scanned(points: np.ndarray, viewpoint: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """4 mm voxels of ``points`` and their normals oriented from ``viewpoint``, as the planner builds them."""
    pts = voxel_downsample(points, 0.004)
    return pts, estimate_normals(pts, viewpoint=viewpoint)


def test_the_bar_of_a_horizontal_handle_is_found() -> None:
    rng = np.random.default_rng(3)
    pts, centre = handle_on_plate(0.011, 0.15, 0.04, False, rng)
    grip, nrm = _scanned(pts[:-1500], centre + PALM_OFFSET)  # bar and posts, the plate left out
    found = find_cylinder(grip, nrm, np.random.default_rng(0))
    assert found is not None and found.shape.kind == "cylinder"
    assert abs(found.shape.size[0] - 0.011) < 0.0005
    assert abs(2.0 * found.shape.size[1] - 0.15) < 0.004
    axis = Rotation.from_quat(found.shape.quat_xyzw).apply([0.0, 0.0, 1.0])
    assert abs(axis[0]) > np.cos(np.radians(1.0))  # along world x
    np.testing.assert_allclose(found.shape.position, centre, atol=0.001)


def test_a_box_a_plate_and_a_sphere_give_no_cylinder() -> None:
    rng = np.random.default_rng(4)
    view = np.array([0.0, -0.3, 0.0])
    box, _ = sample_box_surface(np.array([0.03, 0.04, 0.05]), 3000, rng)
    plate, _ = sample_box_surface(np.array([0.08, 0.005, 0.1]), 3000, rng)
    sphere = rng.normal(size=(3000, 3))
    sphere = 0.03 * sphere / np.linalg.norm(sphere, axis=1, keepdims=True)
    for points in (box, plate, sphere):
        pts, nrm = _scanned(points, view)
        assert find_cylinder(pts, nrm, np.random.default_rng(0)) is None


def test_prism_vertices_lie_on_the_cylinder() -> None:
    turn = Rotation.from_euler("xz", [30.0, 50.0], degrees=True)
    q = turn.as_quat()
    shape = PrimitiveShape("cylinder", (0.015, 0.06, 0.0), (0.1, 0.2, 0.3), (q[0], q[1], q[2], q[3]))
    local = turn.inv().apply(prism_vertices(shape) - np.array([0.1, 0.2, 0.3]))
    np.testing.assert_allclose(np.hypot(local[:, 0], local[:, 1]), 0.015, atol=1e-12)
    np.testing.assert_allclose(np.abs(local[:, 2]), 0.06, atol=1e-12)


def test_a_mounted_handle_is_planned_on_its_bar_and_the_truth_is_not_fitted() -> None:
    rng = np.random.default_rng(5)
    pts, centre = handle_on_plate(0.012, 0.14, 0.04, True, rng)
    palm = centre + PALM_OFFSET
    model = build_object_model(pts, rng, viewpoint=palm, approach=np.array([0.0, 1.0, 0.0]))
    assert model.mount is not None and model.mount_parts > 0
    assert model.cylinder is not None and abs(model.cylinder.size[0] - 0.012) < 0.0005
    assert model.primitive is None
    bar = model.parts[0]  # the prism: 128 vertices at the bar's radius about the world z line through the centre
    assert len(bar) == 128
    np.testing.assert_allclose(np.hypot(*(bar[:, :2] - centre[:2]).T), 0.012, atol=0.0005)
    pieces = build_object_model(pts, rng, viewpoint=palm, approach=np.array([0.0, 1.0, 0.0]), fit=False)
    assert pieces.cylinder is None and max(len(p) for p in pieces.parts) < 128
    assert pieces.primitive is None
    truth = labelled_model(pts[:-1500], pts[-1500:], rng, viewpoint=palm)
    assert truth.cylinder is None and max(len(p) for p in truth.parts) < 128


def test_a_bar_collides_round_not_as_its_prism() -> None:
    """The model's bar collides as a round cylinder of its radius and length, fixed or free (the part without its
    mount, as the hold check shakes it): no facets of its 64-sided prism for a fingertip's flat pad to seat on. A
    probe 13 mm from the axis is 3 mm from it (Bullet's closest points, to GJK's tolerance) at any azimuth."""
    quat = Rotation.from_euler("y", 90, degrees=True).as_quat()
    bar = PrimitiveShape("cylinder", (0.01, 0.05, 0.0), (0.5, 0.0, 0.5), tuple(float(q) for q in quat))
    plate = np.array([[x, 0.03 + d, z] for x in (0.4, 0.6) for d in (0.0, 0.01) for z in (0.45, 0.55)])
    points = np.concatenate([prism_vertices(bar), plate])
    mount = np.arange(len(points)) >= 128
    model = ObjectModel(
        points, np.zeros_like(points), bar.position, 0.05, (prism_vertices(bar), plate), None, mount, 1, bar
    )
    for body_model, mass in ((model, 0.0), (model.without_mount(), 0.3)):
        client = pb.connect(pb.DIRECT)
        try:
            obj = load_object(client, body_model, mass_kg=mass)
            (shape,) = pb.getCollisionShapeData(obj, -1, physicsClientId=client)
            assert shape[2] == pb.GEOM_CYLINDER
            np.testing.assert_allclose(shape[3][:2], (0.1, 0.01))
            sphere = pb.createCollisionShape(pb.GEOM_SPHERE, radius=1e-4, physicsClientId=client)
            probe = pb.createMultiBody(0.0, sphere, physicsClientId=client)
            for azimuth in np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False):
                radial = Rotation.from_quat(quat).apply([np.cos(azimuth), np.sin(azimuth), 0.0])
                at = np.array(bar.position) + 0.0131 * radial
                pb.resetBasePositionAndOrientation(probe, at.tolist(), [0, 0, 0, 1], physicsClientId=client)
                (hit,) = [p for p in pb.getClosestPoints(probe, obj, 0.01, physicsClientId=client) if p[4] == -1]
                assert abs(hit[8] - 0.003) < 5e-5
        finally:
            pb.disconnect(client)
