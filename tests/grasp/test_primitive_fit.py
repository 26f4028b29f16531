"""Box and cylinder fits of object point clouds: recovered poses and sizes, and the shapes that are neither."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.grasp.object_model import estimate_normals, voxel_downsample
from tasks.grasp.primitive_fit import (
    RMS_FRACTION,
    TOLERANCE_M,
    PrimitiveFit,
    PrimitiveShape,
    fit_box,
    fit_cylinder,
    fit_primitive,
    surface_distance,
    tolerance,
)
from tests.grasp.surface_sampling import sample_box_surface, sample_cylinder_surface

NOISE_M = 0.0003
"""Gaussian noise added to every sampled coordinate, metres."""


def _scan(points: Points, rng: np.random.Generator, noise_m: float = NOISE_M) -> tuple[Points, Points]:
    """Noisy points downsampled to 4 mm voxels and their estimated normals, as the planner builds its model."""
    noisy = voxel_downsample(points + rng.normal(0.0, noise_m, points.shape), 0.004)
    return noisy, estimate_normals(noisy)


def _posed(points: Points, seed: int) -> tuple[Points, Rotation, np.ndarray]:
    """``points`` under a random rotation and a translation within 0.5 m (from ``seed``), with the motion."""
    rng = np.random.default_rng(seed + 100)
    rot = Rotation.random(random_state=seed)
    shift = rng.uniform(-0.5, 0.5, 3)
    return rot.apply(points) + shift, rot, shift


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two lines (sign free), degrees."""
    cos = abs(float(a @ b)) / float(np.linalg.norm(a) * np.linalg.norm(b))
    return math.degrees(math.acos(min(cos, 1.0)))


def _axes(shape: PrimitiveShape) -> np.ndarray:
    """(3, 3) columns: the shape's local axes in the world."""
    out: np.ndarray = Rotation.from_quat(shape.quat_xyzw).as_matrix()
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(
    ("half", "n"),
    [((0.015, 0.04, 0.06), 2500), ((0.03, 0.031, 0.033), 1500), ((0.035, 0.035, 0.035), 3000)],
    ids=["thin", "near-cubic", "cube"],
)
def test_box_pose_and_size_recovered(half: tuple[float, float, float], n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    pts, _ = sample_box_surface(np.array(half), n, rng)
    posed, rot, shift = _posed(pts, seed)
    fit = fit_primitive(*_scan(posed, rng))
    assert fit is not None
    assert fit.shape.kind == "box"
    assert np.linalg.norm(np.array(fit.shape.position) - shift) < 0.001
    fitted = _axes(fit.shape)
    true_axes = rot.as_matrix()
    for k in range(3):
        # the fitted axis along true axis k (for a cube any of them: then the nearest)
        match = int(np.argmax(np.abs(true_axes[:, k] @ fitted)))
        assert _angle_deg(true_axes[:, k], fitted[:, match]) < 2.0
        assert abs(fit.shape.size[match] - half[k]) < 0.001
    assert fit.p95_m < TOLERANCE_M


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(
    ("radius", "half_height", "n"), [(0.015, 0.08, 2000), (0.04, 0.02, 2500)], ids=["long", "squat"]
)
def test_cylinder_pose_and_size_recovered(radius: float, half_height: float, n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    pts, _ = sample_cylinder_surface(radius, half_height, n, rng)
    posed, rot, shift = _posed(pts, seed)
    fit = fit_primitive(*_scan(posed, rng))
    assert fit is not None
    assert fit.shape.kind == "cylinder"
    assert np.linalg.norm(np.array(fit.shape.position) - shift) < 0.001
    assert _angle_deg(_axes(fit.shape)[:, 2], rot.apply([0.0, 0.0, 1.0])) < 2.0
    assert abs(fit.shape.size[0] - radius) < 0.001
    assert abs(fit.shape.size[1] - half_height) < 0.001
    assert fit.shape.size[2] == 0.0


def test_surface_distance_is_to_the_surface_not_the_solid() -> None:
    box = PrimitiveShape(
        "box", (0.01, 0.02, 0.03), (1.0, 0.0, 0.0), tuple(Rotation.from_euler("z", 90, degrees=True).as_quat())
    )
    # world x is the box's -y: the centre lies 10 mm inside its nearest face, a face point on it, a corner 3 mm out
    probe = np.array([[1.0, 0.0, 0.0], [1.0, 0.01, 0.0], [1.0, 0.0, 0.03], [1.022, 0.01, 0.03 + 0.002]])
    np.testing.assert_allclose(surface_distance(box, probe), [0.01, 0.0, 0.0, math.hypot(0.002, 0.002)], atol=1e-12)
    cylinder = PrimitiveShape("cylinder", (0.02, 0.05, 0.0), (0.0, 0.0, 0.0))
    probe = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.01], [0.01, 0.0, 0.05], [0.0, 0.0, 0.04], [0.023, 0.0, 0.054]])
    np.testing.assert_allclose(surface_distance(cylinder, probe), [0.02, 0.0, 0.0, 0.01, 0.005], atol=1e-12)


