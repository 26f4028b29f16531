"""Model-based change-point search (the default segmenter).

The cost of a time span is, summed over markers, the cost of the best still / line / circle / undefined
model of that marker's samples in the span (``tasks.fit.select.model_costs``, O(1) per span from prefix
moments), plus a penalty ``beta`` per segment. PELT (Killick et al. 2012) searches change points on a time
grid of ``grid_s`` cells with a minimum segment length, scoring spans of at most ``max_span_s``; the cheapest
subset of the change points found, with spans of any length, is then kept; each change point is finally refined
at the full sample rate between its neighbours. Every marker shares the change points: a switch in one marker is a
candidate for all. Segments are contiguous in time and their number is found by the search.

Why not ruptures' ``Pelt``: it asks its cost for one span at a time, while this search scores every candidate of
a step in one vectorised call; with the same cost, grid and penalty it finds the same change points about 7
times slower (``bench/changepoint_peer.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tasks.arrays import FloatArray
from tasks.fit.moments import concat_moments, span_residuals
from tasks.fit.select import model_costs
from tasks.segment.tracks import Track, anisotropy

IntArray = np.ndarray


MIN_MODEL_SAMPLES = 4
"""Samples a line or circle needs before its residual says anything (a circle passes through any three points)."""
FEW_SAMPLE_MODELS = [0, 3]
"""Models (still, undefined) that score a span with fewer samples: a short span is never free."""


@dataclass(frozen=True)
class ChangepointParams:
    """Search settings: grid cell (s), minimum segment (s), penalty per segment (nats, None = 3 log N per
    marker, N the effective sample count), per-sample cost of the undefined model (nats), most grid cells, and
    the longest span (s) PELT scores directly (longer segments come from the subset pass)."""

    grid_s: float = 0.05
    min_segment_s: float = 0.3
    penalty: float | None = None
    undefined_nats: float = 9.0
    max_cells: int = 3000
    max_span_s: float = 10.0
    """PELT's pruning keeps every start a single model explains (one circle fits any stretch of a door swung to
    and fro), so each step would score all earlier cells; bounding the span keeps the search linear in time, and
    the subset pass after it restores longer segments."""


@dataclass(frozen=True)
class Segmentation:
    """Segment boundaries in seconds since recording start: segment i is [bounds[i], bounds[i+1])."""

    bounds_s: tuple[float, ...]
    cost: float

    @property
    def spans(self) -> list[tuple[float, float]]:
        """(start, end) seconds of each segment."""
        return list(zip(self.bounds_s[:-1], self.bounds_s[1:], strict=True))


def marker_costs(track: Track, start: IntArray, stop: IntArray, undefined: float) -> tuple[IntArray, FloatArray]:
    """Sample counts (b,) of ``track``'s sample spans [start, stop) and the cost (b, 4) in nats of each model
    (``tasks.fit.select.KINDS``) over them, the still model under the marker's anisotropic sensor noise."""
    res = span_residuals(track.moments, start, stop)
    precision, excess = anisotropy(track)
    b = len(res.n)
    costs = model_costs(
        res.n,
        res.still,
        res.line,
        res.circle,
        sigma_still=track.sigma_hf_m,
        sigma_model=track.sigma_m,
        undefined=undefined,
        still_noise=(res.scatter, np.broadcast_to(precision, (b, 3, 3)), np.full(b, excess)),
    )
    return res.count, costs


def _marker_cost(track: Track, start: IntArray, stop: IntArray, undefined: float) -> FloatArray:
    """(b,) cost in nats of the best model of ``track`` over sample spans [start, stop); 0 for < 4 samples."""
    count, costs = marker_costs(track, start, stop, undefined)
    best: FloatArray = np.where(count >= MIN_MODEL_SAMPLES, costs.min(axis=1), costs[:, FEW_SAMPLE_MODELS].min(axis=1))
    return np.where(count > 0, best, 0.0)


def spans_cost(tracks: list[Track], t_from: FloatArray, t_to: FloatArray, undefined: float) -> FloatArray:
    """(b,) summed best-model cost (nats) of the time spans [t_from, t_to) over every marker."""
    total = np.zeros(len(t_from))
    for tr in tracks:
        a = np.searchsorted(tr.t_s, t_from, side="left")
        b = np.searchsorted(tr.t_s, t_to, side="left")
        total += _marker_cost(tr, a, b, undefined)
    return total


