"""Which model normals state a plane: a flat face's own normal, and the borders whose normals state none.

A point-to-plane pair is information along its plane's normal only where the model is that plane. Normals
estimated on a sampled model and smoothed (``stretch.smoothed_normals``) scatter by a fraction of a degree on a
flat face, and along a border between two faces they stay tilted by 5-22 degrees from the face the point lies on.
Either tilt, paired with a scan of that face, reads as information along the face (a door leaf's front face
"measuring" where its edges are), which the face does not give. So:

- the model's **face directions** are the directions that many of its normals share tightly (a flat face, or
  parallel faces), not a curved surface passing through them (``face_directions``);
- a normal within ``FLAT_DEG`` of a face direction (or a few of the normals' own scatter, where more) is that
  direction exactly (``model_normals``);
- a normal tilted from a face direction by more than that but within ``BORDER_DEG`` lies on a border (or is a
  face's normal the smoothing could not settle): its plane is no face's, and its pair gives no point-to-plane
  information (weight 0);
- other normals (curved surfaces: a cap's side, a handle bar) keep their own direction, whose change from point to
  point is the surface's curvature;
- a pair measures its scan point against the plane of a model point some way off along the surface, and the plane
  stands for the surface only as far as the model's points there lie on it (``plane_scatter``): where the surface
  curves or breaks within that offset (a spindle 9 mm in radius, sampled every 6 mm, paired 15 mm along), the
  plane misplaces the surface by as much as they stray from it.

Normals are unit and unsigned; frames are the model's own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import chi2

from tasks.arrays import FloatArray, Points

FLAT_DEG = 3.0
"""A smoothed normal within 3 degrees of a face direction lies on that flat face (a face's smoothed normals
scatter by 1-2 degrees with a careful scan's noise; a border's tilt starts at several) ..."""
FLAT_SCATTERS = 2.5
"""... or within 2.5 of the normals' own scatter on the model's tightest face where that is more (``normal_scatter``):
a normal's tilt grows with the noise over the spacing (0.5 mm of noise every 1.5 mm scatters a face's smoothed
normals by about 1.8 degrees, every 5 mm by 0.7), and 2.5 scatters hold 96 % of a face's normals (tilts about a
direction, two-dimensional normal)."""
SCATTER_CONE_DEG = 10.0
"""The scatter is first measured over the normals within 10 degrees of a candidate direction, then over four of
that scatter where wider (a face whose normals scatter widely is not cut off)."""
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
CHUNK_ROWS = 8192
"""Normals compared with the candidates at a time (an (8192, 256) cosine block, 16 MB, whatever the model's size)."""
SCATTER_SPACINGS = 2.0
"""A pair's plane is checked over at least two model point spacings about its model point (a few neighbours each
way, enough to see the surface bend; less than a door's or leaf's thickness, so a parallel face behind stays out)."""
NOISE_QUANTILE = 0.5
"""A model's own noise is the median of its planes' scatter (most of a box is flat faces, most of a body of
revolution curves gently over a few spacings)."""
NOISE_SAMPLE = 1000
"""Model points the noise is measured on (every n/1000-th)."""
PLANE_CONFIDENCE = 0.99
"""A plane holds where its scatter is within what the model's noise gives at 99 % (chi-square over the points
that test it): a flat face's planes nearly all pass, a surface bending off the plane by more than the noise fails."""


@dataclass(frozen=True)
class ModelNormals:
    """A model's normals for point-to-plane pairs and how much each pair's plane informs (model frame)."""

    normals: Points
    """(n, 3) unit: face directions on flat faces, the smoothed normal elsewhere."""
    plane_weight: FloatArray
    """(n,) 1 where the normal states the surface's plane, 0 on borders between faces."""
    directions: FloatArray
    """(k, 3) unit face directions found (unsigned)."""
    flat_deg: float = FLAT_DEG
    """Normals within this of a face direction lie on the face (``flat_degrees``), degrees."""


def _principal(normals: Points) -> FloatArray:
    """The unit direction (either sign) that unsigned ``normals`` (m, 3) lie closest to: their scatter's main axis."""
    _, vecs = np.linalg.eigh(normals.T @ normals)
    out: FloatArray = vecs[:, -1]
    return out


def _spread(members: Points) -> tuple[FloatArray, float]:
    """The direction ``members`` (m, 3, unit, unsigned) share and their scatter about it: the Rayleigh scale of
    their tilts from it, from the tilts' median (degrees)."""
    direction = _principal(members)
    tilt = np.degrees(np.arccos(np.clip(np.abs(members @ direction), 0.0, 1.0)))
    return direction, float(np.median(tilt)) / math.sqrt(2.0 * math.log(2.0))


def _least_face(n: int) -> float:
    """Normals of ``n`` that a face direction must hold: ``FACE_SHARE`` of them, at least 12."""
    return max(FACE_SHARE * n, 12)


def _within(normals: Points, candidates: Points, cosines: tuple[float, ...]) -> np.ndarray:
    """(len(cosines), c) counts of ``normals`` ((n, 3) unit, unsigned) at least each of ``cosines`` from each of
    ``candidates`` ((c, 3) unit), counted ``CHUNK_ROWS`` normals at a time so memory stays bounded."""
    out = np.zeros((len(cosines), len(candidates)), dtype=np.int64)
    for start in range(0, len(normals), CHUNK_ROWS):
        cos = np.abs(normals[start : start + CHUNK_ROWS] @ candidates.T)
        for i, limit in enumerate(cosines):
            out[i] += (cos >= limit).sum(axis=0)
    return out


def normal_scatter(normals: Points) -> float:
    """The scatter (degrees; the Rayleigh scale of their tilts) of ``normals`` ((n, 3) unit, unsigned) about the
    tightest direction that at least ``FACE_SHARE`` of them share within ``SCATTER_CONE_DEG``; nan when none does."""
    candidates = normals[:: max(1, len(normals) // CANDIDATES)]
    cone = math.cos(math.radians(SCATTER_CONE_DEG))
    counts = _within(normals, candidates, (cone,))[0]
    least = math.inf
    seen: list[FloatArray] = []
    for c in np.argsort(-counts, kind="stable"):
        if counts[c] < _least_face(len(normals)):
            break
        if any(abs(float(candidates[c] @ d)) >= cone for d in seen):
            continue  # a direction already measured
        direction, scatter = _spread(normals[np.abs(normals @ candidates[c]) >= cone])
        wider = math.cos(math.radians(min(max(SCATTER_CONE_DEG, 4.0 * scatter), BORDER_DEG)))
        direction, scatter = _spread(normals[np.abs(normals @ direction) >= wider])
        seen.append(direction)
        least = min(least, scatter)
    return least if math.isfinite(least) else float("nan")


def flat_degrees(normals: Points) -> float:
    """How far (degrees) a normal of ``normals`` may tilt from a face direction and lie on that face:
    ``FLAT_DEG``, or ``FLAT_SCATTERS`` of the normals' own scatter where more."""
    scatter = normal_scatter(normals)
    return max(FLAT_DEG, FLAT_SCATTERS * scatter) if math.isfinite(scatter) else FLAT_DEG


def face_directions(normals: Points, flat_deg: float = FLAT_DEG) -> FloatArray:
    """(k, 3) unit directions that at least ``FACE_SHARE`` of ``normals`` ((n, 3) unit, unsigned) lie within
    ``flat_deg`` of, with ``FACE_CONTRAST`` times fewer in the ring out to twice that; most populous first."""
    flat, ring = math.cos(math.radians(flat_deg)), math.cos(math.radians(2.0 * flat_deg))
    border = math.cos(math.radians(BORDER_DEG))
    remaining = np.ones(len(normals), dtype=bool)
    candidates = normals[:: max(1, len(normals) // CANDIDATES)]
    found: list[FloatArray] = []
    while remaining.any():
        inside, within_ring = _within(normals[remaining], candidates, (flat, ring))
        around = within_ring - inside
        ok = (inside >= _least_face(len(normals))) & (inside >= FACE_CONTRAST * around)
        if not ok.any():
            break
        best = candidates[int(np.where(ok, inside, -1).argmax())]
        direction = _principal(normals[remaining][np.abs(normals[remaining] @ best) >= flat])
        found.append(direction)
        remaining &= np.abs(normals @ direction) < border
    return np.array(found, dtype=np.float64).reshape(-1, 3)


def model_normals(normals: Points) -> ModelNormals:
    """A model's normals for point-to-plane pairs from its smoothed ``normals`` ((n, 3) unit, unsigned): snapped
    onto the face directions within ``flat_degrees``, weight 0 where tilted from one by that to ``BORDER_DEG``
    (module docstring)."""
    normals = np.asarray(normals, dtype=np.float64)
    flat_deg = flat_degrees(normals)
    directions = face_directions(normals, flat_deg)
    weight = np.ones(len(normals))
    if not len(directions):
        return ModelNormals(normals, weight, directions, flat_deg)
    cos = normals @ directions.T  # (n, k)
    k = np.abs(cos).argmax(axis=1)
    best = cos[np.arange(len(cos)), k]
    snapped = np.abs(best) >= math.cos(math.radians(flat_deg))
    tilted = ~snapped & (np.abs(best) >= math.cos(math.radians(BORDER_DEG)))
    out = normals.copy()
    out[snapped] = directions[k[snapped]] * np.sign(best[snapped])[:, None]
    weight[tilted] = 0.0
    return ModelNormals(out, weight, directions, flat_deg)


def plane_scatter(
    points: Points, normals: Points, tree: cKDTree, at: np.ndarray, radius_m: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """(m,) RMS distance (metres) of the model ``points`` ((n, 3) metres, indexed by ``tree``) within
    ``radius_m[i]`` of model point ``at[i]`` whose normals face its own within ``BORDER_DEG`` (those a scan point
    paired with its plane may lie on) from their best plane along its normal (``normals``): about the model's
    noise on a flat face, the sag of the surface where it curves within the radius, the step where it breaks, the
    tilt where the normal is not the surface's; and how many points that is."""
    cos = math.cos(math.radians(BORDER_DEG))
    out, count = np.zeros(len(at)), np.zeros(len(at))
    for i, (k, found) in enumerate(zip(at, tree.query_ball_point(points[at], radius_m), strict=True)):
        near = np.asarray(found, dtype=np.intp)
        alike = near[np.abs(normals[near] @ normals[k]) >= cos]
        out[i] = float(np.std(points[alike] @ normals[k])) if len(alike) else 0.0
        count[i] = len(alike)
    return out, count


def plane_holds(points: Points, normals: Points, tree: cKDTree, at: np.ndarray, offset_m: FloatArray) -> np.ndarray:
    """(m,) bool: the plane of model point ``at[i]`` stands for the model over ``offset_m[i]`` (metres, at least
    ``SCATTER_SPACINGS`` model spacings) about it: the model's points there that face the same way
    (``plane_scatter``) stray from it no more than the model's own noise explains (``PLANE_CONFIDENCE``; the noise:
    the ``NOISE_QUANTILE`` of its planes' scatter). ``points`` (n, 3) metres, ``normals`` (n, 3)
    unit, indexed by ``tree``."""
    sample = np.arange(0, len(points), max(1, len(points) // NOISE_SAMPLE), dtype=np.intp)
    spacing = float(np.median(tree.query(points[sample], k=2)[0][:, 1]))
    least = np.full(len(sample), SCATTER_SPACINGS * spacing)
    noise, _ = plane_scatter(points, normals, tree, sample, least)
    noise_var = float(np.percentile(noise, 100.0 * NOISE_QUANTILE)) ** 2
    scatter, count = plane_scatter(points, normals, tree, at, np.maximum(offset_m, SCATTER_SPACINGS * spacing))
    dof = np.maximum(count - 1.0, 1.0)
    limit = chi2.ppf(PLANE_CONFIDENCE, dof) / dof
    out: np.ndarray = scatter**2 <= limit * noise_var
    return out