def _sphere(rng: np.random.Generator, radius_m: float = 0.04) -> Points:
    """2500 points on a sphere (radius 40 mm unless given)."""
    v = rng.normal(size=(2500, 3))
    out: Points = radius_m * v / np.linalg.norm(v, axis=1, keepdims=True)
    return out


def _box_with_cylinder_on_top(rng: np.random.Generator) -> Points:
    """A 60 x 60 x 80 mm box with a cylinder (r 15 mm, 40 mm high) standing on its top, the contact hidden."""
    box, _ = sample_box_surface(np.array([0.03, 0.03, 0.04]), 2000, rng)
    can, _ = sample_cylinder_surface(0.015, 0.02, 600, rng)
    can += [0.0, 0.0, 0.06]
    box = box[~((box[:, 2] > 0.0399) & (np.hypot(box[:, 0], box[:, 1]) < 0.015))]
    out: Points = np.concatenate([box, can[can[:, 2] > 0.0401]])
    return out


def _l_shape(rng: np.random.Generator) -> Points:
    """An L of two boxes: a 120 x 40 x 40 mm bar and a 40 x 40 x 80 mm block on its end, the joint face hidden."""
    bar, _ = sample_box_surface(np.array([0.06, 0.02, 0.02]), 2000, rng)
    block, _ = sample_box_surface(np.array([0.02, 0.02, 0.04]), 1500, rng)
    block += [0.04, 0.0, 0.06]
    bar = bar[~((bar[:, 2] > 0.0199) & (bar[:, 0] > 0.02))]
    out: Points = np.concatenate([bar, block[block[:, 2] > 0.0201]])
    return out


@pytest.mark.parametrize("make", [_sphere, _box_with_cylinder_on_top, _l_shape], ids=["sphere", "box+can", "L"])
def test_shapes_that_are_neither_give_none(make: Callable[[np.random.Generator], Points]) -> None:
    rng = np.random.default_rng(3)
    posed, _, _ = _posed(make(rng), 3)
    pts, nrm = _scan(posed, rng)
    assert fit_primitive(pts, nrm) is None
    # rejected because no surface explains the points (both best fits are far off), not for want of a fit
    fits = [fit_box(pts, nrm), fit_cylinder(pts, nrm)]
    assert all(f is not None and f.p95_m > 2 * TOLERANCE_M for f in fits)


@pytest.mark.parametrize(
    ("radius", "length", "standoff", "vertical"), [(0.008, 0.10, 0.03, True), (0.016, 0.18, 0.05, False)]
)
def test_bar_handle_on_its_posts_gives_none(radius: float, length: float, standoff: float, vertical: bool) -> None:
    from tests.grasp.cases.grasp import PLATE_POINTS, handle_on_plate

    rng = np.random.default_rng(5)
    pts, _ = handle_on_plate(radius, length, standoff, vertical, rng)
    scan = _scan(pts[:-PLATE_POINTS], rng)
    assert fit_primitive(*scan) is None
    cylinder = fit_cylinder(*scan)
    assert cylinder is not None
    assert cylinder.rms_m > 2 * TOLERANCE_M  # the posts are off the bar's surface


