"""The stretched fit's planes come from the model: clean normals, the faces' own frame, one face per scan point,
and an axis placement whose sigma covers what the fits disagree on."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from schemas.descriptor import Primitive
from tasks.transfer.axis_fit import AGREEMENT_SIGMAS, AxisFit, axis_edges, fit_axis
from tasks.transfer.clouds import median_spacing
from tasks.transfer.face_normals import model_normals
from tasks.transfer.registration import surface_normals
from tasks.transfer.similarity import Similarity
from tasks.transfer.stretch import NEAREST_SLACK, Stretched, _matched, box_axes, line_spread, smoothed_normals
from tasks.transfer.uncertainty import MAX_AXIS_POS_STD_M
from tests.transfer import shapes

LEAF = np.array([0.8, 0.04, 2.0])


def _leaf(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A door leaf with a block sticking out 70 mm on each face near one edge (a lever on its rose)."""
    parts = shapes.box(LEAF, np.array([0.0, 0.0, 1.0]))
    for sign in (-1.0, 1.0):
        parts += shapes.box(np.array([0.13, 0.07, 0.03]), np.array([0.3, sign * 0.055, 0.95]))
    return shapes.sample_parts(parts, n, rng)


def test_box_axes_follow_the_faces_not_what_sticks_out() -> None:
    rng = np.random.default_rng(2)
    points, _ = _leaf(rng, 12_000)
    points = points + rng.normal(scale=5e-4, size=points.shape)
    normals = smoothed_normals(points, surface_normals(points, median_spacing(points)))

    def off_thickness_deg(axes: np.ndarray) -> float:
        return float(np.degrees(np.arccos(np.abs(axes[1]).max())))  # the axis nearest the leaf's normal (y)

    tilted = off_thickness_deg(box_axes(points))  # the minimal box trades the leaf's depth for its height
    faced = off_thickness_deg(box_axes(points, normals))
    assert tilted > 1.0
    assert faced < 0.2


def test_smoothed_normals_lie_on_the_faces() -> None:
    rng = np.random.default_rng(4)
    points, truth = shapes.sample_parts(shapes.box(np.array([0.4, 0.3, 0.5]), np.zeros(3)), 8000, rng)
    points = points + rng.normal(scale=5e-4, size=points.shape)
    raw = surface_normals(points, median_spacing(points))
    smooth = smoothed_normals(points, raw)

    def off_deg(normals: np.ndarray) -> np.ndarray:
        return np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", normals, truth)), 0.0, 1.0)))

    assert np.median(off_deg(smooth)) < 0.5 * np.median(off_deg(raw))
    assert np.mean(off_deg(smooth) > 10.0) < 0.5 * np.mean(off_deg(raw) > 10.0)  # edge normals join a face


def _front_only(rng: np.random.Generator, size: np.ndarray, noise: float) -> tuple[np.ndarray, np.ndarray]:
    """A box's front face (-y) alone, as one view straight on shows it, with scanner noise; estimated normals."""
    pts, _ = shapes.sample_parts(shapes.box(size, np.zeros(3))[2:3], 3000, rng)
    pts = pts + rng.normal(scale=noise, size=pts.shape)
    return pts, surface_normals(pts, median_spacing(pts))


def test_a_hinge_on_a_face_the_scan_lacks_is_not_pinned() -> None:
    rng = np.random.default_rng(6)
    size = np.array([0.45, 0.35, 0.3])
    source, _ = shapes.sample_parts(shapes.box(size, np.zeros(3)), 6000, rng)
    source_n = smoothed_normals(source, surface_normals(source, median_spacing(source)))
    hinge = (np.array([-0.225, -0.175, 0.0]), np.array([0.0, 0.0, 1.0]))
    region = np.linalg.norm((source - hinge[0])[:, :2], axis=1) < 0.08
    target, target_n = _front_only(rng, size, 1.5e-3)
    fit = Stretched(Similarity.identity(), np.eye(3), np.ones(3), source.mean(axis=0))
    spread = line_spread(
        fit, source[region], source_n[region], target=target, target_normals=target_n, dist_m=0.01, line=hinge,
        free_stretch=False,
    )  # fmt: skip
    # the front face says nothing about where along it the door ends: the hinge may slide
    assert spread.pos_std_m > MAX_AXIS_POS_STD_M


def test_a_direction_no_pair_constrains_keeps_the_fits_reach() -> None:
    rng = np.random.default_rng(7)
    face = shapes.box(np.array([0.45, 0.35, 0.3]), np.zeros(3))[2:3]  # the front face (-y) alone
    source, source_n = shapes.sample_parts(face, 3000, rng)
    target, target_n = shapes.sample_parts(face, 3000, rng)
    target = target + rng.normal(scale=1e-3, size=target.shape) * np.array([0.0, 1.0, 0.0])
    fit = Stretched(Similarity.identity(), np.eye(3), np.ones(3), source.mean(axis=0))
    hinge = (np.array([-0.225, -0.175, 0.0]), np.array([0.0, 0.0, 1.0]))
    spread = line_spread(
        fit, source, source_n, target=target, target_normals=target_n, dist_m=0.01, line=hinge, free_stretch=False
    )
    # exact normals along -y: nothing at all pins the hinge along x, so it is as uncertain as the fit's reach
    assert spread.pos_std_m > 0.5 * 0.01


