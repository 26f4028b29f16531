"""Noise level of a marker track, estimated from the data (fourth differences at two lags, robust MAD).

Fourth differences cancel any cubic motion, so a hand's acceleration and jerk do not pass for noise. Tracking noise
is often correlated over tens of milliseconds (a camera tracker's filter), which hides part of its variance from
differences of nearby samples; the ratio of the differences' variance at the lag L and 2 L gives that correlation
(an exponential one, AR(1)), and the variance is corrected for it.
"""

from __future__ import annotations

import numpy as np

from tasks.arrays import FloatArray, Points

MAD_TO_SIGMA = 1.4826
"""Scale from the median absolute deviation to the standard deviation of a normal distribution."""


NOISE_LAG_S = 1.0 / 30.0
"""Time (s) between the samples whose differences measure the noise: recorders and drivers upsample or re-send
slower sensors (a camera at 30 Hz) by interpolation or repetition, which hides the noise between samples closer
than a camera frame."""

MAX_CORRELATION_S = 0.1
"""Longest noise correlation time (s) corrected for: the segmentation counts samples as independent at 10 Hz
(``tasks.segment.tracks.INDEPENDENT_HZ``); slower wander is motion, not noise."""

MIN_COVARIANCE_ROWS = 50
"""Differences needed before their spread is resolved into axes: fewer, and a short track's own accelerations
along its motion pass for noise along that axis (the estimate stays isotropic)."""

DIFFERENCE = np.array([1.0, -4.0, 6.0, -4.0, 1.0])
"""Fourth-difference weights (they cancel cubic motion)."""


def _gain(r: FloatArray | float) -> FloatArray:
    """Variance of a fourth difference over noise of unit variance whose correlation at the lag is ``r`` and
    ``r**k`` at k lags (AR(1)); 70 for white noise."""
    return np.asarray(70.0 - 112.0 * r + 56.0 * r**2 - 16.0 * r**3 + 2.0 * r**4)


