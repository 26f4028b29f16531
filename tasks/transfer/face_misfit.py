"""How far a fit's faces lie off their scan on average: a misfit the pairs' scatter does not show.

A fit's sigma comes from its pairs' scatter about it (``stretch.line_spread``), as if each face's pairs erred about
zero. Where the model and the object differ in shape where the fit cannot follow (a door thinner than the model's,
a face the scan holds behind another), a whole face's pairs lie off to one side and another face's to the other:
the fit balances them and the axis lands off by about that much, however tightly the pairs scatter. Such a face
shows as a mean residual beyond what its own scatter explains. Per face of the model (its pairs' model normals
snapped to the same direction, ``face_normals``, split where parallel faces lie apart along it), the part of the
mean residual beyond ``SIGNIFICANCE`` standard errors is a systematic error of the placement along that face's
normal; it adds to the position covariance across the axis (``bias_cov``). A face whose normal lies within
``AXIS_CONE_DEG`` of the axis does not place the axis across itself and is left out.
"""

from __future__ import annotations

import math

import numpy as np

from tasks.arrays import FloatArray, Points

SIGNIFICANCE = 2.0
"""A face's mean residual is a misfit where it lies beyond two of its standard errors (95 %, two-sided)."""
MIN_INDEPENDENT = 8.0
"""A face's pairs count when they make at least 8 independent observations: fewer leave its standard error itself
uncertain by more than a quarter."""
FACE_GAP_RMS = 6.0
"""Parallel faces are apart where their model points lie more than six of the pairs' RMS residual apart along the
normal (one face's points lie within three of it about its plane)."""
AXIS_CONE_DEG = 45.0
"""A face whose normal lies within 45 degrees of the axis moves the axis mostly along itself, not across."""


def _canonical(normals: Points) -> tuple[FloatArray, FloatArray]:
    """``normals`` (m, 3) unit, turned so that each one's largest component is positive, and the signs used."""
    largest = np.abs(normals).argmax(axis=1)
    sign = np.sign(normals[np.arange(len(normals)), largest])
    return normals * sign[:, None], sign


def bias_cov(
    source: Points,
    source_normals: Points,
    carried_normals: Points,
    residual: FloatArray,
    *,
    direction: FloatArray,
    rms_m: float,
    correlated: float,
) -> FloatArray:
    """(3, 3) covariance (metres squared, target frame, across the unit carried axis ``direction``) of the
    placement's systematic error from its faces' misfits: per face direction, the largest of its faces' mean
    residuals beyond ``SIGNIFICANCE`` standard errors, along that face's carried normal.

    ``source``: (m, 3) the pairs' model points (source frame, metres); ``source_normals``: (m, 3) their model
    normals, snapped onto face directions where they lie on a flat face (``face_normals``); ``carried_normals``:
    (m, 3) the same carried to the target (unit); ``residual``: (m,) each pair's point-to-plane residual along its
    carried normal (metres); ``rms_m``: the pairs' RMS residual; ``correlated``: pairs counting as one independent
    observation (``stretch.CORRELATED_POINTS``)."""
    out = np.zeros((3, 3))
    if len(source) == 0:
        return out
    across = np.eye(3) - np.outer(direction, direction)
    keys, sign = _canonical(np.asarray(source_normals, dtype=np.float64))
    faces, members, counts = np.unique(np.round(keys, 9), axis=0, return_inverse=True, return_counts=True)
    members = members.ravel()
    least = MIN_INDEPENDENT * correlated
    cone = math.cos(math.radians(AXIS_CONE_DEG))
    for f in np.flatnonzero(counts >= least):  # a curved surface's own normals are each a "face" of one
        face = np.flatnonzero(members == f)
        normal = (carried_normals[face] * sign[face, None]).mean(axis=0)
        normal /= np.linalg.norm(normal)
        if abs(float(normal @ direction)) > cone:
            continue
        offset = source[face] @ faces[f]
        order = np.argsort(offset)
        cuts = np.flatnonzero(np.diff(offset[order]) > FACE_GAP_RMS * rms_m) + 1
        worst = 0.0
        for part in np.split(order, cuts):
            if len(part) < least:
                continue
            r = residual[face[part]] * sign[face[part]]
            se = float(r.std()) / math.sqrt(len(r) / correlated)
            worst = max(worst, abs(float(r.mean())) - SIGNIFICANCE * se)
        moved = across @ normal
        out += worst**2 * np.outer(moved, moved)
    return out
