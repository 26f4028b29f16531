"""Marker tracks prepared for segmentation: finite samples, seconds since recording start, prefix moments."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tasks.arrays import FloatArray, Points
from tasks.fit.moments import PrefixMoments, prefix_moments
from tasks.fit.noise import noise_sigma


@dataclass(frozen=True)
class Track:
    """One marker: times (s since recording start), finite (n, 3) points (m, world), moments, noise sigma (m)."""

    name: str
    t_s: FloatArray
    points: Points
    moments: PrefixMoments
    sigma_m: float
    sigma_hf_m: float


def make_track(name: str, t_s: FloatArray, points: Points, sigma_floor_m: float) -> Track:
    """Build a ``Track`` from finite samples sorted by time; sigma = max(high-frequency noise, floor)."""
    hf = noise_sigma(points)
    return Track(name, t_s, points, prefix_moments(points), max(hf, sigma_floor_m), hf)


def span_indices(track: Track, t_from: float, t_to: float) -> tuple[int, int]:
    """Sample index span [i, j) of ``track`` with t_from <= t < t_to."""
    i = int(np.searchsorted(track.t_s, t_from, side="left"))
    j = int(np.searchsorted(track.t_s, t_to, side="left"))
    return i, j
