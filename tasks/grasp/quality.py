"""Grasp wrench space qualities (Ferrari & Canny 1992; GraspIt!'s QualEpsilon and QualVolume).

Each contact contributes the 8 edges of a linearised Coulomb friction cone (normal component 1, friction
coefficient ``mu``); the wrench of an edge force ``f`` at contact ``c`` is ``(f, (c - centre) × f / radius)``,
torques divided by the object's largest radius so forces and torques are comparable. The grasp wrench space
is the convex hull (scipy's qhull) of all edge wrenches: epsilon = radius of the largest origin-centred ball
inside it (0 when the origin is not strictly inside, i.e. no force closure), volume = its 6-D volume.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from tasks.arrays import FloatArray, Points, Vector3

CONE_EDGES = 8
DEFAULT_MU = 0.5
"""Friction coefficient of the Barrett's rubber-coated links on household objects (GraspIt! uses 0.5..1)."""


@dataclass(frozen=True)
class GraspQuality:
    """Epsilon (L1 GWS, unitless), volume of the GWS, force closure, and the number of contacts used."""

    epsilon: float
    volume: float
    force_closure: bool
    contacts: int


def contact_wrenches(positions: Points, normals_in: Points, center: Vector3, radius: float, mu: float) -> FloatArray:
    """(8 m, 6) edge wrenches of ``m`` contacts: positions (m, 3) metres, ``normals_in`` (m, 3) into the object."""
    n = normals_in / np.linalg.norm(normals_in, axis=1, keepdims=True)
    helper = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    angles = np.arange(CONE_EDGES) * (2.0 * math.pi / CONE_EDGES)
    forces = n[:, None, :] + mu * (
        np.cos(angles)[None, :, None] * t1[:, None, :] + np.sin(angles)[None, :, None] * t2[:, None, :]
    )
    arms = (positions - center)[:, None, :]
    torques = np.cross(arms, forces) / radius
    return np.concatenate([forces, torques], axis=2).reshape(-1, 6)


def grasp_quality(
    positions: Points, normals_in: Points, center: Vector3, radius: float, mu: float = DEFAULT_MU
) -> GraspQuality:
    """Epsilon and volume of the grasp wrench space of the contacts (see module docstring)."""
    count = len(positions)
    if count == 0:
        return GraspQuality(0.0, 0.0, False, 0)
    wrenches = contact_wrenches(positions, normals_in, center, radius, mu)
    if np.linalg.matrix_rank(wrenches, tol=1e-9) < 6:
        return GraspQuality(0.0, 0.0, False, count)
    try:
        hull = ConvexHull(wrenches)
    except QhullError:
        return GraspQuality(0.0, 0.0, False, count)
    # facets: normal·x + offset <= 0 inside, unit normals; the origin's distance to a facet is -offset
    epsilon = float(np.min(-hull.equations[:, -1]))
    closure = epsilon > 1e-9
    return GraspQuality(max(epsilon, 0.0), float(hull.volume), closure, count)
