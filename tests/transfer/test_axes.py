"""Placing carried axes: the symmetry fit of a cap and of its body, the snap onto a fatter bottle's cap, the local
check."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from schemas.descriptor import Primitive
from tasks.transfer.axes import place_axes
from tasks.transfer.clouds import median_spacing
from tasks.transfer.local_refine import LocalCheck, LocalParams, _judge, axis_region, check_axis
from tasks.transfer.registration import surface_normals
from tasks.transfer.similarity import Similarity, angle_between_deg, point_line_distance
from tasks.transfer.symmetry_axis import fit_symmetry_axis, fit_symmetry_line
from tests.transfer import shapes

CAP_AXIS = Primitive("rotation", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 3.0)


def _cap_axis(model: shapes.ShapeModel) -> Primitive:
    top = model.axis_pos
    return Primitive("rotation", (float(top[0]), float(top[1]), float(top[2])), (0.0, 0.0, 1.0), 3.0)


def test_symmetry_fit_finds_the_cap_axis_from_a_point_beside_it(bottle_model: shapes.ShapeModel) -> None:
    beside = bottle_model.axis_pos + np.array([0.004, -0.003, 0.0])
    normals = surface_normals(bottle_model.points, median_spacing(bottle_model.points))
    fit = fit_symmetry_axis(bottle_model.points, normals, beside, np.array([0.0, 0.0, 1.0]), 0.03, loss_scale_m=5e-4)
    assert fit is not None
    assert fit.offset_m == pytest.approx(0.005, abs=3e-4)
    assert point_line_distance(bottle_model.axis_pos, fit.pos, np.array([0.0, 0.0, 1.0])) < 3e-4


def test_a_box_corner_is_no_body_of_revolution() -> None:
    rng = np.random.default_rng(3)
    pts, _ = shapes.sample_parts(shapes.box(np.array([0.1, 0.1, 0.1]), np.zeros(3)), 3000, rng)
    normals = surface_normals(pts, median_spacing(pts))
    fit = fit_symmetry_axis(
        pts, normals, np.array([0.05, 0.05, 0.0]), np.array([0.0, 0.0, 1.0]), 0.04, loss_scale_m=5e-4
    )
    assert fit is not None
    assert fit.offset_m > 0.005  # the fitted "axis" wanders off the edge: not within 1 % of the radius


def test_cap_axis_moves_onto_a_fatter_bottles_cap(bottle_model: shapes.ShapeModel) -> None:
    rng = np.random.default_rng(5)
    fat = shapes.bottle(rng, n=3000, radius=0.042, cap_radius=0.021)  # no similarity maps the one onto the other
    truth = Similarity(1.0, shapes.random_rotation(rng), np.array([0.2, -0.1, 0.4]))
    target = truth.apply_points(fat.points)
    off = Similarity(1.0, truth.rotation, truth.translation + truth.rotation @ np.array([0.008, 0.0, 0.0]))
    prim = _cap_axis(bottle_model)
    placed = place_axes(
        (prim,), bottle_model.points, target, best=off, grip=bottle_model.focus[:1], threshold_m=0.003,
        spacing_m=0.002,
    )  # fmt: skip
    assert placed.snapped_m[0] == pytest.approx(0.008, abs=1e-3)
    moved = placed.transforms[0]
    true_axis = truth.apply_point(fat.axis_pos)
    assert point_line_distance(true_axis, moved.apply_point(bottle_model.axis_pos), moved.rotation[:, 2]) < 5e-4
    assert placed.grasp_transform is moved  # the hand on the cap moves with its axis
    symmetry = placed.symmetry[0]
    assert symmetry is not None and 0.0 < symmetry.worst_pos_std_m < 5e-4
    assert placed.warnings == ()


def test_local_check_passes_a_right_placement_and_warns_a_shifted_hinge() -> None:
    rng = np.random.default_rng(9)
    cab = shapes.cabinet(rng, n=9000)
    hinge = Primitive("rotation", tuple(float(v) for v in cab.axis_pos), tuple(float(v) for v in cab.axis_dir), 1.0)  # type: ignore[arg-type]
    normals = cab.normals
    grip = cab.focus[-1:]
    right = check_axis(
        hinge, 0, cab.points, cab.points, normals, source_normals=normals, best=Similarity.identity(), grip=grip,
        threshold=0.006, params=LocalParams(),
    )  # fmt: skip
    assert right.warning is None
    assert right.back_fitness > 0.95
    across = np.cross(cab.axis_dir, [0.0, 0.0, 1.0] if abs(cab.axis_dir[2]) < 0.9 else [1.0, 0.0, 0.0])
    shifted = Similarity(1.0, np.eye(3), 0.06 * across / np.linalg.norm(across))
    wrong = check_axis(
        hinge, 0, cab.points, cab.points, normals, source_normals=normals, best=shifted, grip=grip,
        threshold=0.006, params=LocalParams(),
    )  # fmt: skip
    assert wrong.warning is not None
    assert wrong.warning.startswith("poor registration: axis 0 (rotation)")


def test_axis_region_is_a_cylinder_as_long_as_wide() -> None:
    pts = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.0, 0.0, 0.09], [0.0, 0.0, 0.2], [0.2, 0.0, 0.0]])
    mask = axis_region(pts, np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.1)
    assert mask.tolist() == [True, True, True, False, False]


def test_local_check_warns_when_the_region_fits_as_well_with_the_axis_far_off() -> None:
    # the benchmark's door 2>3: its lever placed 15 mm off under a 28 mm threshold, the lever's own refinement
    # moving it 27 mm with both fits at 1.0
    door = LocalCheck(0, 115, 1.57, 0.0268, 1.0, 1.0, 0.95, 0.135, None)
    warning = _judge(door, "rotation", LocalParams())
    assert warning is not None
    assert "fits as well (1.00 -> 1.00)" in warning
    assert "moved 26.8 mm" in warning
    assert _judge(replace(door, shift_m=0.004, turn_deg=1.4), "rotation", LocalParams()) is None
    assert _judge(replace(door, lateral=0.01), "rotation", LocalParams()) is None  # a flat lid may slide


def test_a_caps_top_seen_from_one_side_does_not_pull_its_axis() -> None:
    """Ten scans of a bottle from one side, 30 degrees above, with 1.5 mm of noise: the cap's top face is seen on one
    half only. The sides alone place the axis (with the top face in, the median error is 1.4 mm) and the fit's
    own sigma covers the error (with the top face in, 7 of 10 errors are beyond three sigmas)."""
    errors, ratios = [], []
    for seed in range(20, 30):
        rng = np.random.default_rng(seed)
        model = shapes.bottle(rng, n=8000)
        view = np.array([math.cos(math.radians(30.0)), 0.0, math.sin(math.radians(30.0))])
        seen = model.normals @ view > 0.2
        pts = model.points[seen] + rng.normal(scale=1.5e-3, size=(int(seen.sum()), 3))
        normals = surface_normals(pts, median_spacing(pts))
        up = np.array([0.0, 0.0, 1.0])
        fit = fit_symmetry_axis(pts, normals, model.axis_pos, up, 0.03, loss_scale_m=1e-3)
        assert fit is not None
        errors.append(point_line_distance(model.axis_pos, fit.pos, up))
        ratios.append(errors[-1] / fit.worst_pos_std_m)
    assert float(np.median(errors)) < 1e-3
    assert sum(r > 3.0 for r in ratios) <= 2


def _one_side(model: shapes.ShapeModel, rng: np.random.Generator, noise_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The points of ``model`` facing a view 30 degrees above its side, with noise, and their estimated normals."""
    view = np.array([math.cos(math.radians(30.0)), 0.0, math.sin(math.radians(30.0))])
    seen = model.normals @ view > 0.2
    pts = model.points[seen] + rng.normal(scale=noise_m, size=(int(seen.sum()), 3))
    return pts, surface_normals(pts, median_spacing(pts))


