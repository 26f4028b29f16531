"""Change-point search: ours (``tasks.segment.changepoint.search``, PELT with every candidate's model cost from
prefix moments in one vectorised call) beside ruptures' ``Pelt`` given the same cost (a ``BaseCost`` whose
``error(start, end)`` is our per-span model cost) on the same grid, minimum segment and penalty.

Development: a door swung open and shut at 120 Hz with 3 markers (seed 0); held out: seed 1, 240 Hz. Each row
prints the wall time and the change points found (both should agree: the same cost and penalty).

    .venv/bin/python bench/changepoint_peer.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
import ruptures as rpt

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tasks.segment.changepoint import ChangepointParams, search, spans_cost
from tasks.segment.tracks import Track, make_track


def _door(seconds: float, hz: float, rng: np.random.Generator) -> list[Track]:
    """Three markers on a door swung 1 rad open and shut every 4 s (m, s)."""
    t = np.arange(0.0, seconds, 1.0 / hz)
    phase = (t % 4.0) / 4.0
    s = np.clip(np.where(phase < 0.5, phase / 0.35, (1.0 - phase) / 0.35), 0.0, 1.0)
    angle = 1.0 * (10 * s**3 - 15 * s**4 + 6 * s**5)
    tracks = []
    for i, (radius, height) in enumerate(((0.8, 0.9), (0.6, 0.7), (0.4, 1.0))):
        pts = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.full_like(t, height)])
        tracks.append(make_track(f"/m{i}", t, pts + rng.normal(0.0, 0.0005, pts.shape), 0.002))
    return tracks


class _OurCost(rpt.base.BaseCost):  # type: ignore[misc]
    """Our segment cost (summed best still / line / circle / undefined model over the markers) on grid cells."""

    model = "pbd"
    min_size = 1

    def __init__(self, tracks: list[Track], grid: np.ndarray, undefined: float) -> None:
        self.tracks = tracks
        self.grid = grid
        self.undefined = undefined

    def fit(self, signal: np.ndarray) -> _OurCost:
        """ruptures reads the number of cells from ``signal``; the cost itself comes from the tracks."""
        self.signal = signal
        return self

    def error(self, start: int, end: int) -> float:
        lo = np.array([self.grid[start]])
        hi = np.array([self.grid[end]])
        return float(spans_cost(self.tracks, lo, hi, self.undefined)[0])


def _ruptures(tracks: list[Track], params: ChangepointParams) -> list[float]:
    t_lo = min(float(tr.t_s[0]) for tr in tracks)
    t_hi = max(float(tr.t_s[-1]) for tr in tracks) + 1e-9
    n_cells = max(1, math.ceil((t_hi - t_lo) / params.grid_s))
    grid = t_lo + params.grid_s * np.arange(n_cells + 1, dtype=np.float64)
    grid[-1] = t_hi
    n_evidence = max(float(tr.weights.sum()) for tr in tracks)
    beta = 3.0 * len(tracks) * math.log(max(n_evidence, 2.0))
    min_cells = max(1, math.ceil(params.min_segment_s / params.grid_s))
    algo = rpt.Pelt(custom_cost=_OurCost(tracks, grid, params.undefined_nats), min_size=min_cells, jump=1)
    bkps = algo.fit(np.zeros((n_cells, 1))).predict(pen=beta)
    return [float(grid[b]) for b in bkps[:-1]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=60.0, help="recording length (default 60 s)")
    args = parser.parse_args()
    params = ChangepointParams()
    print(f"{'part':<12} {'method':<30} {'seconds':>9} {'change points':>14}")
    for part, seed, hz in (("development", 0, 120.0), ("held out", 1, 240.0)):
        tracks = _door(args.seconds, hz, np.random.default_rng(seed))
        t0 = time.perf_counter()
        ours = search(tracks, params).bounds_s[1:-1]
        t_ours = time.perf_counter() - t0
        t0 = time.perf_counter()
        theirs = _ruptures(tracks, params)
        t_theirs = time.perf_counter() - t0
        print(f"{part:<12} {'ours (vectorised PELT)':<30} {t_ours:>9.2f} {len(ours):>14}")
        print(f"{part:<12} {'ruptures Pelt, same cost':<30} {t_theirs:>9.2f} {len(theirs):>14}")


if __name__ == "__main__":
    main()
