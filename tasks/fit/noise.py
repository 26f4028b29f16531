"""Noise level of a marker track, estimated from the data (second differences, robust MAD)."""

from __future__ import annotations

import numpy as np

from tasks.arrays import FloatArray, Points

MAD_TO_SIGMA = 1.4826
"""Scale from the median absolute deviation to the standard deviation of a normal distribution."""


NOISE_LAG_S = 1.0 / 30.0
"""Time (s) between the samples whose second difference measures the noise: recorders and drivers upsample or
re-send slower sensors (a camera at 30 Hz) by interpolation or repetition, which hides the noise between samples
closer than a camera frame."""


MIN_COVARIANCE_ROWS = 50
"""Second differences needed before their spread is resolved into axes: fewer, and a short track's own
accelerations along its motion pass for noise along that axis (the estimate stays isotropic)."""


def _lag(points: Points, t_s: FloatArray | None) -> int:
    """Samples spanning ``NOISE_LAG_S`` (1 without times), at most what the track's length allows."""
    lag = 1
    if t_s is not None and len(t_s) > 1:
        dt = float(np.median(np.diff(t_s)))
        lag = max(1, round(NOISE_LAG_S / dt)) if dt > 0 else 1
    return max(1, min(lag, (len(points) - 3) // 2))


def noise_covariance(points: Points, t_s: FloatArray | None = None) -> FloatArray:
    """(3, 3) covariance (m^2, world axes) of a track's white noise, anisotropic where it is (a camera's depth).

    The second differences over ``NOISE_LAG_S`` (covariance 6 Sigma for white noise) are turned to the principal
    axes of their central 90 % and scaled per axis by the median absolute deviation, which motion and outliers
    do not move; isotropic below ``MIN_COVARIANCE_ROWS``. Zero for fewer than 5 samples. (scikit-learn's
    MinCovDet estimates the same robustly but costs far more per marker: ``bench/noise_estimate.py``.)
    """
    if len(points) < 5:
        return np.zeros((3, 3))
    lag = _lag(points, t_s)
    d2 = points[2 * lag :] - 2.0 * points[lag:-lag] + points[: -2 * lag]
    if len(d2) < MIN_COVARIANCE_ROWS:
        return np.eye(3) * noise_sigma(points, t_s) ** 2
    d2 = d2 - np.median(d2, axis=0)
    norms = np.linalg.norm(d2, axis=1)
    core = d2[norms <= np.percentile(norms, 90.0)]
    _, axes = np.linalg.eigh(core.T @ core if len(core) >= 3 else d2.T @ d2)
    proj = d2 @ axes
    mad = np.median(np.abs(proj - np.median(proj, axis=0)), axis=0)
    var = (MAD_TO_SIGMA * mad) ** 2 / 6.0
    out: FloatArray = (axes * var) @ axes.T
    return out


def noise_sigma(points: Points, t_s: FloatArray | None = None) -> float:
    """Per-axis white-noise standard deviation (metres) of an (n, 3) track from its second differences.

    For white noise of standard deviation s the second difference p[i+L] - 2 p[i] + p[i-L] has standard
    deviation s * sqrt(6); smooth motion adds only acceleration * (L dt)^2, which the median ignores. The lag L
    spans ``NOISE_LAG_S`` when the times ``t_s`` are given (one sample otherwise). Returns 0.0 for fewer than 5
    samples.
    """
    if len(points) < 5:
        return 0.0
    lag = _lag(points, t_s)
    d2 = points[2 * lag :] - 2.0 * points[lag:-lag] + points[: -2 * lag]
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return float(np.sqrt(np.mean((MAD_TO_SIGMA * mad) ** 2)) / np.sqrt(6.0))
