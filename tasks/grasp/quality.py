"""Grasp wrench space qualities (Ferrari & Canny 1992; GraspIt!'s QualEpsilon and QualVolume).

Each contact contributes the 8 edges of a linearised Coulomb friction cone (normal component 1, friction
coefficient ``mu``); the wrench of an edge force ``f`` at contact ``c`` is ``(f, (c - centre) × f / radius)``,
torques divided by the object's largest radius so forces and torques are comparable. The grasp wrench space
is the convex hull (scipy's qhull) of all edge wrenches: epsilon = radius of the largest origin-centred ball
inside it (0 when the origin is not strictly inside, i.e. no force closure), volume = its 6-D volume.

Force closure is decided by one linear program (scipy's HiGHS), without the hull: the origin lies inside the
hull exactly when the edge wrenches span the six dimensions and a combination of all of them with every weight
positive sums to zero (the relative interior of a hull is the set of such combinations). The hull (qhull's 6-D hull
of up to 128 edge wrenches takes up to 35 ms) is built only when epsilon or the volume is asked for: the planner
ranks and checks grasps by force closure and reports the qualities of the one it keeps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, QhullError

from tasks.arrays import FloatArray, Points, Vector3

CONE_EDGES = 8
DEFAULT_MU = 0.5
"""Friction coefficient of the Barrett's rubber-coated links on household objects (GraspIt! uses 0.5..1)."""


@dataclass(frozen=True)
class GraspQuality:
    """The number of contacts used and their (8 m, 6) edge wrenches, ``mu`` the friction coefficient they were
    computed with; ``force_closure`` (``_origin_inside``), ``epsilon`` (L1 GWS, unitless; 0 without force closure)
    and ``volume`` (6-D, unitless; 0 when the GWS is flat) on first use."""

    contacts: int
    wrenches: FloatArray = field(default_factory=lambda: np.zeros((0, 6)), repr=False, compare=False)
    mu: float = DEFAULT_MU
    """The friction coefficient of the contacts' cones."""

    @cached_property
    def force_closure(self) -> bool:
        """Whether the origin lies inside the grasp wrench space."""
        return _origin_inside(self.wrenches)

    @cached_property
    def _hull(self) -> ConvexHull | None:
        """qhull's hull of the wrenches, None when they span fewer than six dimensions."""
        if len(self.wrenches) == 0 or np.linalg.matrix_rank(self.wrenches, tol=1e-9) < 6:
            return None
        try:
            return ConvexHull(self.wrenches)
        except QhullError:
            return None

    @cached_property
    def epsilon(self) -> float:
        """Radius of the largest origin-centred ball inside the grasp wrench space (0 without force closure)."""
        if not self.force_closure or self._hull is None:
            return 0.0
        # facets: normal·x + offset <= 0 inside, unit normals; the origin's distance to a facet is -offset
        return max(float(np.min(-self._hull.equations[:, -1])), 0.0)

    @cached_property
    def volume(self) -> float:
        """6-D volume of the grasp wrench space (unitless; 0 when it is flat)."""
        return 0.0 if self._hull is None else float(self._hull.volume)


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
    """The quality of the contacts (see the module docstring), each measure computed on first use."""
    if len(positions) == 0:
        return GraspQuality(0, mu=mu)
    return GraspQuality(len(positions), contact_wrenches(positions, normals_in, center, radius, mu), mu=mu)


def _origin_inside(wrenches: FloatArray) -> bool:
    """Whether the origin lies inside the hull of the (k, 6) wrenches: they span six dimensions and the largest
    smallest weight s of a combination sum l_i w_i = 0, sum l_i = 1, l_i >= s (HiGHS) exceeds ``MIN_WEIGHT``."""
    k = len(wrenches)
    if k < 7 or np.linalg.matrix_rank(wrenches, tol=1e-9) < 6:
        return False
    a_eq = np.zeros((7, k + 1))
    a_eq[:6, :k] = wrenches.T
    a_eq[6, :k] = 1.0
    b_eq = np.zeros(7)
    b_eq[6] = 1.0
    a_ub = np.hstack([-np.eye(k), np.ones((k, 1))])  # s - l_i <= 0
    cost = np.zeros(k + 1)
    cost[-1] = -1.0
    bounds = [(0.0, None)] * k + [(None, None)]
    result = linprog(cost, A_ub=a_ub, b_ub=np.zeros(k), A_eq=a_eq, b_eq=b_eq, bounds=bounds, method="highs")
    return bool(result.status == 0 and -float(result.fun) > MIN_WEIGHT)


MIN_WEIGHT = 1e-7
"""Smallest weight per edge wrench of a balanced combination for the origin to count as inside (HiGHS's feasibility
tolerance): below it the origin lies on the hull's boundary, no force closure."""
