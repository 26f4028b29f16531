"""Model normals that state no plane inform nothing, and a stretch leaves what the scan does not show open."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from tasks.transfer.clouds import median_spacing
from tasks.transfer.face_normals import FLAT_DEG, model_normals, plane_holds
from tasks.transfer.registration import surface_normals
from tasks.transfer.similarity import Similarity
from tasks.transfer.stretch import Stretched, line_spread, smoothed_normals
from tests.transfer import shapes

LEAF = np.array([0.8, 0.04, 2.0])
SPINDLE = (np.array([0.3, -0.02, -0.06]), np.array([0.0, -1.0, 0.0]))
"""A lever's spindle through the leaf's front face (-y), near its middle."""


def _leaf_model(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A door leaf's full model (0.5 mm noise), its smoothed normals as the pipeline estimates them, and the true
    normals."""
    points, truth = shapes.sample_parts(shapes.box(LEAF, np.zeros(3)), 20_000, rng)
    points = points + rng.normal(scale=5e-4, size=points.shape)
    return points, smoothed_normals(points, surface_normals(points, median_spacing(points))), truth


def _scan(rng: np.random.Generator, keep: tuple[int, ...], above_m: float = -1.0) -> tuple[np.ndarray, np.ndarray]:
    """The leaf's faces ``keep`` (indices into ``shapes.box``) above height ``above_m`` with 1.5 mm noise and
    estimated normals."""
    points, _ = shapes.sample_parts([shapes.box(LEAF, np.zeros(3))[k] for k in keep], 8000, rng)
    points = points[points[:, 2] > above_m] + rng.normal(scale=1.5e-3, size=(int((points[:, 2] > above_m).sum()), 3))
    return points, surface_normals(points, median_spacing(points))


def test_flat_faces_take_their_direction_and_borders_inform_nothing() -> None:
    _, smooth, truth = _leaf_model(np.random.default_rng(1))
    model = model_normals(smooth)
    assert np.abs(np.abs(model.directions[0]) - [0.0, 1.0, 0.0]).max() < 2e-3  # the leaf's faces
    off = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", model.normals, truth)), 0.0, 1.0)))
    front = np.abs(truth[:, 1]) > 0.9
    informs = model.plane_weight > 0.0
    assert np.median(off[front & informs]) < 0.2
    # the smoothing leaves normals tilted along the leaf's borders; none of those 3-30 degrees off informs
    tilt = np.degrees(np.arccos(np.clip(np.abs(smooth @ model.directions[0]), 0.0, 1.0)))
    border = (tilt > 3.0) & (tilt < 30.0)
    assert border.sum() > 500
    assert not informs[border].any()


def test_a_densely_sampled_box_keeps_its_faces() -> None:
    # 0.5 mm of noise every ~1.5 mm scatters a face's smoothed normals by about 2 degrees, beyond the 3 degrees a
    # sparse model's faces sit within: the faces are found at the normals' own scatter, and the borders still
    # inform nothing
    rng = np.random.default_rng(3)
    box = np.array([0.45, 0.35, 0.3])
    for count, flat in ((8_000, False), (120_000, True)):
        points, truth = shapes.sample_parts(shapes.box(box, np.zeros(3)), count, rng)
        points = points + rng.normal(scale=5e-4, size=points.shape)
        smooth = smoothed_normals(points, surface_normals(points, median_spacing(points)))
        model = model_normals(smooth)
        assert (model.flat_deg > FLAT_DEG) is flat
        assert len(model.directions) == 3
        assert np.abs(model.directions).max(axis=1).min() > np.cos(np.radians(1.0))  # the box's three axes
        off = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", model.normals, truth)), 0.0, 1.0)))
        informs = model.plane_weight > 0.0
        assert np.quantile(off[informs], 0.9) < 1.0
        tilt = np.degrees(np.arccos(np.clip(np.abs(smooth @ model.directions.T).max(axis=1), 0.0, 1.0)))
        border = (tilt > model.flat_deg) & (tilt < 30.0)
        assert border.sum() > 0.03 * count  # the edges' tilted normals ...
        assert not informs[border].any()  # ... inform nothing
    # a cylinder's normals spread evenly at any sampling: no face
    side, _ = shapes.sample_parts([shapes.cylinder_side(0.04, 0.0, 0.2)], 60_000, rng)
    side = side + rng.normal(scale=5e-4, size=side.shape)
    assert len(model_normals(smoothed_normals(side, surface_normals(side, median_spacing(side)))).directions) == 0