def test_a_bottles_body_gives_its_axis_direction_with_its_sigma() -> None:
    """Ten bottles scanned from one side with 1.5 mm of noise, the fit started 2 degrees off: the body's sides turn
    the direction back, and the fit's own sigma covers what is left."""
    up = np.array([0.0, 0.0, 1.0])
    start = np.array([math.sin(math.radians(2.0)), 0.0, math.cos(math.radians(2.0))])
    errors, ratios = [], []
    for seed in range(40, 50):
        rng = np.random.default_rng(seed)
        model = shapes.bottle(rng, n=8000)
        pts, normals = _one_side(model, rng, 1.5e-3)
        pos, direction = model.axis_pos, start
        for _ in range(3):  # slices cut square to a turned axis: each fit starts from the last (as ``axes`` does)
            fit = fit_symmetry_line(pts, normals, pos, direction, 0.06, loss_scale_m=1e-3)
            assert fit is not None and fit.dir_std_rad is not None
            pos, direction = fit.pos, fit.direction
        errors.append(math.radians(angle_between_deg(direction, up)))
        ratios.append(errors[-1] / fit.dir_std_rad)
    assert math.degrees(float(np.median(errors))) < 0.2
    assert sum(r > 3.0 for r in ratios) <= 2


def test_a_turned_cap_axis_is_turned_back_onto_the_bottles_body(bottle_model: shapes.ShapeModel) -> None:
    rng = np.random.default_rng(6)
    fat = shapes.bottle(rng, n=6000, radius=0.042, cap_radius=0.021)
    truth = Similarity(1.0, shapes.random_rotation(rng), np.array([0.2, -0.1, 0.4]))
    target = truth.apply_points(fat.points)
    tilt = Similarity(1.0, Rotation.from_rotvec([math.radians(2.0), 0.0, 0.0]).as_matrix(), np.zeros(3))
    off = truth.compose(tilt)
    prim = _cap_axis(bottle_model)
    placed = place_axes(
        (prim,), bottle_model.points, target, best=off, grip=bottle_model.focus[:1], threshold_m=0.003,
        spacing_m=0.002,
    )  # fmt: skip
    moved = placed.transforms[0]
    true_dir = truth.apply_direction(np.array([0.0, 0.0, 1.0]))
    assert angle_between_deg(moved.apply_direction(np.array([0.0, 0.0, 1.0])), true_dir) < 0.3
    true_pos = truth.apply_point(fat.axis_pos)
    assert point_line_distance(true_pos, moved.apply_point(bottle_model.axis_pos), true_dir) < 5e-4
    symmetry = placed.symmetry[0]
    assert symmetry is not None and symmetry.dir_std_rad is not None and 0.0 < symmetry.dir_std_rad < math.radians(0.3)


