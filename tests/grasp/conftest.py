"""Shared objects for the grasp tests: a lying cylinder (a handle) and a box, as sampled point clouds."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tests.grasp.surface_sampling import sample_box_surface, sample_cylinder_surface

HANDLE_CENTER = np.array([0.5, 0.0, 0.3])
"""A cylinder of radius 20 mm and length 160 mm lying along world x, centred here (metres)."""
PALM_DOWN = Rotation.from_euler("x", 180, degrees=True).as_quat()
"""Palm frame looking down (approach = world -z)."""


@pytest.fixture
def handle_points() -> tuple[Points, Points]:
    """(n, 3) points and outward normals of the lying cylinder, world metres."""
    rng = np.random.default_rng(0)
    pts, nrm = sample_cylinder_surface(0.02, 0.08, 3000, rng)
    rot = Rotation.from_euler("y", 90, degrees=True)
    return rot.apply(pts) + HANDLE_CENTER, rot.apply(nrm)


@pytest.fixture
def box_points() -> Points:
    """(n, 3) points on a 60 x 50 x 80 mm box standing at (0.5, 0.1, 0.3) (centre), world metres."""
    rng = np.random.default_rng(1)
    pts, _ = sample_box_surface(np.array([0.03, 0.025, 0.04]), 3000, rng)
    out: Points = np.asarray(pts + np.array([0.5, 0.1, 0.3]), dtype=np.float64)
    return out
