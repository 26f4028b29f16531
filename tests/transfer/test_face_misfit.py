"""A fit whose faces lie off their scan to either side is no surer than that misfit, however tight its pairs."""

from __future__ import annotations

import numpy as np

from schemas.descriptor import Primitive
from tasks.transfer.axis_fit import fit_axes
from tasks.transfer.clouds import median_spacing
from tasks.transfer.face_misfit import bias_cov
from tasks.transfer.face_normals import model_normals
from tasks.transfer.registration import surface_normals
from tasks.transfer.similarity import Similarity
from tasks.transfer.stretch import CORRELATED_POINTS, Stretched, line_spread, smoothed_normals
from tests.transfer import shapes

LEAF = np.array([0.6, 0.04, 0.8])
"""A door leaf 40 mm thick (y), its hinge along z at its -x edge."""
HINGE = (np.array([-0.3, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))


def _spread(thicker_m: float, seed: int) -> tuple[float, np.ndarray]:
    """The hinge's position sigma (metres) and bias covariance when the leaf's model, fitted where it is, meets a
    scan of a leaf ``thicker_m`` thicker (front, back and hinge-side faces, 0.5 mm noise)."""
    rng = np.random.default_rng(seed)
    points, _ = shapes.sample_parts(shapes.box(LEAF, np.zeros(3)), 20_000, rng)
    points = points + rng.normal(scale=2e-4, size=points.shape)
    model = model_normals(smoothed_normals(points, surface_normals(points, median_spacing(points))))
    scanned = shapes.box(LEAF + np.array([0.0, thicker_m, 0.0]), np.zeros(3))
    target, _ = shapes.sample_parts([scanned[k] for k in (0, 2, 3)], 20_000, rng)
    target = target + rng.normal(scale=5e-4, size=target.shape)
    fit = Stretched(Similarity.identity(), np.eye(3), np.ones(3), points.mean(axis=0))
    spread = line_spread(
        fit, points, model.normals, target=target, target_normals=surface_normals(target, median_spacing(target)),
        dist_m=0.01, line=HINGE, free_stretch=False, plane_weight=model.plane_weight,
    )  # fmt: skip
    assert spread.bias_cov is not None
    return spread.pos_std_m, spread.bias_cov


def test_a_leaf_thicker_than_its_model_shows_a_misfit_across_the_leaf() -> None:
    for seed in range(2):
        pos_std, bias = _spread(0.004, seed)  # front and back faces each 2 mm out, to either side
        values, vectors = np.linalg.eigh(bias)
        assert 1.5e-3 < np.sqrt(values[-1]) < 2.2e-3
        assert abs(vectors[1, -1]) > 0.99  # across the leaf (y), along the faces' normal
        assert np.sqrt(values[-1]) > 3.0 * pos_std  # the pairs' scatter alone says far less
        _, same = _spread(0.0, seed)
        assert np.sqrt(np.linalg.eigvalsh(same)[-1]) < 2e-4


def test_noise_alone_and_faces_along_the_axis_are_no_misfit() -> None:
    rng = np.random.default_rng(5)
    n = 4000
    source = rng.uniform(-0.2, 0.2, size=(n, 3))
    normals = np.zeros((n, 3))
    normals[: n // 2, 1] = 1.0  # a face across the axis, its pairs erring about zero
    normals[n // 2 :, 2] = -1.0  # a face whose normal is the axis, off by 3 mm
    source[: n // 2, 1] = 0.02
    source[n // 2 :, 2] = 0.4
    residual = rng.normal(scale=1e-3, size=n)
    residual[n // 2 :] += 3e-3
    direction = np.array([0.0, 0.0, 1.0])
    out = bias_cov(source, normals, normals, residual, direction=direction, rms_m=1e-3, correlated=CORRELATED_POINTS)
    assert not out.any()
    residual[: n // 2] += 1e-3  # the face across the axis now lies 1 mm off: about 1 mm less two standard errors
    out = bias_cov(source, normals, normals, residual, direction=direction, rms_m=1e-3, correlated=CORRELATED_POINTS)
    assert 0.8e-3 < np.sqrt(out[1, 1]) < 1.0e-3
    assert np.abs(out[[0, 2]]).max() == 0.0


BODY = np.array([0.5, 0.35, 0.4])
"""A microwave-like body (metres) whose front (-y) holds a door 22 mm thick on its left, hinged at the left edge."""


def _hinged_box(door_t: float, rng: np.random.Generator, faces: tuple[int, ...] | None = None) -> np.ndarray:
    """30 000 points of the body and its door (``faces``: the indices into ``shapes.box`` kept of each)."""
    body = shapes.box(BODY, np.array([0.0, 0.0, 0.2]))
    door = shapes.box(np.array([0.35, door_t, 0.39]), np.array([-0.075, -0.175 - door_t / 2, 0.2]))
    if faces is not None:
        body, door = [body[k] for k in faces], [door[k] for k in faces]
    points, _ = shapes.sample_parts(body + door, 30_000, rng)
    return points


def test_a_door_thicker_than_its_model_widens_the_hinges_sigma() -> None:
    hinge = np.array([-0.25, -0.197, 0.2])
    prim = Primitive("rotation", (float(hinge[0]), float(hinge[1]), float(hinge[2])), (0.0, 0.0, -1.0), 1.0)
    out, off = {}, {}
    for extra in (0.0, 0.006):  # the scanned door as thick as the model's, and 6 mm thicker
        rng = np.random.default_rng(0)
        model = _hinged_box(0.022, rng) + rng.normal(scale=5e-4, size=(30_000, 3))
        scan = _hinged_box(0.022 + extra, rng, faces=(0, 2, 5)) + rng.normal(scale=1e-3, size=(30_000, 3))
        fits = fit_axes(
            (prim,), model, scan, best=Similarity.identity(), grip=np.zeros((0, 3)), threshold_m=0.01,
            spacing_m=median_spacing(scan), rng=rng,
        )  # fmt: skip
        out[extra] = fits.axes[0].spread
        off[extra] = float(np.linalg.norm((fits.starts[0].apply_point(hinge) - hinge + [0.0, extra, 0.0])[:2]))
    assert out[0.0].misfit_std_m == 0.0
    # a body stretched in depth cannot thicken its door alone: the door's front and the body's faces lie off
    assert 0.3e-3 < out[0.006].misfit_std_m < 3e-3
    # the misfit widens the sigma (the pairs' own scatter about 1.2 times), and the door's edges, trusted more
    # against it, place the hinge closer (1.16 mm off without it)
    assert out[0.006].worst_pos_std_m > 1.4 * out[0.0].worst_pos_std_m
    assert off[0.006] < 1e-3