def search(tracks: list[Track], params: ChangepointParams) -> Segmentation:
    """PELT over the grid, then full-rate refinement of every change point (tracks must be non-empty)."""
    t_lo = min(float(tr.t_s[0]) for tr in tracks)
    t_hi = max(float(tr.t_s[-1]) for tr in tracks) + 1e-9
    duration = t_hi - t_lo
    cell = max(params.grid_s, duration / params.max_cells)
    n_cells = max(1, math.ceil(duration / cell))
    grid = t_lo + cell * np.arange(n_cells + 1, dtype=np.float64)
    grid[-1] = t_hi
    min_cells = max(1, math.ceil(params.min_segment_s / cell))
    max_span_cells = max(min_cells, math.ceil(params.max_span_s / cell))
    n_evidence = max(float(tr.weights.sum()) for tr in tracks)
    beta = params.penalty if params.penalty is not None else 3.0 * len(tracks) * math.log(max(n_evidence, 2.0))
    margin = 4.0 * len(tracks) * math.log(max(n_evidence, 2.0))
    stacked, offsets = concat_moments([tr.moments for tr in tracks])
    # grid boundary -> row in the stacked prefix sums, per marker: (markers, cells + 1)
    rows = np.stack([np.searchsorted(tr.t_s, grid, side="left") + off for tr, off in zip(tracks, offsets, strict=True)])
    sig_still = np.array([tr.sigma_hf_m for tr in tracks])
    sig_model = np.array([tr.sigma_m for tr in tracks])
    still_noise = [anisotropy(tr) for tr in tracks]
    precisions = np.stack([p for p, _ in still_noise])
    excesses = np.array([e for _, e in still_noise])
    n_markers = len(tracks)

    def cost(cands: IntArray, end: int) -> FloatArray:
        start = rows[:, cands].ravel()
        stop = np.repeat(rows[:, end], len(cands))
        res = span_residuals(stacked, start, stop)
        costs = model_costs(
            res.n,
            res.still,
            res.line,
            res.circle,
            sigma_still=np.repeat(sig_still, len(cands)),
            sigma_model=np.repeat(sig_model, len(cands)),
            undefined=params.undefined_nats,
            still_noise=(res.scatter, np.repeat(precisions, len(cands), axis=0), np.repeat(excesses, len(cands))),
        )
        best_model = np.where(
            res.count >= MIN_MODEL_SAMPLES, costs.min(axis=1), costs[:, FEW_SAMPLE_MODELS].min(axis=1)
        )
        best_model = np.where(res.count > 0, best_model, 0.0)
        out: FloatArray = best_model.reshape(n_markers, len(cands)).sum(axis=0)
        return out

    best = np.full(n_cells + 1, np.inf)
    best[0] = -beta
    prev = np.zeros(n_cells + 1, dtype=np.int64)
    cands = np.zeros(0, dtype=np.int64)
    for end in range(min_cells, n_cells + 1):
        new = end - min_cells
        if np.isfinite(best[new]):
            cands = np.append(cands, new)
        cands = cands[cands >= end - max_span_cells]
        if len(cands) == 0:
            continue
        c = cost(cands, end)
        vals = best[cands] + c + beta
        k = int(np.argmin(vals))
        best[end] = vals[k]
        prev[end] = cands[k]
        cands = cands[best[cands] + c <= best[end] + margin]
    if not np.isfinite(best[n_cells]):
        return Segmentation((float(grid[0]), float(grid[-1])), float("nan"))
    cuts = [n_cells]
    while cuts[-1] > 0:
        cuts.append(int(prev[cuts[-1]]))
    cuts.reverse()
    cuts = _best_subset(cuts, cost, beta)
    bounds = [float(grid[c]) for c in cuts]
    bounds = _refine(tracks, bounds, cell, params)
    return Segmentation(tuple(bounds), float(best[n_cells]))


def _best_subset(cuts: list[int], cost: Callable[[IntArray, int], FloatArray], beta: float) -> list[int]:
    """The cheapest segmentation whose change points are among ``cuts`` (grid cells, first 0, last the end),
    spans of any length; ``cost(starts, end)`` scores the grid spans [start, end)."""
    points = np.asarray(cuts, dtype=np.int64)
    best = np.full(len(points), np.inf)
    best[0] = -beta
    prev = np.zeros(len(points), dtype=np.int64)
    for j in range(1, len(points)):
        vals = best[:j] + cost(points[:j], int(points[j])) + beta
        prev[j] = int(np.argmin(vals))
        best[j] = vals[prev[j]]
    out = [len(points) - 1]
    while out[-1] > 0:
        out.append(int(prev[out[-1]]))
    return [int(points[i]) for i in reversed(out)]


def _refine(tracks: list[Track], bounds: list[float], cell: float, params: ChangepointParams) -> list[float]:
    """Move each inner boundary to the sample time within one grid cell that minimises its two segments' cost."""
    out = list(bounds)
    stamps = np.unique(np.concatenate([tr.t_s for tr in tracks]))
    for i in range(1, len(out) - 1):
        lo = max(out[i] - cell, out[i - 1] + params.min_segment_s * 0.5)
        hi = min(out[i] + cell, out[i + 1] - params.min_segment_s * 0.5)
        cand = stamps[(stamps > lo) & (stamps < hi)]
        if len(cand) == 0:
            continue
        if len(cand) > 400:
            cand = cand[np.linspace(0, len(cand) - 1, 400).round().astype(np.int64)]
        left = spans_cost(tracks, np.full(len(cand), out[i - 1]), cand, params.undefined_nats)
        right = spans_cost(tracks, cand, np.full(len(cand), out[i + 1]), params.undefined_nats)
        out[i] = float(cand[int(np.argmin(left + right))])
    return out
