"""Prefix sums of monomials up to degree 4, so any time span's still / line / circle residual costs O(1).

For a span of samples the centred moments C2 (scatter), C3 and C4 follow from the raw moments; the line
residual is the scatter matrix's two smallest eigenvalues, the circle residual is the smallest eigenvalue
(distance from the plane) plus the Kåsa algebraic circle fit in that plane, turned into a geometric residual
by dividing by 4 r^2. Points are re-centred on the track's centroid first so the degree-4 sums keep precision.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from tasks.arrays import FloatArray, Points

IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True)
class SpanResiduals:
    """Residual sums of squares (m^2) of the best still, line and circle model for a batch of spans."""

    n: FloatArray
    """(b,) effective sample counts (sum of the samples' weights)."""
    count: FloatArray
    """(b,) sample counts."""
    still: FloatArray
    """(b,) sum of squared distances to the centroid, m^2."""
    line: FloatArray
    """(b,) sum of squared distances to the principal line, m^2."""
    circle: FloatArray
    """(b,) approximate sum of squared distances to the best circle, m^2 (inf when degenerate)."""
    radius: FloatArray
    """(b,) algebraic circle radius, m (inf when degenerate)."""
    scatter: FloatArray
    """(b, 3, 3) scatter matrix about the centroid, m^2."""


@dataclass(frozen=True)
class PrefixMoments:
    """Cumulative raw moments of one marker's samples (metres, relative to ``origin``)."""

    origin: FloatArray
    cum0: FloatArray
    """(n+1,) cumulative sample weights"""
    cum1: FloatArray
    """(n+1, 3)"""
    cum2: FloatArray
    """(n+1, 3, 3)"""
    cum3: FloatArray
    """(n+1, 3, 3, 3)"""
    cum4: FloatArray
    """(n+1, 3, 3, 3, 3)"""

    @property
    def size(self) -> int:
        """Number of samples."""
        return int(self.cum1.shape[0] - 1)


def prefix_moments(points: Points, weights: FloatArray | None = None) -> PrefixMoments:
    """Weighted prefix sums of 1, p, p⊗p, p⊗p⊗p, p⊗p⊗p⊗p for (n, 3) finite points (metres) with (n,) sample
    weights (default 1: each sample one independent observation)."""
    origin = points.mean(axis=0) if len(points) else np.zeros(3)
    q = points - origin
    n = len(q)
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
    zero = np.zeros
    m2 = np.einsum("n,ni,nj->nij", w, q, q)
    m3 = np.einsum("nij,nk->nijk", m2, q)
    cum0 = np.concatenate([zero(1), np.cumsum(w)])
    cum1 = np.concatenate([zero((1, 3)), np.cumsum(q * w[:, None], axis=0)])
    cum2 = np.concatenate([zero((1, 3, 3)), np.cumsum(m2, axis=0)])
    cum3 = np.concatenate([zero((1, 3, 3, 3)), np.cumsum(m3, axis=0)])
    del m2
    cum4 = np.empty((n + 1, 3, 3, 3, 3))
    cum4[0] = 0.0
    chunk = 4096
    running = np.zeros((3, 3, 3, 3))
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        block = np.einsum("nijk,nl->nijkl", m3[start:stop], q[start:stop])
        np.cumsum(block, axis=0, out=cum4[start + 1 : stop + 1])
        cum4[start + 1 : stop + 1] += running
        running = cum4[stop].copy()
    return PrefixMoments(origin, cum0, cum1, cum2, cum3, cum4)


def concat_moments(parts: list[PrefixMoments]) -> tuple[PrefixMoments, IntArray]:
    """Several markers' prefix sums stacked into one, with each marker's row offset: spans of every marker can
    then be evaluated in one vectorised call (a span must stay inside its own marker's block)."""
    offsets = np.cumsum([0] + [p.cum1.shape[0] for p in parts[:-1]]).astype(np.int64)
    stacked = PrefixMoments(
        np.zeros(3),
        np.concatenate([p.cum0 for p in parts]),
        np.concatenate([p.cum1 for p in parts]),
        np.concatenate([p.cum2 for p in parts]),
        np.concatenate([p.cum3 for p in parts]),
        np.concatenate([p.cum4 for p in parts]),
    )
    return stacked, offsets


def span_residuals(pm: PrefixMoments, start: IntArray, stop: IntArray) -> SpanResiduals:
    """Still / line / circle residual sums of squares of sample spans ``[start, stop)`` (vectorised)."""
    start = np.asarray(start, dtype=np.int64)
    stop = np.asarray(stop, dtype=np.int64)
    count = (stop - start).astype(np.float64)
    n = pm.cum0[stop] - pm.cum0[start]
    safe = np.where(n > 0, n, 1.0)
    m1 = (pm.cum1[stop] - pm.cum1[start]) / safe[:, None]
    m2 = (pm.cum2[stop] - pm.cum2[start]) / safe[:, None, None]
    m3 = (pm.cum3[stop] - pm.cum3[start]) / safe[:, None, None, None]
    m4 = (pm.cum4[stop] - pm.cum4[start]) / safe[:, None, None, None, None]
    c = m1
    cc = np.einsum("bi,bj->bij", c, c)
    c2 = m2 - cc
    c2 = 0.5 * (c2 + np.swapaxes(c2, 1, 2))
    evals, evecs = np.linalg.eigh(c2)
    evals = np.maximum(evals, 0.0)
    still = n * evals.sum(axis=1)
    line = n * (evals[:, 0] + evals[:, 1])

    normal = evecs[:, :, 0]
    proj = np.eye(3)[None] - np.einsum("bi,bj->bij", normal, normal)
    # centred third moment contracted with the in-plane projector P: v_i = E[q_i (q^T P q)]
    m3p = np.einsum("bijk,bjk->bi", m3, proj)
    m2c = np.einsum("bij,bj->bi", m2, c)  # M2 c
    c_p_c = np.einsum("bi,bij,bj->b", c, proj, c)
    tr_pm2 = np.einsum("bij,bij->b", proj, m2)
    pc = np.einsum("bij,bj->bi", proj, c)
    m2pc = np.einsum("bij,bj->bi", m2, pc)
    v = m3p - c * tr_pm2[:, None] - 2.0 * m2pc + 2.0 * c * c_p_c[:, None]
    # E[w] and E[w^2] with w = q^T P q
    mean_w = np.einsum("bij,bij->b", proj, c2)
    e_w2 = _centred_quartic(m1, m2, m3, m4, proj)
    var_w = np.maximum(e_w2 - mean_w**2, 0.0)
    basis = evecs[:, :, 1:]  # in-plane axes (eigenvalues evals[:, 1], evals[:, 2])
    e_uw = np.einsum("bia,bi->ba", basis, v)
    lam = np.maximum(evals[:, 1:], 1e-300)
    a = 0.5 * e_uw / lam
    alg = np.maximum(var_w - 2.0 * np.einsum("ba,ba->b", a, e_uw), 0.0)
    r2 = mean_w + np.einsum("ba,ba->b", a, a)
    with np.errstate(divide="ignore", invalid="ignore"):
        radius = np.where(r2 > 0, np.sqrt(np.maximum(r2, 0.0)), np.inf)
        circle = n * (evals[:, 0] + np.where(r2 > 0, alg / (4.0 * r2), np.inf))
    del m2c
    circle = np.where(np.isfinite(circle), circle, np.inf)
    return SpanResiduals(
        n=n, count=count, still=still, line=line, circle=circle, radius=radius, scatter=n[:, None, None] * c2
    )


def _centred_quartic(m1: FloatArray, m2: FloatArray, m3: FloatArray, m4: FloatArray, proj: FloatArray) -> FloatArray:
    """E[(q^T P q)^2] with q = p - E[p], from raw moments up to degree 4 (batched).

    With A = p^T P p, B = c^T P p and K = c^T P c (c = E[p]): q^T P q = A - 2B + K and E[B] = K, so
    E[(A - 2B + K)^2] = E[A^2] - 4 E[AB] + 2 K E[A] + 4 E[B^2] - 3 K^2.
    """
    c = m1
    pc = np.einsum("bij,bj->bi", proj, c)
    k = np.einsum("bi,bi->b", c, pc)
    e_a2 = np.einsum("bijkl,bij,bkl->b", m4, proj, proj)
    e_ab = np.einsum("bijk,bij,bk->b", m3, proj, pc)
    e_a = np.einsum("bij,bij->b", m2, proj)
    e_b2 = np.einsum("bi,bij,bj->b", pc, m2, pc)
    out: FloatArray = e_a2 - 4.0 * e_ab + 2.0 * k * e_a + 4.0 * e_b2 - 3.0 * k * k
    return out