def _lag(n: int, t_s: FloatArray | None) -> tuple[int, float]:
    """Samples spanning ``NOISE_LAG_S`` (1 without times), at most what a track of ``n`` samples allows for
    differences at twice the lag, and the lag in seconds (``NOISE_LAG_S`` without times)."""
    lag, dt = 1, NOISE_LAG_S
    if t_s is not None and len(t_s) > 1:
        step = float(np.median(np.diff(t_s)))
        if step > 0:
            lag, dt = max(1, round(NOISE_LAG_S / step)), step
    lag = max(1, min(lag, (n - 1) // (2 * len(DIFFERENCE))))
    return lag, lag * dt


def _differences(points: Points, lag: int, t_s: FloatArray | None = None) -> FloatArray:
    """(n - 4 lag, 3) fourth differences (m). With sample times, each is the divided difference of its five
    samples scaled to the uniform weights' noise gain: it cancels cubic motion at jittered or uneven times too,
    where fixed weights turn the motion between unevenly spaced samples into noise. Windows with repeated times
    are left out."""
    n = len(points) - lag * (len(DIFFERENCE) - 1)
    if n <= 0:
        return np.zeros((0, points.shape[1]))
    if t_s is None:
        out = np.zeros((n, points.shape[1]))
        for k, w in enumerate(DIFFERENCE):
            out += w * points[k * lag : k * lag + n]
        return out
    m = len(DIFFERENCE)
    tw = np.stack([t_s[k * lag : k * lag + n] for k in range(m)], axis=1)  # (n, 5)
    gaps = tw[:, :, None] - tw[:, None, :]
    gaps[:, np.arange(m), np.arange(m)] = 1.0
    ok = np.all(gaps != 0.0, axis=(1, 2))
    w = 1.0 / np.prod(gaps[ok], axis=2)  # divided-difference weights
    w *= np.sqrt(float((DIFFERENCE**2).sum()) / (w**2).sum(axis=1))[:, None]
    pw = np.stack([points[k * lag : k * lag + n][ok] for k in range(m)], axis=1)  # (n_ok, 5, 3)
    result: FloatArray = np.einsum("nk,nkd->nd", w, pw)
    return result


def robust_variance(d: FloatArray) -> FloatArray:
    """Per-column variance of ``d`` (its units squared) from the median absolute deviation."""
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    out: FloatArray = (MAD_TO_SIGMA * mad) ** 2
    return out


def _correlation(points: Points, lag: int, lag_s: float, near: FloatArray, t_s: FloatArray | None) -> float:
    """The noise's correlation between samples ``lag`` apart (AR(1), fitted to the variance ratio of the fourth
    differences at lags 2 L and L; ``near`` are the differences at L): 0 for white noise."""
    if len(points) < 2 * lag * (len(DIFFERENCE) - 1) + 3:
        return 0.0
    var_near = float(robust_variance(near).sum())
    var_far = float(robust_variance(_differences(points, 2 * lag, t_s)).sum())
    if var_near <= 0.0 or var_far <= var_near:
        return 0.0
    rs = np.linspace(0.0, np.exp(-lag_s / MAX_CORRELATION_S), 256)
    ratio = _gain(rs**2) / _gain(rs)
    return float(rs[min(int(np.searchsorted(ratio, var_far / var_near)), len(rs) - 1)])


def noise_estimate(points: Points, t_s: FloatArray | None = None) -> tuple[float, FloatArray]:
    """Per-axis noise standard deviation (m) and (3, 3) noise covariance (m^2, world axes) of an (n, 3) track.

    For white noise of standard deviation s the fourth difference over a lag L has standard deviation
    s * sqrt(70); smooth motion adds only its fourth derivative * (L dt)^4, which the median ignores. The lag L
    spans ``NOISE_LAG_S`` when the times ``t_s`` are given (one sample otherwise). The differences are turned to
    the principal axes of their central 90 % and scaled per axis by the median absolute deviation, which motion
    and outliers do not move, over the correlation gain; the covariance stays isotropic below
    ``MIN_COVARIANCE_ROWS`` (anisotropic where the sensor is: a camera's depth). Zero for fewer than 5 samples.
    (scikit-learn's MinCovDet estimates the same robustly but costs far more per marker:
    ``bench/noise_estimate.py``.)
    """
    sigma, cov, _ = noise_model(points, t_s)
    return sigma, cov


def noise_model(points: Points, t_s: FloatArray | None = None) -> tuple[float, FloatArray, float]:
    """``noise_estimate``'s sigma (m) and covariance (m^2) of an (n, d) track, and the noise's correlation time (s;
    0 for white noise or without times): samples closer than that are not independent draws of it."""
    d_axes = points.shape[1]
    if len(points) < len(DIFFERENCE):
        return 0.0, np.zeros((d_axes, d_axes)), 0.0
    lag, lag_s = _lag(len(points), t_s)
    d = _differences(points, lag, t_s)
    r = _correlation(points, lag, lag_s, d, t_s)
    tau = -lag_s / float(np.log(r)) if r > 0.0 and t_s is not None else 0.0
    gain = float(_gain(r))
    sigma = float(np.sqrt(float(np.mean(robust_variance(d))) / gain)) if len(d) else 0.0
    if len(d) < MIN_COVARIANCE_ROWS:
        return sigma, np.eye(d_axes) * sigma**2, tau
    d = d - np.median(d, axis=0)
    norms = np.linalg.norm(d, axis=1)
    core = d[norms <= np.percentile(norms, 90.0)]
    _, axes = np.linalg.eigh(core.T @ core if len(core) >= d_axes else d.T @ d)
    var = robust_variance(d @ axes) / gain
    cov: FloatArray = (axes * var) @ axes.T
    return sigma, cov, tau


def series_noise(values: FloatArray, t_s: FloatArray) -> tuple[float, float]:
    """Noise standard deviation (its units) of a 1-D series at times ``t_s`` (s) and the noise's correlation
    time (s; 0 for white noise), as ``noise_model`` estimates them; (0, 0) under 5 samples."""
    sigma, _, tau = noise_model(np.asarray(values, dtype=np.float64)[:, None], t_s)
    return sigma, tau


def independent_draws(n: float, span_s: float, tau_s: float) -> float:
    """How many independent draws of its noise ``n`` samples spread over ``span_s`` (s, first to last) hold, at
    least one: at most one per ``NOISE_LAG_S`` (a recorder upsamples a slower sensor by interpolation or
    repetition), and under noise correlated over ``tau_s`` (s; AR(1) at the mean spacing dt, rho = exp(-dt /
    tau)) at most n (1 - rho) / (1 + rho), the count whose mean has the same variance."""
    if n <= 1.0:
        return 1.0
    frames = span_s / NOISE_LAG_S + 1.0
    dt = span_s / (n - 1.0)
    rho = float(np.exp(-dt / tau_s)) if tau_s > 0.0 and dt > 0.0 else 0.0
    return max(min(n, frames, n * (1.0 - rho) / (1.0 + rho)), 1.0)


def noise_covariance(points: Points, t_s: FloatArray | None = None) -> FloatArray:
    """(3, 3) noise covariance (m^2, world axes) of a track (``noise_estimate``)."""
    return noise_estimate(points, t_s)[1]


def noise_sigma(points: Points, t_s: FloatArray | None = None) -> float:
    """Per-axis noise standard deviation (m) of an (n, 3) track (``noise_estimate``); 0.0 under 5 samples."""
    return noise_estimate(points, t_s)[0]
