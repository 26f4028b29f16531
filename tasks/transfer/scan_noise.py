"""A scan's noise across its surface, measured on the scan itself (lengths in metres).

A surface normal is the least-variance direction of a point's neighbours. Over a disc of radius r the neighbours
spread by r^2 / 4 across it and by the noise's sigma^2 along the normal: where r is not several sigmas, the
least-variance direction is as much the noise's as the surface's, and a neighbourhood counted in point spacings
reaches fewer noise sigmas the denser the scan. ``registration.surface_normals`` therefore also reaches a stated
number of the noise sigmas measured here.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import chi2

from tasks.arrays import Points

SAMPLE = 500
"""Points the noise is measured about (evenly through the cloud)."""
NEIGHBOURS = 10
"""Each is fitted a quadric over at least its 10 nearest points: the fewest that leave its 6 unknowns a scatter
to measure (4 degrees of freedom), so that a sparse scan's patches stay on one face ..."""
MAX_NEIGHBOURS = 400
"""... and more where the noise is not small against their reach (``NOISE_REACH``), up to 400."""
NOISE_REACH = 10.0
"""A quadric measures the noise where its points reach 10 noise sigmas from its centre: over a patch hardly wider
than the noise, the least-variance plane and the quadric follow the noise itself and read it as smaller (on a flat
patch, 10 % smaller at 7 sigmas, 3 % at 10)."""
QUANTILE = 0.25
"""The noise is read off the quarter of the points whose quadric fits best, scaled by what that quantile of a
pure-noise scatter is: edges, gaps and handles, where one quadric cannot follow the surface, stay above it."""
MIN_NOISE_M = 1e-5
"""Noise below 10 micrometres counts as 10: an exact cloud (a CAD model's samples) needs no wider neighbourhood."""
LN2 = math.log(2.0)


def _quadric_noise(points: Points, tree: cKDTree, centres: np.ndarray, k: int) -> float:
    """The ``QUANTILE`` noise estimate from quadrics over the ``k`` nearest points of each centre."""
    _, idx = tree.query(points[centres], k=k)
    local = points[idx] - points[idx].mean(axis=1, keepdims=True)  # (m, k, 3)
    _, vecs = np.linalg.eigh(np.einsum("mki,mkj->mij", local, local))
    frame = np.einsum("mki,mij->mkj", local, vecs)  # columns: least-variance direction first
    h, u, v = frame[..., 0], frame[..., 1], frame[..., 2]
    design = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=-1)  # (m, k, 6)
    gram = np.einsum("mki,mkj->mij", design, design) + 1e-18 * np.eye(6)
    coef = np.linalg.solve(gram, np.einsum("mki,mk->mi", design, h)[..., None])[..., 0]
    resid = h - np.einsum("mki,mi->mk", design, coef)
    dof = k - 6
    rms = np.sqrt((resid**2).sum(axis=1) / dof)
    return float(np.quantile(rms, QUANTILE)) / math.sqrt(chi2.ppf(QUANTILE, dof) / dof)


def scan_noise(points: Points, spacing_m: float) -> float:
    """One-sigma noise of ``points`` (n, 3) across their surface, metres, at median nearest-neighbour spacing
    ``spacing_m``: the RMS residual of a quadric (a height over the neighbours' least-variance plane, so a curved
    surface does not count as noise) fitted about ``SAMPLE`` points, over ``NEIGHBOURS`` points, and again over
    as many as reach ``NOISE_REACH`` noise sigmas while fewer do."""
    n = points.shape[0]
    if n <= NEIGHBOURS:
        return MIN_NOISE_M
    tree = cKDTree(points)
    centres = np.arange(0, n, max(1, n // SAMPLE), dtype=np.intp)
    k = NEIGHBOURS
    noise = max(_quadric_noise(points, tree, centres, k), MIN_NOISE_M)
    while k < min(MAX_NEIGHBOURS, n - 1):
        wanted = math.ceil(LN2 * (NOISE_REACH * noise / max(spacing_m, 1e-9)) ** 2)  # points within the reach
        if wanted <= k:
            break
        k = min(wanted, MAX_NEIGHBOURS, n - 1)  # a patch too narrow reads the noise as smaller
        noise = max(noise, _quadric_noise(points, tree, centres, k))
    return noise
