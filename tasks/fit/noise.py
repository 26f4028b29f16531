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


def noise_sigma(points: Points, t_s: FloatArray | None = None) -> float:
    """Per-axis white-noise standard deviation (metres) of an (n, 3) track from its second differences.

    For white noise of standard deviation s the second difference p[i+L] - 2 p[i] + p[i-L] has standard
    deviation s * sqrt(6); smooth motion adds only acceleration * (L dt)^2, which the median ignores. The lag L
    spans ``NOISE_LAG_S`` when the times ``t_s`` are given (one sample otherwise). Returns 0.0 for fewer than 5
    samples.
    """
    if len(points) < 5:
        return 0.0
    lag = 1
    if t_s is not None and len(t_s) > 1:
        dt = float(np.median(np.diff(t_s)))
        lag = max(1, round(NOISE_LAG_S / dt)) if dt > 0 else 1
        lag = min(lag, (len(points) - 3) // 2)
    d2 = points[2 * lag :] - 2.0 * points[lag:-lag] + points[: -2 * lag]
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return float(np.sqrt(np.mean((MAD_TO_SIGMA * mad) ** 2)) / np.sqrt(6.0))
