"""The nearest scan point whose surface faces as a model point's does: the pairing of the stretched fits.

A point-to-plane pair joins a model point to the scan of the same face. Taking the nearest scan point and then
dropping the pair when the normals disagree loses every face that lies nearer another face of the scan than
its own counterpart: a door's edge face, 40 mm wide, whose scan lies 30 mm off across a model stretched too
little, has the scan of the door's front within a few millimetres of each of its points, so its pairs are all
dropped and the stretch that would bring the edge in is never measured. The pair is therefore the nearest scan
point within the distance whose normal agrees (the "compatible point" of Godin, Rioux and Baribeau, 1994).
scipy's KD-tree has no such query; the nearest ``k`` are taken and ``k`` grows only for the points whose ``k``
nearest all lie within the distance and none agrees.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from tasks.arrays import Points

FIRST_K = 8
"""Neighbours asked for first: on a face away from its borders one of the nearest few agrees even where the
scan's estimated normals tilt with its noise, so most points are paired in one query (the result does not depend
on it: ``bench/pairing.py`` prints the time)."""
GROWTH = 4
"""Each further round asks the points still unpaired for this many times more neighbours."""
CHUNK = 1 << 20
"""At most this many neighbours are held at once (about 50 MB with their normals): a dense scan holds tens of
thousands of points within a wide distance of a face it does not show."""


def nearest_compatible(
    tree: cKDTree,
    points: Points,
    normals: Points,
    target_normals: Points,
    *,
    dist_m: float,
    min_cos: float,
) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``points`` (n, 3, metres) with unit ``normals`` (n, 3): the index into ``tree``'s points of the
    nearest one within ``dist_m`` whose unit normal (``target_normals``, unsigned) makes an angle with its own of
    cosine at least ``min_cos`` in magnitude, and whether there is one ((n,) int, (n,) bool; the index is
    ``len(target_normals)`` where there is none)."""
    n_target = len(target_normals)
    idx = np.full(len(points), n_target, dtype=np.intp)
    found = np.zeros(len(points), dtype=bool)
    pending = np.arange(len(points))
    k = min(FIRST_K, n_target)
    while len(pending) and k > 0:
        further = []
        for chunk in np.array_split(pending, min(len(pending), max(1, len(pending) * k // CHUNK))):
            dist, near = tree.query(points[chunk], k=k, distance_upper_bound=dist_m)
            dist, near = dist.reshape(len(chunk), -1), near.reshape(len(chunk), -1)
            within = np.isfinite(dist)
            safe = np.where(within, near, 0)
            agree = within & (np.abs(np.einsum("ikj,ij->ik", target_normals[safe], normals[chunk])) >= min_cos)
            first = np.argmax(agree, axis=1)
            hit = agree[np.arange(len(chunk)), first]
            idx[chunk[hit]] = safe[hit, first[hit]]
            found[chunk[hit]] = True
            further.append(chunk[~hit & within[:, -1]])  # all k within the distance, none agrees: there may be more
        if k >= n_target:
            break
        pending = np.concatenate(further)
        k = min(k * GROWTH, n_target)
    return idx, found
