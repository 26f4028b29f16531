"""The stretched fits pair a model point with the nearest scan point of a face like its own."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from tasks.transfer import pairing
from tasks.transfer.pairing import nearest_compatible
from tasks.transfer.stretch import NORMAL_COS


def _slab_scan(spacing: float, edge_x: float) -> tuple[np.ndarray, np.ndarray]:
    """A scanned door 40 mm thick: its front (z = 0, x <= edge_x) and its edge face (x = edge_x, -40..0 mm)."""
    xs = np.arange(-0.3, edge_x + 1e-9, spacing)
    ys = np.arange(-0.2, 0.2 + 1e-9, spacing)
    front = np.array([(x, y, 0.0) for x in xs for y in ys])
    zs = np.arange(-0.04, 0.0, spacing)
    edge = np.array([(edge_x, y, z) for y in ys for z in zs])
    points = np.vstack([front, edge])
    normals = np.vstack([np.tile([0.0, 0.0, 1.0], (len(front), 1)), np.tile([1.0, 0.0, 0.0], (len(edge), 1))])
    return points, normals


def test_an_edge_face_pairs_with_its_scan_past_the_nearer_front() -> None:
    scan, scan_normals = _slab_scan(0.002, edge_x=0.03)
    tree = cKDTree(scan)
    model = np.array([[0.0, 0.0, -0.02], [0.0, 0.1, -0.01]])  # the model's edge face, 30 mm short of the scan's
    facing = np.tile([-1.0, 0.0, 0.0], (2, 1))  # unsigned: the opposite sense agrees
    idx, found = nearest_compatible(tree, model, facing, scan_normals, dist_m=0.05, min_cos=NORMAL_COS)
    assert found.all()
    assert np.allclose(scan[idx, 0], 0.03)  # on the edge face, not the front 10-20 mm away
    assert np.all(np.abs(scan[idx, 1:] - model[:, 1:]) <= 0.0011)  # its nearest point there
    nearest = tree.query(model)[1]
    assert np.all(scan_normals[nearest, 2] == 1.0)  # what the plain nearest point would have paired


def test_no_face_alike_within_the_distance_pairs_nothing() -> None:
    scan, scan_normals = _slab_scan(0.002, edge_x=0.03)
    tree = cKDTree(scan)
    model = np.array([[0.0, 0.0, -0.02], [-0.25, 0.0, 0.001]])
    facing = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # no scan face faces along y; the second is the front
    idx, found = nearest_compatible(tree, model, facing, scan_normals, dist_m=0.05, min_cos=NORMAL_COS)
    assert found.tolist() == [False, True]
    assert idx[0] == len(scan)
    assert scan_normals[idx[1], 2] == 1.0


def test_an_edge_beyond_the_distance_is_not_paired() -> None:
    scan, scan_normals = _slab_scan(0.002, edge_x=0.03)
    tree = cKDTree(scan)
    model = np.array([[-0.05, 0.0, -0.02]])  # 80 mm from the scan's edge face
    idx, found = nearest_compatible(
        tree, model, np.array([[1.0, 0.0, 0.0]]), scan_normals, dist_m=0.05, min_cos=NORMAL_COS
    )
    assert not found[0]
    assert idx[0] == len(scan)


def test_held_in_chunks_the_pairs_are_the_same(monkeypatch: pytest.MonkeyPatch) -> None:
    scan, scan_normals = _slab_scan(0.002, edge_x=0.03)
    tree = cKDTree(scan)
    rng = np.random.default_rng(3)
    model = rng.uniform([-0.1, -0.1, -0.04], [0.05, 0.1, 0.0], size=(300, 3))
    facing = np.where(rng.random(300)[:, None] < 0.5, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    whole = nearest_compatible(tree, model, facing, scan_normals, dist_m=0.05, min_cos=NORMAL_COS)
    monkeypatch.setattr(pairing, "CHUNK", 64)
    chunked = nearest_compatible(tree, model, facing, scan_normals, dist_m=0.05, min_cos=NORMAL_COS)
    assert whole[1].sum() > 200  # the edge face is out of reach of the x-facing points beyond x = -0.02
    assert np.array_equal(whole[0], chunked[0]) and np.array_equal(whole[1], chunked[1])