def test_a_cylinder_keeps_its_normals() -> None:
    rng = np.random.default_rng(2)
    points, _ = shapes.sample_parts([shapes.cylinder_side(0.04, 0.0, 0.2)], 6000, rng)
    smooth = smoothed_normals(points, surface_normals(points, median_spacing(points)))
    model = model_normals(smooth)
    assert len(model.directions) == 0  # a curved surface's normals spread evenly: no face
    assert (model.plane_weight == 1.0).all()
    np.testing.assert_array_equal(model.normals, smooth)


def test_a_leaf_seen_from_the_front_does_not_place_its_spindle() -> None:
    rng = np.random.default_rng(3)
    points, smooth, _ = _leaf_model(rng)
    target, target_n = _scan(rng, (2,))  # the front face alone
    model = model_normals(smooth)
    fit = Stretched(Similarity.identity(), np.eye(3), np.ones(3), points.mean(axis=0))
    spread = line_spread(
        fit, points, model.normals, target=target, target_normals=target_n, dist_m=0.02, line=SPINDLE,
        free_stretch=False, plane_weight=model.plane_weight,
    )  # fmt: skip
    # the front face says nothing about where along it the spindle is: the borders' tilted normals do not either
    assert spread.pos_std_m > 2e-3


def test_a_stretch_leaves_an_unscanned_height_open() -> None:
    rng = np.random.default_rng(4)
    points, smooth, _ = _leaf_model(rng)
    # the front's upper part and the top edge: where the front ends below is not in the scan, and a taller leaf
    # looks like a shifted one
    target, target_n = _scan(rng, (2, 5), above_m=-0.4)
    model = model_normals(smooth)
    fit = Stretched(Similarity.identity(), np.eye(3), np.ones(3), points.mean(axis=0))
    spread = line_spread(
        fit, points, model.normals, target=target, target_normals=target_n, dist_m=0.02, line=SPINDLE,
        plane_weight=model.plane_weight,
    )  # fmt: skip
    assert spread.pos_std_m > 0.05  # the height stretch moves a spindle 1 m below the top edge by decimetres


PLATE = np.array([0.4, 0.4, 0.04])


def test_a_plane_holds_on_a_face_and_on_a_gentle_curve_not_on_a_thin_post() -> None:
    for seed in range(3):
        rng = np.random.default_rng(20 + seed)
        # a plate with a post 9 mm in radius on its front, sampled every ~6 mm as a door leaf's model is
        parts = [
            *shapes.box(PLATE, np.zeros(3)),
            shapes.cylinder_side(0.009, 0.02, 0.07),
            shapes.disk(0.009, 0.07, True),
        ]
        points, _ = shapes.sample_parts(parts, 2300, rng)
        points = points + rng.normal(scale=5e-4, size=points.shape)
        model = model_normals(smoothed_normals(points, surface_normals(points, median_spacing(points))))
        holds = plane_holds(points, model.normals, cKDTree(points), np.arange(len(points)), np.zeros(len(points)))
        radial = np.hypot(points[:, 0], points[:, 1])
        post = (radial < 0.012) & (points[:, 2] > 0.025) & (points[:, 2] < 0.065)
        face = (points[:, 2] > 0.019) & (radial > 0.05) & (np.abs(points[:, :2]).max(axis=1) < 0.17)
        assert holds[face].mean() > 0.9
        assert holds[post].mean() < 0.3  # its normals, smoothed over a few spacings, state no plane of it
        # a bottle's side, 40 mm in radius and sampled every 1.5 mm: its planes hold
        side, _ = shapes.sample_parts([shapes.cylinder_side(0.04, 0.0, 0.2)], 6000, rng)
        side = side + rng.normal(scale=5e-4, size=side.shape)
        normals = model_normals(smoothed_normals(side, surface_normals(side, median_spacing(side)))).normals
        assert plane_holds(side, normals, cKDTree(side), np.arange(len(side)), np.zeros(len(side))).mean() > 0.9
