"""Where to start an axis neighbourhood's fit when the whole model places the axis only loosely.

A local point-to-plane fit converges to the features within its correspondence distance of where they start.
The whole model's stretched fit may know an axis only to tens of millimetres across it (a door's lever: the
leaf's height, and the lever's with it, is not measured where the scan misses the leaf's bottom), while the
features that pin the axis are smaller (a lever 20 mm tall). Started that far off, the neighbourhood's fit
settles on a partial overlap and reports the sigma of that basin (a lever 19 mm off with a sigma of 0.3 mm).

So when three of the whole model's sigmas across the axis exceed the distance the fit starts with (its reach),
the neighbourhood is first slid across the axis over a grid covering those three sigmas (within its radius), and
each offset is scored by how closely the points that pin the axis (normals across it) lie on the scan: each
counts by a Gaussian of its distance along its normal to its pair (the nearest scan point of the same facing
within the features' own distance ``dist_m``, finer than the whole model's threshold: ``pairing``), half a grid
step wide (where the true offset may lie from the nearest one). A count of pairs within the distance alone
rewards covering the scan rather than lying on it: a lever arm 20 mm tall, scanned on its top face only, slid
half its height up pairs both its faces, 10 mm off, with the scanned one. When the whole model's own
placement scores as well as the best offset (within the score's binomial noise), nothing says the features lie
elsewhere and the fit starts there as before (a hinge, free along its face, scores alike all along it). Else it
starts from the best offset, at twice the features' distance and then at it. Offsets more than twice that
distance from the best that score as well are places the scan does not tell apart: their distance is returned,
and the fit's sigma must cover it. Lengths in metres, target frame unless named otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from tasks.arrays import Points, Vector3
from tasks.fit.geometry import perpendicular_basis
from tasks.transfer.pairing import nearest_compatible
from tasks.transfer.similarity import Similarity
from tasks.transfer.stretch import CORRELATED_POINTS, NORMAL_COS, Stretched, carried_normals

SEARCH_SIGMAS = 3.0
"""The search covers three of the whole model's sigmas across the axis (where its placement may lie)."""
ACROSS_COS = math.cos(math.radians(45.0))
"""A point pins the axis across itself when its normal is within 45 degrees of square to the axis."""
MAX_STEPS = 20
"""At most this many grid steps on either side of the start along each direction across the axis."""
NOISE_SIGMAS = 2.0
"""Offsets scoring within two binomial sigmas of the best are as good as it."""
ONE_PEAK_DISTANCES = 2.0
"""A placement keeps its features within the distance of their counterparts while it is off by less than the
distance either way: offsets up to twice the distance apart can score alike about one placement."""


@dataclass(frozen=True)
class SearchResult:
    """The start chosen for the neighbourhood's fit and how far apart equally good starts lie."""

    start: Stretched
    spread_m: float
    """Largest distance from the chosen offset to another as good, metres (0: none farther than the distance)."""


def search_start(
    whole: Stretched,
    region: Points,
    normals: Points,
    target: Points,
    target_normals: Points,
    *,
    line: tuple[Vector3, Vector3],
    sigma_m: float,
    radius_m: float,
    dist_m: float,
    reach_m: float,
) -> SearchResult | None:
    """The start for the fit of ``region`` (source frame, its unit ``normals``) about ``line`` (source point, unit
    direction), from ``whole`` whose sigma across the axis is ``sigma_m``; ``target``: the scan (m, 3) and
    ``target_normals`` its unit normals (unsigned); ``dist_m``:
    the fit's last correspondence distance and ``reach_m`` its first; ``radius_m``: the neighbourhood's radius
    (source metres). None when the fit reaches where the whole model may have put the axis (three sigmas within
    ``reach_m``), no point pins the axis, or the whole model's placement scores as well as the best offset."""
    pos, direction = line
    extent = min(SEARCH_SIGMAS * sigma_m, radius_m * whole.similarity.scale)
    if not math.isfinite(extent) or extent <= reach_m:
        return None
    pins = np.abs(normals @ direction) < ACROSS_COS
    if int(pins.sum()) < 2 * CORRELATED_POINTS:
        return None
    carried = whole.apply_points(region[pins])
    facing = carried_normals(whole, normals[pins])
    _, axis_dir = whole.carry_line(pos, direction)
    u, v = perpendicular_basis(axis_dir)
    tree = cKDTree(target)  # only when searching: the scan may hold hundreds of thousands of points
    step = max(dist_m / 2.0, extent / MAX_STEPS)
    ticks = step * np.arange(-math.floor(extent / step), math.floor(extent / step) + 1)
    offsets = np.array([(a, b) for a in ticks for b in ticks if a * a + b * b <= extent * extent + 1e-12])
    scores = np.empty(len(offsets))
    width = step / 2.0
    for k, (a, b) in enumerate(offsets):
        moved = carried + a * u + b * v
        idx, found = nearest_compatible(tree, moved, facing, target_normals, dist_m=dist_m, min_cos=NORMAL_COS)
        gap = np.einsum("ij,ij->i", facing[found], tree.data[idx[found]] - moved[found])
        scores[k] = float(np.exp(-0.5 * (gap / width) ** 2).sum()) / len(moved)
    best = int(np.argmax(scores))
    n_eff = carried.shape[0] / CORRELATED_POINTS
    noise = NOISE_SIGMAS * math.sqrt(max(scores[best] * (1.0 - scores[best]), 1.0 / n_eff) / n_eff)
    if scores[int(np.argmin(np.linalg.norm(offsets, axis=1)))] >= scores[best] - noise:
        return None  # the whole model's placement scores as well: nothing says the features lie elsewhere
    apart = np.linalg.norm(offsets - offsets[best], axis=1)
    alike = (scores >= scores[best] - noise) & (apart > ONE_PEAK_DISTANCES * dist_m)
    a, b = offsets[best]
    start = Stretched(
        Similarity(whole.similarity.scale, whole.similarity.rotation, whole.similarity.translation + a * u + b * v),
        whole.axes,
        whole.factors,
        whole.centre,
    )
    return SearchResult(start, float(apart[alike].max()) if alike.any() else 0.0)
