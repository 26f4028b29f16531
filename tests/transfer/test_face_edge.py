"""A face's edge locates an axis that runs along it: the blurred step, the neighbouring face seen edge-on, the
faces an axis bounds, and the update of a fit that leaves the axis free along a face."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tasks.transfer.face_edge import edge_location, edge_update, locate_edge, model_edges
from tasks.transfer.face_normals import model_normals
from tasks.transfer.similarity import Similarity
from tasks.transfer.stretch import Stretched
from tests.transfer import shapes


def _face(rng: np.random.Generator, n: int, edge_m: float, noise_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(s, depth) of ``n`` points of a face 100 mm wide from ``edge_m`` across, on depth 0, blurred by noise."""
    s = rng.uniform(edge_m, edge_m + 0.1, n) + rng.normal(scale=noise_m, size=n)
    return s, rng.normal(scale=noise_m, size=n)


@pytest.mark.parametrize(("noise_m", "n"), [(3e-4, 300), (1e-3, 300), (2e-3, 600)])
def test_the_edge_of_a_blurred_face_is_found_within_its_sigma_and_moves_with_it(noise_m: float, n: int) -> None:
    rng = np.random.default_rng(int(noise_m * 1e5) + n)
    s, _ = _face(rng, n, 0.0, noise_m)
    window = (-0.03, 0.06)
    found = edge_location(s, window, noise_m, 0.0)
    assert found is not None
    assert abs(found.offset_m) <= 3.0 * found.std_m
    assert found.std_m < max(noise_m, 1e-3)  # a few hundred points place the edge within a noise sigma
    moved = edge_location(s + 0.007, (window[0] + 0.007, window[1] + 0.007), noise_m, 0.0)
    assert moved is not None
    assert moved.offset_m - found.offset_m == pytest.approx(0.007, abs=2e-4)


def test_too_few_points_locate_no_edge() -> None:
    s, _ = _face(np.random.default_rng(1), 30, 0.0, 1e-3)
    assert edge_location(s, (-0.03, 0.06), 1e-3, 0.0) is None


def test_a_neighbouring_face_seen_edge_on_is_measured_and_does_not_pull_the_edge_out() -> None:
    rng = np.random.default_rng(4)
    noise = 1.5e-3
    s, depth = _face(rng, 3000, 0.0, noise)
    # the door's edge face: at the edge, running 20 mm back into the object, scanned as densely
    m = 600
    side_s = rng.normal(scale=noise, size=m)
    side_depth = -rng.uniform(0.0, 0.02, m) + rng.normal(scale=noise, size=m)
    all_s, all_depth = np.concatenate([s, side_s]), np.concatenate([depth, side_depth])
    window = (-0.03, 0.06)
    band = np.abs(all_depth) <= 2.0 * noise
    ignored = edge_location(all_s[band], window, noise, 0.0)
    measured = locate_edge(all_s, all_depth, window, noise)
    assert ignored is not None
    assert measured is not None
    assert ignored.offset_m < -3.0 * ignored.std_m  # the edge face's points drag a plain step outwards
    assert abs(measured.offset_m) <= 3.0 * measured.std_m
    assert measured.line_mass_m > 0.0


def _door(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A door slab 400 x 18 x 600 mm (front face towards -y), its hinge the front face's edge at x = -0.2."""
    pts, nrm = shapes.sample_parts(shapes.box(np.array([0.4, 0.018, 0.6]), np.array([0.0, 0.0, 0.3])), 20000, rng)
    return pts + rng.normal(scale=3e-4, size=pts.shape), nrm


def test_a_hinge_runs_along_its_doors_faces_and_an_axis_across_a_face_along_none_of_it() -> None:
    pts, nrm = _door(np.random.default_rng(2))
    model = model_normals(nrm)
    hinge = (np.array([-0.2, -0.009, 0.3]), np.array([0.0, 0.0, 1.0]))
    found = model_edges(pts, model, line=hinge, radius_m=0.05)
    front = [e for e in found if abs(e.normal[1]) > 0.99]
    assert len(front) == 1
    assert front[0].across @ np.array([1.0, 0.0, 0.0]) > 0.99  # into the face, away from the hinge
    assert abs(front[0].edge.offset_m) < 1e-3
    middle = (np.array([0.0, -0.009, 0.3]), np.array([0.0, 0.0, 1.0]))
    across = model_edges(pts, model, line=middle, radius_m=0.05)
    assert not [e for e in across if abs(e.normal[1]) > 0.99]


def test_a_fit_that_leaves_the_hinge_free_along_the_face_is_moved_onto_the_scans_edge() -> None:
    rng = np.random.default_rng(3)
    pts, nrm = _door(rng)
    model = model_normals(nrm)
    hinge = (np.array([-0.2, -0.009, 0.3]), np.array([0.0, 0.0, 1.0]))
    edge = next(e for e in model_edges(pts, model, line=hinge, radius_m=0.05) if abs(e.normal[1]) > 0.99)
    truth = Similarity(1.0, shapes.random_rotation(np.random.default_rng(5)), np.array([0.3, -0.2, 0.8]))
    front = pts[pts[:, 1] < -0.0085]  # the scan sees the front face only
    scan = truth.apply_points(front) + rng.normal(scale=1.5e-3, size=front.shape)
    # the fit slid the door 12 mm along its front face, and knows that direction only within 10 mm
    slid = Similarity(1.0, truth.rotation, truth.translation + truth.rotation @ np.array([0.012, 0.0, 0.0]))
    fit = Stretched(slid, np.eye(3), np.ones(3), np.zeros(3))
    along_face = truth.rotation @ np.array([1.0, 0.0, 0.0])
    depth = truth.rotation @ np.array([0.0, 1.0, 0.0])
    cov = 1e-4 * np.outer(along_face, along_face) + 1e-8 * np.outer(depth, depth)
    step = edge_update(edge, fit, hinge, scan, cov)
    assert step is not None
    assert step.agrees
    placed = slid.apply_point(hinge[0]) + step.shift
    assert np.linalg.norm(placed - truth.apply_point(hinge[0])) < 1e-3
    assert math.sqrt(float(along_face @ step.cov @ along_face)) < 1e-3
