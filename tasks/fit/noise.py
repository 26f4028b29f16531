"""Noise level of a marker track, estimated from the data (second differences, robust MAD)."""

from __future__ import annotations

import numpy as np

from tasks.arrays import Points

MAD_TO_SIGMA = 1.4826
"""Scale from the median absolute deviation to the standard deviation of a normal distribution."""


def noise_sigma(points: Points) -> float:
    """Per-axis white-noise standard deviation (metres) of an (n, 3) track from its second differences.

    For white noise of standard deviation s the second difference p[i+1] - 2 p[i] + p[i-1] has standard
    deviation s * sqrt(6); smooth motion adds only acceleration * dt^2, which the median ignores.
    Returns 0.0 for fewer than 5 samples.
    """
    if len(points) < 5:
        return 0.0
    d2 = points[2:] - 2.0 * points[1:-1] + points[:-2]
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return float(np.sqrt(np.mean((MAD_TO_SIGMA * mad) ** 2)) / np.sqrt(6.0))