def test_the_back_of_a_thin_part_does_not_pair_with_its_front() -> None:
    rng = np.random.default_rng(8)
    source, source_n = shapes.sample_parts(shapes.box(LEAF, np.zeros(3)), 3000, rng)
    target, target_n = _front_only(rng, LEAF, 1e-3)
    fit = Stretched(Similarity.identity(), np.eye(3), np.ones(3), source.mean(axis=0))
    line = (np.array([0.3, -0.02, 1.0]), np.array([0.0, -1.0, 0.0]))
    back = source[:, 1] > 0.0199
    tree = cKDTree(target)
    for dist in (0.12, 0.06):  # wider than the leaf is thick: its back face is within reach of the front
        _, _, _, paired = _matched(
            fit, source, source_n, target_normals=target_n, tree=tree, dist_m=dist, slack_m=NEAREST_SLACK * dist
        )
        assert int((paired & back).sum()) <= 20  # of the back face's 1,388 points, only a few at its border
        assert int((paired & ~back).sum()) >= 1400  # the front face, and edge points at the front's rim
        spread = line_spread(fit, source, source_n, target=target, target_normals=target_n, dist_m=dist, line=line)
        assert spread.rms_m < 3e-3


def _hinge_fit(rng: np.random.Generator, whole_shift_m: float) -> AxisFit:
    """A box's hinge placed from a whole-model fit ``whole_shift_m`` off along the box's width, on a scan of the
    box's front and hinge side (1 mm noise)."""
    size = np.array([0.45, 0.35, 0.3])
    source, _ = shapes.sample_parts(shapes.box(size, np.zeros(3)), 6000, rng)
    model = model_normals(smoothed_normals(source, surface_normals(source, median_spacing(source))))
    target, _ = shapes.sample_parts([shapes.box(size, np.zeros(3))[k] for k in (0, 2)], 4000, rng)
    target = target + rng.normal(scale=1e-3, size=target.shape)
    target_n = surface_normals(target, median_spacing(target))
    whole = Stretched(Similarity(1.0, np.eye(3), np.array([whole_shift_m, 0.0, 0.0])), np.eye(3), np.ones(3),
                      np.zeros(3))  # fmt: skip
    prim = Primitive("rotation", (-0.225, -0.175, 0.0), (0.0, 0.0, 1.0), 1.0)
    return fit_axis(
        prim, source, model, target, target_n, whole=whole,
        whole_points=(source, model.normals, model.plane_weight), grip=np.empty((0, 3)), radius_m=0.08,
        threshold_m=0.015, spacing_m=median_spacing(target), edges=axis_edges(prim, source, model, 0.08),
    )  # fmt: skip


def test_the_axis_sigma_covers_a_contradicting_fit() -> None:
    fit = _hinge_fit(np.random.default_rng(10), 0.008)
    assert fit.local
    assert fit.whole_shift_m > AGREEMENT_SIGMAS * fit.fit_pos_std_m  # the whole model contradicts the hinge's fit
    assert fit.spread.pos_std_m == pytest.approx(fit.whole_shift_m / AGREEMENT_SIGMAS)


def test_the_axis_keeps_its_own_sigma_when_the_fits_agree() -> None:
    fit = _hinge_fit(np.random.default_rng(12), 0.0)
    assert fit.local
    assert fit.spread.pos_std_m == fit.fit_pos_std_m
    assert fit.spread.pos_std_m < MAX_AXIS_POS_STD_M


def test_a_held_stretch_moves_an_axis_beside_its_part_by_its_offset_from_the_part() -> None:
    # A lever's arm 20-150 mm to one side of its spindle, fitted rigidly with the door's stretch held (stretched
    # about the door's centre 400 mm away): a 10 % error of the stretch along the arm moves the arm's balance
    # point, the middle of its end faces 85 mm from the spindle, and the spindle with it by 8.5 mm.
    rng = np.random.default_rng(4)
    source, source_n = shapes.sample_parts(
        shapes.box(np.array([0.13, 0.014, 0.02]), np.array([0.085, 0.0, 0.0])), 4000, rng
    )
    target = source + rng.normal(scale=1e-3, size=source.shape)
    fitted = Stretched(Similarity.identity(), np.eye(3), np.ones(3), np.array([0.4, 0.0, 0.0]))
    line = (np.zeros(3), np.array([0.0, 1.0, 0.0]))
    spreads = [
        line_spread(
            fitted,
            source,
            source_n,
            target=target,
            target_normals=source_n,
            dist_m=0.01,
            line=line,
            free_stretch=False,
            held_factor_cov=held,
        )
        for held in (None, np.diag([0.1**2, 0.0, 0.0]))
    ]
    assert spreads[0].pos_cov is not None and spreads[1].pos_cov is not None
    added = spreads[1].pos_cov - spreads[0].pos_cov
    assert np.sqrt(added[0, 0]) == pytest.approx(0.0085, rel=0.1)  # along the arm
    assert abs(added[2, 2]) < 1e-8  # across it the stretch moves nothing
