"""Marker tracks prepared for segmentation: finite samples, seconds since recording start, sample weights,
prefix moments and noise levels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tasks.arrays import FloatArray, Points
from tasks.fit.moments import PrefixMoments, prefix_moments
from tasks.fit.noise import noise_model
from tasks.fit.select import SIGMA_MIN_M

ANISOTROPY_FLOOR = 0.01
"""Smallest noise variance along any axis, as a fraction of the largest: a camera's depth noise is 3 to 30 times
its lateral noise (1/100 in variance at most), and no real sensor is noise-free along an axis."""

INDEPENDENT_HZ = 10.0
"""Rate (Hz) of independent evidence about a path: a hand-driven mechanism's departures from its ideal line or
circle (play, wobble, the hand's own motion, under 5 Hz of bandwidth) stay correlated for about 0.1 s, so samples
closer than that add no independent evidence. A sample weighs its share of time times this rate, at most 1."""


@dataclass(frozen=True)
class Track:
    """One marker: times (s since recording start), finite (n, 3) points (m, world), sample weights (n,),
    weighted moments, model noise sigma (m, with the floor), sensor noise sigma (m, from the data) and its
    covariance."""

    name: str
    t_s: FloatArray
    points: Points
    moments: PrefixMoments
    sigma_m: float
    sigma_hf_m: float
    weights: FloatArray
    noise_cov: FloatArray
    """(3, 3) sensor noise covariance (m^2, world axes), anisotropic where it is."""
    noise_tau_s: float = 0.0
    """The sensor noise's correlation time (s; 0 for white noise): samples closer than that are not independent
    draws of it."""

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
    hf, cov, tau = noise_model(points, t_s)
    weights = sample_weights(t_s)
    return Track(name, t_s, points, prefix_moments(points, weights), max(hf, sigma_floor_m), hf, weights, cov, tau)


def anisotropy(track: Track) -> tuple[FloatArray, float]:
    """The still model's noise for ``tasks.fit.select.model_costs``: precision (3, 3, 1/m^2) of the marker's
    noise covariance with the eigenvalues floored at ``ANISOTROPY_FLOOR`` of the largest, and the per-sample
    log-normaliser excess (nats) of an isotropic noise of the same total power over it."""
    evals, evecs = np.linalg.eigh(track.noise_cov)
    top = max(float(evals[-1]), SIGMA_MIN_M**2)
    evals = np.maximum(evals, ANISOTROPY_FLOOR * top)
    iso = float(evals.mean())
    precision: FloatArray = (evecs / evals) @ evecs.T
    return precision, float(1.5 * np.log(iso) - 0.5 * np.log(evals).sum())


def span_indices(track: Track, t_from: float, t_to: float) -> tuple[int, int]:
    """Sample index span [i, j) of ``track`` with t_from <= t < t_to."""
    i = int(np.searchsorted(track.t_s, t_from, side="left"))
    j = int(np.searchsorted(track.t_s, t_to, side="left"))
    return i, j
