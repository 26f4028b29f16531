"""The scan's own noise and the surface normals' neighbourhood that follows from it."""

from __future__ import annotations

import numpy as np
import pytest

from tasks.transfer.clouds import median_spacing, to_cloud, with_normals
from tasks.transfer.registration import surface_normals
from tasks.transfer.scan_noise import scan_noise


def _sheet(rng: np.random.Generator, spacing_m: float, noise_m: float, size_m: float = 0.2) -> np.ndarray:
    """A flat square patch, (size / spacing)^2 points sampled at random, its noise along z."""
    n = int((size_m / spacing_m) ** 2)
    xy = rng.uniform(0.0, size_m, size=(n, 2))
    return np.column_stack([xy, rng.normal(scale=noise_m, size=n)])


def _sphere(rng: np.random.Generator, n: int, radius_m: float, noise_m: float) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * (radius_m + rng.normal(scale=noise_m, size=(n, 1)))


@pytest.mark.parametrize(("spacing_m", "noise_m"), [(0.005, 0.0015), (0.002, 0.0005), (0.003, 0.002)])
def test_noise_of_a_flat_scan_is_measured(spacing_m: float, noise_m: float) -> None:
    points = _sheet(np.random.default_rng(3), spacing_m, noise_m)
    assert scan_noise(points, median_spacing(points)) == pytest.approx(noise_m, rel=0.15)


def test_a_curved_surface_does_not_count_as_noise() -> None:
    """A ball 40 mm in radius, 6,000 points (about 3 mm apart), 0.5 mm of noise: a plane over 20 neighbours
    would read the bend as a millimetre of scatter."""
    points = _sphere(np.random.default_rng(4), 6000, 0.04, 0.0005)
    assert scan_noise(points, median_spacing(points)) == pytest.approx(0.0005, rel=0.2)


def test_a_dense_noisy_scan_gets_normals_the_noise_does_not_tip_over() -> None:
    """1.5 mm of noise, points about 0.5 mm apart: 12 neighbours within 3 spacings tilt a normal by about 40
    degrees (median), as much the noise's direction as the surface's; over 3 noise sigmas, by half that."""
    points = _sheet(np.random.default_rng(5), 0.001, 0.0015, size_m=0.15)
    spacing = median_spacing(points)
    grown = surface_normals(points, spacing)
    counted = np.asarray(with_normals(to_cloud(points), 3.0 * spacing, max_nn=12).normals)

    def tilt(normals: np.ndarray) -> float:
        return float(np.median(np.degrees(np.arccos(np.clip(np.abs(normals[:, 2]), 0.0, 1.0)))))

    assert tilt(counted) > 35.0
    assert tilt(grown) < 0.6 * tilt(counted)


def test_a_sparse_scan_keeps_its_counted_neighbourhood() -> None:
    """Noise well under the spacing (1 mm, points about 2.5 mm apart): the normals are those of 12 neighbours
    within 3 spacings, local enough for thin parts."""
    points = _sheet(np.random.default_rng(6), 0.005, 0.001)
    spacing = median_spacing(points)
    counted = np.asarray(with_normals(to_cloud(points), 3.0 * spacing, max_nn=12).normals)
    np.testing.assert_allclose(np.abs(surface_normals(points, spacing)), np.abs(counted), atol=1e-12)
