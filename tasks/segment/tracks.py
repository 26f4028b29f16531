"""Marker tracks prepared for segmentation: finite samples, seconds since recording start, sample weights,
prefix moments and noise levels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tasks.arrays import FloatArray, Points
from tasks.fit.moments import PrefixMoments, prefix_moments
from tasks.fit.noise import noise_sigma

INDEPENDENT_HZ = 10.0
"""Rate (Hz) of independent evidence about a path: a hand-driven mechanism's departures from its ideal line or
circle (play, wobble, the hand's own motion, under 5 Hz of bandwidth) stay correlated for about 0.1 s, so samples
closer than that add no independent evidence. A sample weighs its share of time times this rate, at most 1."""


@dataclass(frozen=True)
class Track:
    """One marker: times (s since recording start), finite (n, 3) points (m, world), sample weights (n,),
    weighted moments, model noise sigma (m, with the floor) and sensor noise sigma (m, from the data)."""

    name: str
    t_s: FloatArray
    points: Points
    moments: PrefixMoments
    sigma_m: float
    sigma_hf_m: float
    weights: FloatArray

    @property
    def mean_weight(self) -> float:
        """Average evidence per sample (1 at or below ``INDEPENDENT_HZ``)."""
        return float(np.mean(self.weights)) if len(self.weights) else 1.0


def sample_weights(t_s: FloatArray) -> FloatArray:
    """(n,) evidence weight of each sample: half the time to its neighbours times ``INDEPENDENT_HZ``, at most 1
    (a sample after an occlusion gap counts once, not for the whole gap)."""
    n = len(t_s)
    if n < 2:
        return np.ones(n)
    dt = np.diff(t_s)
    share = np.empty(n)
    share[0] = dt[0]
    share[-1] = dt[-1]
    share[1:-1] = 0.5 * (dt[:-1] + dt[1:])
    out: FloatArray = np.clip(share * INDEPENDENT_HZ, 1e-6, 1.0)
    return out


def make_track(name: str, t_s: FloatArray, points: Points, sigma_floor_m: float) -> Track:
    """Build a ``Track`` from finite samples sorted by time; sigma = max(high-frequency noise, floor)."""
    hf = noise_sigma(points, t_s)
    weights = sample_weights(t_s)
    return Track(name, t_s, points, prefix_moments(points, weights), max(hf, sigma_floor_m), hf, weights)


def span_indices(track: Track, t_from: float, t_to: float) -> tuple[int, int]:
    """Sample index span [i, j) of ``track`` with t_from <= t < t_to."""
    i = int(np.searchsorted(track.t_s, t_from, side="left"))
    j = int(np.searchsorted(track.t_s, t_to, side="left"))
    return i, j
