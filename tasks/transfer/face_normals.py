"""Which model normals state a plane: a flat face's own normal, and the borders whose normals state none.

A point-to-plane pair is information along its plane's normal only where the model is that plane. Normals
estimated on a sampled model and smoothed (``stretch.smoothed_normals``) scatter by a fraction of a degree on a
flat face, and along a border between two faces they stay tilted by 5-22 degrees from the face the point lies on.
Either tilt, paired with a scan of that face, reads as information along the face (a door leaf's front face
"measuring" where its edges are), which the face does not give. So:

- the model's **face directions** are the directions that many of its normals share tightly (a flat face, or
  parallel faces), not a curved surface passing through them (``face_directions``);
- a normal within ``FLAT_DEG`` of a face direction is that direction exactly (``model_normals``);
- a normal tilted from a face direction by more than that but within ``BORDER_DEG`` lies on a border (or is a
  face's normal the smoothing could not settle): its plane is no face's, and its pair gives no point-to-plane
  information (weight 0);
- other normals (curved surfaces: a cap's side, a handle bar) keep their own direction, whose change from point to
  point is the surface's curvature.

Normals are unit and unsigned; frames are the model's own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tasks.arrays import FloatArray, Points

FLAT_DEG = 3.0
"""A smoothed normal within 3 degrees of a face direction lies on that flat face (a face's smoothed normals
scatter by 1-2 degrees with a careful scan's noise; a border's tilt starts at several)."""
BORDER_DEG = 30.0
"""A normal tilted 3-30 degrees from a face direction is a border's, or a face normal the smoothing could not settle
(a strip a few point spacings wide): within 30 degrees it pairs with a scan of that face (``stretch.NORMAL_COS``),
where its tilt reads as information along the face."""
FACE_SHARE = 0.02
"""A face direction holds at least 2 % of the model's normals within ``FLAT_DEG`` (a face, not a few points)."""
FACE_CONTRAST = 4.0
"""... and at least 4 times as many as lie between ``FLAT_DEG`` and twice it: a flat face's normals bunch, a
curved surface's spread evenly through the direction."""
CANDIDATES = 256
"""Model normals tried as face directions (every n/256-th)."""


@dataclass(frozen=True)
class ModelNormals:
    """A model's normals for point-to-plane pairs and how much each pair's plane informs (model frame)."""

    normals: Points
    """(n, 3) unit: face directions on flat faces, the smoothed normal elsewhere."""
    plane_weight: FloatArray
    """(n,) 1 where the normal states the surface's plane, 0 on borders between faces."""
    directions: FloatArray
    """(k, 3) unit face directions found (unsigned)."""


def face_directions(normals: Points) -> FloatArray:
    """(k, 3) unit directions that at least ``FACE_SHARE`` of ``normals`` ((n, 3) unit, unsigned) lie within
    ``FLAT_DEG`` of, with ``FACE_CONTRAST`` times fewer in the ring out to twice that; most populous first."""
    flat, ring = math.cos(math.radians(FLAT_DEG)), math.cos(math.radians(2.0 * FLAT_DEG))
    border = math.cos(math.radians(BORDER_DEG))
    remaining = np.ones(len(normals), dtype=bool)
    candidates = normals[:: max(1, len(normals) // CANDIDATES)]
    found: list[FloatArray] = []
    while remaining.any():
        cos = np.abs(normals[remaining] @ candidates.T)  # (r, c)
        inside = (cos >= flat).sum(axis=0)
        around = ((cos >= ring) & (cos < flat)).sum(axis=0)
        ok = (inside >= max(FACE_SHARE * len(normals), 12)) & (inside >= FACE_CONTRAST * around)
        if not ok.any():
            break
        best = candidates[int(np.where(ok, inside, -1).argmax())]
        members = normals[remaining][np.abs(normals[remaining] @ best) >= flat]
        _, vecs = np.linalg.eigh(members.T @ members)
        direction = vecs[:, -1]
        found.append(direction)
        remaining &= np.abs(normals @ direction) < border
    return np.array(found, dtype=np.float64).reshape(-1, 3)


def model_normals(normals: Points) -> ModelNormals:
    """A model's normals for point-to-plane pairs from its smoothed ``normals`` ((n, 3) unit, unsigned): snapped
    onto the face directions within ``FLAT_DEG``, weight 0 where tilted from one by ``FLAT_DEG``-``BORDER_DEG``
    (module docstring)."""
    normals = np.asarray(normals, dtype=np.float64)
    directions = face_directions(normals)
    weight = np.ones(len(normals))
    if not len(directions):
        return ModelNormals(normals, weight, directions)
    cos = normals @ directions.T  # (n, k)
    k = np.abs(cos).argmax(axis=1)
    best = cos[np.arange(len(cos)), k]
    snapped = np.abs(best) >= math.cos(math.radians(FLAT_DEG))
    tilted = ~snapped & (np.abs(best) >= math.cos(math.radians(BORDER_DEG)))
    out = normals.copy()
    out[snapped] = directions[k[snapped]] * np.sign(best[snapped])[:, None]
    weight[tilted] = 0.0
    return ModelNormals(out, weight, directions)