def _seen_from(points: Points, normals: Points, view: list[float]) -> Points:
    """The points whose true normals face the direction ``view`` (a distant viewer's)."""
    out: Points = points[normals @ (np.array(view) / np.linalg.norm(view)) > 0.05]
    return out


def test_one_view_of_a_box_fits_and_two_faces_do_not() -> None:
    rng = np.random.default_rng(6)
    pts, nrm = sample_box_surface(np.array([0.015, 0.04, 0.06]), 3000, rng)
    three = fit_primitive(*_scan(_seen_from(pts, nrm, [1.0, 1.0, 1.0]), rng))
    assert three is not None
    assert three.shape.kind == "box"
    # the seen faces are where they are; the far ones where the seen faces end
    np.testing.assert_allclose(np.sort(three.shape.size), [0.015, 0.04, 0.06], atol=0.0015)
    two = _scan(_seen_from(pts, nrm, [1.0, 1.0, 0.0]), rng)
    assert fit_primitive(*two) is None
    box = fit_box(*two)
    assert box is not None
    assert box.p95_m < TOLERANCE_M  # the surface fits: the box is refused for the unseen top and bottom


def test_one_view_of_a_cylinder_fits_and_a_quarter_does_not() -> None:
    rng = np.random.default_rng(7)
    pts, nrm = sample_cylinder_surface(0.02, 0.06, 3000, rng)
    half = fit_primitive(*_scan(_seen_from(pts, nrm, [1.0, 0.0, 0.3]), rng))
    assert half is not None
    assert half.shape.kind == "cylinder"
    assert abs(half.shape.size[0] - 0.02) < 0.001
    strip = np.abs(np.arctan2(pts[:, 1], pts[:, 0])) < math.radians(45.0)
    quarter = _scan(pts[strip & (np.abs(pts[:, 2]) < 0.0599)], rng)
    assert fit_primitive(*quarter) is None
    cylinder = fit_cylinder(*quarter)
    assert cylinder is not None
    assert cylinder.p95_m < TOLERANCE_M  # the surface fits: refused for the 90° arc


def test_tolerance_decides_for_a_rough_scan() -> None:
    rng = np.random.default_rng(8)
    pts, _ = sample_box_surface(np.array([0.03, 0.04, 0.05]), 3000, rng)
    scan = _scan(pts, rng, noise_m=0.002)
    assert fit_primitive(*scan) is None
    loose = fit_primitive(*scan, tolerance_m=0.006)
    assert loose is not None
    assert loose.shape.kind == "box"
    assert loose.p95_m > TOLERANCE_M


def test_few_points_give_none() -> None:
    rng = np.random.default_rng(9)
    pts, nrm = sample_box_surface(np.array([0.03, 0.03, 0.03]), 29, rng)
    assert fit_primitive(pts, nrm) is None
    many, many_nrm = sample_box_surface(np.array([0.03, 0.03, 0.03]), 400, rng)
    assert isinstance(fit_primitive(many, many_nrm), PrimitiveFit)


def test_rigid_motion_moves_the_fit_with_it() -> None:
    rng = np.random.default_rng(10)
    pts, _ = sample_cylinder_surface(0.025, 0.05, 2500, rng)
    scan, normals = _scan(pts, rng)
    rot, shift = Rotation.from_euler("xyz", [30.0, -50.0, 110.0], degrees=True), np.array([0.2, -0.1, 0.7])
    here, there = fit_primitive(scan, normals), fit_primitive(rot.apply(scan) + shift, rot.apply(normals))
    assert here is not None
    assert there is not None
    np.testing.assert_allclose(rot.apply(here.shape.position) + shift, there.shape.position, atol=2e-5)
    assert _angle_deg(rot.apply(_axes(here.shape)[:, 2]), _axes(there.shape)[:, 2]) < 0.05
    np.testing.assert_allclose(here.shape.size, there.shape.size, atol=2e-5)


