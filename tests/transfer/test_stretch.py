"""The stretched fit recovers a box's proportions and pins the axes the data pin; the uncertainty it gives."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from schemas.descriptor import Primitive
from tasks.transfer.axis_fit import AxisFit, lateral_pinning
from tasks.transfer.clouds import median_spacing
from tasks.transfer.registration import surface_normals
from tasks.transfer.similarity import Similarity, angle_between_deg, point_line_distance
from tasks.transfer.stretch import (
    MAX_STRETCH,
    Stretched,
    box_axes,
    fit_stretch,
    line_jacobians,
    line_spread,
    local_similarity,
    smoothed_normals,
    stretch_icp,
)
from tasks.transfer.symmetry_axis import SymmetryFit
from tasks.transfer.uncertainty import axis_uncertainty, with_uncertainty
from tests.transfer import shapes

SIZE = np.array([0.4, 0.3, 0.6])
HINGE = (np.array([-0.2, -0.15, 0.3]), np.array([0.0, 0.0, 1.0]))


def _box(rng: np.random.Generator, n: int, stretch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    points, normals = shapes.sample_parts(shapes.box(SIZE * stretch, np.zeros(3)), n, rng)
    return points, normals


def _fit(stretch: np.ndarray, rng: np.random.Generator) -> tuple[Stretched, Similarity, tuple[np.ndarray, ...]]:
    source, source_n = _box(rng, 1500, np.ones(3))
    target, target_n = _box(rng, 1500, stretch)
    truth = Similarity(1.0, shapes.random_rotation(rng), rng.uniform(-0.3, 0.3, 3))
    target, target_n = truth.apply_points(target), target_n @ truth.rotation.T
    start = Stretched(truth, box_axes(source), np.ones(3), source.mean(axis=0))
    fitted = start
    for dist in (0.08, 0.04, 0.02):
        fitted = stretch_icp(source, target, target_n, fitted, dist, source_normals=source_n)
    return fitted, truth, (source, source_n, target, target_n)


def test_stretch_recovers_a_boxs_proportions_and_its_edge() -> None:
    stretch = np.array([1.2, 0.9, 1.1])
    fitted, truth, _ = _fit(stretch, np.random.default_rng(3))
    # the factors come along the box axes found on the source (their order and signs are the box's own)
    found = np.abs(fitted.axes.T) @ fitted.factors / np.abs(fitted.axes.T).sum(axis=1)
    np.testing.assert_allclose(np.sort(found), np.sort(stretch), rtol=0.01)
    pos, direction = fitted.carry_line(*HINGE)
    true_pos = truth.apply_point(HINGE[0] * stretch)
    assert point_line_distance(true_pos, pos, direction) < 1e-3
    assert angle_between_deg(direction, truth.apply_direction(HINGE[1])) < 0.2
    # the similarity carrying that one line as the stretched map does
    sim = local_similarity(fitted, *HINGE)
    np.testing.assert_allclose(sim.apply_point(HINGE[0]), pos, atol=1e-9)
    assert angle_between_deg(sim.apply_direction(HINGE[1]), direction) < 1e-6


def test_stretch_factors_stay_within_the_limit() -> None:
    fitted, _, _ = _fit(np.array([2.0, 1.0, 1.0]), np.random.default_rng(5))
    assert fitted.factors.max() <= MAX_STRETCH + 1e-9 and fitted.factors.min() >= 1.0 / MAX_STRETCH - 1e-9


def test_line_spread_grows_with_the_noise() -> None:
    rng = np.random.default_rng(9)
    fitted, _, (source, source_n, target, target_n) = _fit(np.array([1.1, 1.0, 0.95]), rng)
    quiet = line_spread(fitted, source, source_n, target=target, target_normals=target_n, dist_m=0.02, line=HINGE)
    noisy_target = target + rng.normal(scale=3e-3, size=target.shape)
    noisy = line_spread(fitted, source, source_n, target=noisy_target, target_normals=target_n, dist_m=0.02, line=HINGE)
    assert 0.0 < quiet.pos_std_m < noisy.pos_std_m < 5e-3
    assert quiet.rms_m < noisy.rms_m
    # one flat face leaves an axis along it free; two faces meeting at it pin it
    assert lateral_pinning(np.tile([0.0, -1.0, 0.0], (50, 1)), HINGE[1]) == pytest.approx(0.0)
    corner = np.vstack([np.tile([0.0, -1.0, 0.0], (50, 1)), np.tile([-1.0, 0.0, 0.0], (50, 1))])
    assert lateral_pinning(corner, HINGE[1]) == pytest.approx(0.5)


def test_uncertainty_combines_learned_and_registration() -> None:
    rng = np.random.default_rng(1)
    fitted, _, (source, source_n, target, target_n) = _fit(np.array([1.0, 1.0, 1.0]), rng)
    spread = line_spread(fitted, source, source_n, target=target, target_normals=target_n, dist_m=0.02, line=HINGE)
    prim = Primitive(
        "rotation", (-0.2, -0.15, 0.3), (0.0, 0.0, 1.0), 1.0, fit={"pos_std_m": 0.002, "dir_std_rad": 0.01}
    )
    unc = axis_uncertainty(prim, AxisFit(fitted, spread, local=False), scale=1.5, symmetry=None)
    assert unc.learned_pos_std_m == pytest.approx(0.003)
    assert unc.pos_std_m == pytest.approx(math.hypot(0.003, spread.pos_std_m))
    assert unc.dir_std_rad == pytest.approx(math.hypot(0.01, spread.dir_std_rad))
    out = with_uncertainty(prim, unc)
    assert out.fit["pos_std_m"] == pytest.approx(unc.pos_std_m)
    assert out.fit["registration_pos_std_m"] == pytest.approx(spread.pos_std_m)
    assert out.fit["learned_dir_std_rad"] == pytest.approx(0.01)
    # a primitive learned without an uncertainty keeps the registration's alone
    bare = axis_uncertainty(
        Primitive("translation", None, (0.0, 1.0, 0.0), 0.1), AxisFit(fitted, spread, False), 1.0, symmetry=None
    )
    assert bare.learned_dir_std_rad is None and bare.dir_std_rad == pytest.approx(spread.dir_std_rad)
    assert "pos_std_m" not in with_uncertainty(Primitive("translation", None, (0.0, 1.0, 0.0), 0.1), bare).fit
    # an axis moved onto the target's symmetry axis is placed as loosely as that fit, not the whole fit
    cov = np.diag([4e-8, 1e-8, 0.0])
    symmetry = SymmetryFit(np.zeros(3), 0.001, 0.001, 0.9, 200, cov, np.array([0.0, 0.0, 1.0]))
    snapped = axis_uncertainty(prim, AxisFit(fitted, spread, local=False), scale=1.5, symmetry=symmetry)
    assert snapped.registration_pos_worst_m == pytest.approx(2e-4)
    assert snapped.registration_pos_std_m == pytest.approx(math.sqrt(2.5e-8))
    assert snapped.registration_dir_std_rad == pytest.approx(spread.dir_std_rad)
    # and turned onto the body's fitted axis, its direction is as loose as that fit's
    turned = axis_uncertainty(prim, AxisFit(fitted, spread, local=False), 1.5, replace(symmetry, dir_std_rad=0.002))
    assert turned.registration_dir_std_rad == pytest.approx(0.002)


def test_stretch_icp_without_facing_pairs_keeps_its_start() -> None:
    rng = np.random.default_rng(3)
    face = shapes.box(np.array([0.4, 0.3, 0.5]), np.zeros(3))
    source, source_n = shapes.sample_parts(face[2:3], 500, rng)  # the front face (-y)
    target, target_n = shapes.sample_parts(face[0:1], 500, rng)  # a side face (-x): no normal agrees
    start = Stretched(Similarity.identity(), np.eye(3), np.ones(3), np.zeros(3))
    fitted = stretch_icp(source, target, target_n, start, 1.0, source_normals=source_n)
    assert fitted is start


def test_a_thin_slab_seen_from_the_front_keeps_its_thickness() -> None:
    """A door leaf's back face, unscanned, faces the same way as its front: at the wide early correspondence
    distances it must not be paired with the front (which would squeeze the leaf flat)."""
    rng = np.random.default_rng(4)
    size = np.array([0.8, 0.04, 2.0])
    model, _ = shapes.sample_parts(shapes.box(size, np.zeros(3)), 20000, rng)
    model_n = smoothed_normals(model, surface_normals(model, median_spacing(model)))  # as the pipeline estimates
    pick = rng.permutation(len(model))[:3000]
    source, source_n = model[pick], model_n[pick]
    target, target_n = shapes.sample_parts(shapes.box(size, np.zeros(3)), 20000, rng)
    seen = (target_n[:, 1] < -0.5) | (target_n[:, 0] > 0.5) | (target_n[:, 2] > 0.5)  # front, one side, top
    target, target_n = target[seen] + rng.normal(scale=1.5e-3, size=(int(seen.sum()), 3)), target_n[seen]
    truth = Similarity(1.0, shapes.random_rotation(rng), rng.uniform(-0.3, 0.3, 3))
    target, target_n = truth.apply_points(target), target_n @ truth.rotation.T
    fitted = fit_stretch(
        (source, source_n), target, target_n, truth, 0.025, axes=box_axes(source), centre=source.mean(axis=0)
    )
    thickness = fitted.factors[np.abs(fitted.axes[1]).argmax()]
    assert thickness > 0.9


def test_line_jacobians_match_a_small_step_of_the_fit() -> None:
    """A line tilted from the stretch axes: a step of each unknown (as ``stretch_icp`` applies it) moves the
    carried point and turns the carried direction as the Jacobians say, the factors' turn included."""
    rng = np.random.default_rng(11)
    axes = shapes.random_rotation(rng)
    fitted = Stretched(
        Similarity(1.1, shapes.random_rotation(rng), np.array([0.1, 0.2, -0.3])),
        axes,
        np.array([1.2, 0.9, 1.05]),
        np.array([0.01, -0.02, 0.03]),
    )
    line = (np.array([0.05, 0.1, -0.02]), np.array([0.6, 0.0, 0.8]))
    centre = np.array([0.12, 0.18, -0.25])
    jac, jac_dir = line_jacobians(fitted, line, centre)
    pos0, dir0 = fitted.carry_line(*line)
    step = 1e-6
    for k in range(9):
        x = np.zeros(9)
        x[k] = step
        rot = Rotation.from_rotvec(x[:3]).as_matrix()
        delta = Similarity(1.0, rot, centre + x[3:6] - rot @ centre)
        moved = Stretched(delta.compose(fitted.similarity), axes, fitted.factors * (1.0 + x[6:]), fitted.centre)
        pos1, dir1 = moved.carry_line(*line)
        np.testing.assert_allclose((pos1 - pos0) / step, jac[:, k], atol=1e-4)
        np.testing.assert_allclose((dir1 - dir0) / step, jac_dir[:, k], atol=1e-4)
    assert np.abs(jac_dir[:, 6:]).max() > 0.1  # the factors do turn this line
