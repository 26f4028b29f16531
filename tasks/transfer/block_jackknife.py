"""How far a placement leans on each region of its pairs: the delete-a-group jackknife over spatial blocks.

A fit's sigma from its pairs' scatter (``stretch.line_spread``) counts ``stretch.CORRELATED_POINTS`` neighbouring
pairs as one observation. Where the model and the object differ in shape by more than the noise (a lever drawn
to other proportions than the stretch the whole body gives it), whole regions of pairs err together: the fit
balances them, and a denser scan shrinks that sigma as one over the square root of its pairs while the error
stays. Refitting with each of ``BLOCKS`` spatial blocks of the neighbourhood left out shows how
far the placement moves with each region: the spread of those refits is the delete-a-group jackknife variance
(Künsch 1989), which holds for pairs correlated within a block. A direction no block's pairs constrain does not
move in a refit started at the fit, so the jackknife knows nothing there: the placement's covariance is the
smallest that is at least the pairs' and at least the jackknife's in every direction across the axis
(``dominating``). Metres and radians, target frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from sklearn.cluster import KMeans

from tasks.arrays import FloatArray, Labels, Points, Vector3
from tasks.fit.geometry import perpendicular_basis

BLOCKS = 8
"""Blocks of a neighbourhood, k-means over its model points: each about one of its features (a lever's end, its
rose, a stretch of a hinge's edge), and the jackknife's variance has 7 degrees of freedom (its sigma is within
about 30 % at one sigma)."""


def block_labels(points: Points, blocks: int = BLOCKS) -> Labels:
    """(n,) block of each of ``points`` (m, metres): k-means with a fixed seed, so a transfer repeats exactly."""
    count = min(blocks, len(points))
    labels: Labels = KMeans(n_clusters=count, n_init=1, random_state=0).fit_predict(points).astype(np.int64)
    return labels


def jackknife(
    refit: Callable[[FloatArray], tuple[Vector3, Vector3]], labels: Labels, direction: Vector3
) -> tuple[FloatArray, float]:
    """The jackknife covariance (3, 3, metres squared, across unit ``direction``) of the axis point, and the
    direction's sigma (radians), from ``refit``: the axis's point and unit direction (target frame) fitted
    without the points where the given (n,) boolean mask is False, once per block of ``labels``."""
    across = np.eye(3) - np.outer(direction, direction)
    blocks = np.unique(labels)
    pos, turn = [], []
    for block in blocks:
        p, d = refit(labels != block)
        pos.append(across @ p)
        turn.append(across @ (d if float(d @ direction) >= 0.0 else -d))
    k = len(blocks)
    dp = np.array(pos) - np.mean(pos, axis=0)
    dd = np.array(turn) - np.mean(turn, axis=0)
    factor = (k - 1) / k
    cov: FloatArray = factor * dp.T @ dp
    return cov, math.sqrt(factor * float((dd**2).sum()) / 2.0)


def dominating(a: FloatArray, b: FloatArray, direction: Vector3) -> FloatArray:
    """The covariance (3, 3) across unit ``direction`` that is ``a`` where ``a`` covers ``b`` and ``b`` where ``b``
    exceeds it: ``a`` whitened, its eigenvalues of ``b`` raised to at least 1, coloured back. ``a`` must be
    positive definite across ``direction``."""
    basis = np.stack(perpendicular_basis(direction), axis=1)  # (3, 2)
    chol = np.linalg.cholesky(basis.T @ a @ basis)
    inv = np.linalg.inv(chol)
    values, vectors = np.linalg.eigh(inv @ (basis.T @ b @ basis) @ inv.T)
    cov2 = chol @ vectors @ np.diag(np.maximum(values, 1.0)) @ vectors.T @ chol.T
    out: FloatArray = basis @ cov2 @ basis.T
    return out