def test_a_knob_on_a_box_is_caught_by_the_rms_and_ignored_by_the_refinement() -> None:
    rng = np.random.default_rng(12)
    box, _ = sample_box_surface(np.array([0.03, 0.04, 0.05]), 3000, rng)
    knob, _ = sample_cylinder_surface(0.005, 0.01, 200, rng)
    knob = Rotation.from_euler("y", 90, degrees=True).apply(knob) + np.array([0.04, 0.0, 0.0])
    box = box[~((box[:, 0] > 0.0299) & (np.hypot(box[:, 1], box[:, 2]) < 0.005))]
    scan = _scan(np.concatenate([box, knob[knob[:, 0] > 0.0301]]), rng)
    assert fit_primitive(*scan) is None
    fit = fit_box(*scan)
    assert fit is not None
    assert fit.p95_m < TOLERANCE_M  # the knob's 2 % of the points pass the 95th percentile
    assert fit.rms_m > RMS_FRACTION * TOLERANCE_M  # but not the RMS
    # the soft-L1 loss keeps the box where the faces are
    np.testing.assert_allclose(np.sort(fit.shape.size), [0.03, 0.04, 0.05], atol=0.001)
    np.testing.assert_allclose(fit.shape.position, [0.0, 0.0, 0.0], atol=0.001)


def test_tolerance_follows_the_object_size() -> None:
    assert tolerance(0.0015, 0.05) == pytest.approx(0.0015)
    assert tolerance(0.0015, 0.01) == pytest.approx(0.001)  # a tenth of the radius
    assert tolerance(0.0015, 0.003) == pytest.approx(0.0009)  # not below 0.6 of the given one
    assert tolerance(0.0015, 0.3) == pytest.approx(0.003)  # 1 % of the radius
    assert tolerance(0.0005, 0.01) == pytest.approx(0.0005)


@pytest.mark.parametrize("radius_m", [0.008, 0.01])
def test_small_sphere_gives_none(radius_m: float) -> None:
    rng = np.random.default_rng(13)
    scan = _scan(_sphere(rng, radius_m), rng)
    assert fit_primitive(*scan) is None
    cylinder = fit_cylinder(*scan)
    assert cylinder is not None
    assert cylinder.p95_m < TOLERANCE_M  # the flat 1.5 mm would take it for a cylinder


@pytest.mark.parametrize(
    ("make", "kind"),
    [
        (lambda rng: sample_cylinder_surface(0.005, 0.01, 1500, rng)[0], "cylinder"),
        (lambda rng: sample_box_surface(np.array([0.006, 0.006, 0.006]), 1500, rng)[0], "box"),
    ],
    ids=["pin r5 hh10", "cube 12 mm"],
)
def test_small_primitives_still_fit(make: Callable[[np.random.Generator], Points], kind: str) -> None:
    rng = np.random.default_rng(14)
    posed, _, shift = _posed(make(rng), 14)
    fit = fit_primitive(*_scan(posed, rng))
    assert fit is not None
    assert fit.shape.kind == kind
    assert np.linalg.norm(np.array(fit.shape.position) - shift) < 0.001


def test_noisy_normals_with_random_signs_still_fit() -> None:
    rng = np.random.default_rng(15)
    pts, _ = sample_box_surface(np.array([0.02, 0.035, 0.05]), 2500, rng)
    posed, rot, shift = _posed(pts, 15)
    scan, normals = _scan(posed, rng)
    tilt = Rotation.from_rotvec(rng.normal(0.0, math.radians(20.0) / math.sqrt(2), normals.shape))
    flipped = tilt.apply(normals) * rng.choice([-1.0, 1.0], size=(len(normals), 1))
    fit = fit_primitive(scan, flipped)
    assert fit is not None
    assert fit.shape.kind == "box"
    assert np.linalg.norm(np.array(fit.shape.position) - shift) < 0.001
    np.testing.assert_allclose(np.sort(fit.shape.size), [0.02, 0.035, 0.05], atol=0.001)
    fitted = _axes(fit.shape)
    for true_axis in rot.as_matrix().T:
        assert min(_angle_deg(true_axis, axis) for axis in fitted.T) < 2.0