def test_a_cap_on_a_box_keeps_the_registrations_direction() -> None:
    """A cap on a box (a jar lid on a carton): the cap is a body of revolution, the body under it is not, so only
    the cap's point is moved and the direction stays where the registration carried it."""
    rng = np.random.default_rng(8)
    parts = [
        *shapes.box(np.array([0.12, 0.08, 0.15]), np.array([0.0, 0.0, 0.075])),
        shapes.cylinder_side(0.016, 0.15, 0.17),
        shapes.disk(0.016, 0.17, True),
    ]
    pts, _ = shapes.sample_parts(parts, 6000, rng)
    prim = Primitive("rotation", (0.0, 0.0, 0.17), (0.0, 0.0, 1.0), 3.0)
    tilt = Similarity(1.0, Rotation.from_rotvec([math.radians(1.0), 0.0, 0.0]).as_matrix(), np.zeros(3))
    placed = place_axes(
        (prim,), pts, pts, best=tilt, grip=np.array([[0.016, 0.0, 0.16]]), threshold_m=0.003, spacing_m=0.002
    )
    symmetry = placed.symmetry[0]
    assert symmetry is not None and symmetry.dir_std_rad is None
    assert angle_between_deg(placed.transforms[0].rotation[:, 2], tilt.rotation[:, 2]) < 1e-9


def test_a_learned_direction_off_within_its_sigma_still_finds_the_body(bottle_model: shapes.ShapeModel) -> None:
    """A demonstrated cap axis 0.15 degrees off the bottle's: 0.6 mm from the body's axis at its far end, beyond 1 %
    of the region radius. Learned with a sigma of 0.1 degrees, that is within what the demonstration knows, and the
    direction is turned onto the body's axis; learned without one, the body is not trusted to be coaxial."""
    rng = np.random.default_rng(9)
    truth = Similarity(1.0, shapes.random_rotation(rng), np.array([0.1, 0.2, 0.3]))
    target = truth.apply_points(bottle_model.points)
    top = bottle_model.axis_pos
    off = (0.0, math.sin(math.radians(0.15)), math.cos(math.radians(0.15)))
    true_dir = truth.apply_direction(np.array([0.0, 0.0, 1.0]))
    for fit, turned in (({"dir_std_rad": math.radians(0.1)}, True), ({}, False)):
        prim = Primitive("rotation", (float(top[0]), float(top[1]), float(top[2])), off, 3.0, fit=fit)
        placed = place_axes(
            (prim,), bottle_model.points, target, best=truth, grip=bottle_model.focus[:1], threshold_m=0.003,
            spacing_m=0.002,
        )  # fmt: skip
        symmetry = placed.symmetry[0]
        assert symmetry is not None
        assert (symmetry.dir_std_rad is not None) is turned
        error = angle_between_deg(placed.transforms[0].apply_direction(np.array(off)), true_dir)
        assert (error < 0.05) if turned else error == pytest.approx(0.15, abs=1e-6)
