"""The paper's segmentation (Table I): spectral clustering of one marker's samples in space and time.

A_ij = exp(-|p_i - p_j|^2 / 2 dp^2 - |t_i - t_j|^2 / 2 dt^2), L = D^-1/2 A D^-1/2, the k largest eigenvectors
as columns, rows normalised to unit length, k-means on the rows. Dense (``scipy.linalg.eigh``) up to
``DENSE_LIMIT`` samples; beyond, the affinity keeps only each sample's ``NEIGHBOURS`` nearest neighbours in
the scaled (p / dp, t / dt) space (a sparse matrix; the dense one would need n^2 * 8 bytes, 10 GB at 36,000
samples) and the block solver ``scipy.sparse.linalg.lobpcg`` finds the top eigenvectors (Lanczos, ``eigsh``,
misses repeated eigenvalues, which nearly disconnected clusters produce). With k = "auto", the eigengap heuristic.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.linalg import eigh
from scipy.sparse import csr_matrix
from scipy.sparse.linalg import lobpcg
from scipy.spatial import cKDTree
from sklearn.cluster import KMeans

from tasks.arrays import FloatArray, Labels, Points

DENSE_LIMIT = 2000
NEIGHBOURS = 30


@dataclass(frozen=True)
class SpectralResult:
    """Cluster label per sample and the leading eigenvalues of L (descending)."""

    labels: Labels
    eigenvalues: FloatArray
    k: int


def _affinity_dense(x: FloatArray) -> FloatArray:
    sq = (x**2).sum(axis=1)
    d2 = np.maximum(sq[:, None] + sq[None, :] - 2.0 * x @ x.T, 0.0)
    out: FloatArray = np.exp(-0.5 * d2)
    return out


def spectral_labels(
    points: Points,
    t_s: FloatArray,
    *,
    k: int | Literal["auto"],
    delta_p_m: float,
    delta_t_s: float,
    rng: np.random.Generator,
    max_k: int = 12,
) -> SpectralResult:
    """Spectral clustering of (n, 3) points (m) at times t_s (s) into k clusters (Table I of the paper)."""

    n = len(points)
    x = np.column_stack([points / delta_p_m, (t_s - t_s[0]) / delta_t_s])
    n_eig = min(n - 1, max_k + 1 if k == "auto" else int(k))
    if n <= DENSE_LIMIT:
        aff = _affinity_dense(x)
        deg = aff.sum(axis=1)
        inv = 1.0 / np.sqrt(deg)
        lap = aff * inv[:, None] * inv[None, :]
        vals, vecs = eigh(lap, subset_by_index=[n - n_eig, n - 1])
    else:
        dist, nbr = cKDTree(x).query(x, k=min(NEIGHBOURS, n))
        rows = np.repeat(np.arange(n), nbr.shape[1])
        aff_s = csr_matrix((np.exp(-0.5 * dist.ravel() ** 2), (rows, nbr.ravel())), shape=(n, n))
        aff_s = aff_s.maximum(aff_s.T)
        deg = np.asarray(aff_s.sum(axis=1)).ravel()
        inv = 1.0 / np.sqrt(deg)
        lap_s = aff_s.multiply(inv[:, None]).multiply(inv[None, :]).tocsr()

        # a block method: Lanczos (eigsh) misses repeated eigenvalues (several near-disconnected clusters)
        block = rng.normal(size=(n, min(n - 1, n_eig + 4)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "not converged to tol": the eigengap needs no more
            vals, vecs = lobpcg(lap_s, block, largest=True, tol=1e-7, maxiter=400)

    order = np.argsort(vals)[::-1]
    vals = vals[order]
    vecs = vecs[:, order]
    if k == "auto":
        gaps = vals[:-1] - vals[1:]
        kk = int(np.argmax(gaps[:max_k])) + 1
    else:
        kk = int(k)
    emb = vecs[:, :kk]
    emb = emb / np.maximum(np.linalg.norm(emb, axis=1, keepdims=True), 1e-300)
    seed = int(rng.integers(0, 2**31 - 1))
    labels = KMeans(n_clusters=kk, n_init=10, random_state=seed).fit_predict(emb).astype(np.int64)
    return SpectralResult(labels, vals, kk)


def runs_from_labels(labels: Labels, t_s: FloatArray, min_segment_s: float) -> list[tuple[float, float]]:
    """Contiguous runs of equal labels as (start, end) seconds; runs shorter than ``min_segment_s`` join the
    previous run (the first joins the next)."""
    change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    starts = [0, *change.tolist()]
    stops = [*change.tolist(), len(labels)]
    spans: list[list[float]] = []
    end_t = float(t_s[-1]) + 1e-9
    for a, b in zip(starts, stops, strict=True):
        t_a = float(t_s[a])
        t_b = float(t_s[b]) if b < len(t_s) else end_t
        if spans and (t_b - t_a < min_segment_s or spans[-1][1] - spans[-1][0] < min_segment_s):
            spans[-1][1] = t_b
        else:
            spans.append([t_a, t_b])
    return [(s[0], s[1]) for s in spans]
