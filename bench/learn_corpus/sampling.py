"""Sensor models of the stress corpus: sample stamps, position noise (isotropic or depth-heavy, white or
coloured), outliers, occlusion gaps, sparse and repeated samples, and marker names that do not give away roles."""

from __future__ import annotations

import numpy as np

from bench.learn_corpus.rotations import Array, matrix_from_rotvec, unit


def stamps(rng: np.random.Generator, hz: float, duration_s: float, mode: str) -> Array:
    """Sample times (s) over [0, duration]: "uniform", "jitter" (Gaussian timing jitter up to 0.3 periods) or
    "uneven" (gamma-distributed intervals with the same mean). The first sample is at 0."""
    period = 1.0 / hz
    if mode == "uneven":
        shape = rng.uniform(1.5, 4.0)
        steps = rng.gamma(shape, period / shape, size=int(duration_s * hz * 1.5) + 10)
        t = np.concatenate([[0.0], np.cumsum(np.maximum(steps, 0.05 * period))])
        return t[t <= duration_s]
    t = np.arange(0.0, duration_s + 1e-9, period)
    if mode == "jitter":
        t[1:] += rng.normal(0.0, rng.uniform(0.05, 0.3) * period, size=len(t) - 1)
        t = np.sort(np.clip(t, 0.0, duration_s))
        t = t[np.concatenate([[True], np.diff(t) > 1e-6])]
    return t


def noise(
    rng: np.random.Generator, t: Array, sigma_lat: float, sigma_depth: float, *, depth_dir: Array, corr_s: float
) -> Array:
    """Position noise (n, 3) m: per-axis sigma ``sigma_depth`` along ``depth_dir`` and ``sigma_lat`` across it;
    an AR(1) process with correlation time ``corr_s`` s when it is above zero (camera tracking), else white."""
    white = rng.normal(size=(len(t), 3))
    if corr_s > 0 and len(t) > 1:
        rho = np.exp(-np.diff(t) / corr_s)
        for k in range(1, len(t)):
            white[k] = rho[k - 1] * white[k - 1] + np.sqrt(1.0 - rho[k - 1] ** 2) * white[k]
    d = unit(depth_dir)
    e1 = unit(np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0]))
    e2 = np.cross(d, e1)
    frame = np.stack([e1, e2, d], axis=1)
    out: Array = (white * np.array([sigma_lat, sigma_lat, sigma_depth])) @ frame.T
    return out


def add_outliers(rng: np.random.Generator, xyz: Array, noise_m: float) -> Array:
    """``xyz`` with 0.3-1 % of its samples displaced by at least 10 sigma and 2 cm in random directions."""
    out = xyz.copy()
    n = max(1, int(len(xyz) * rng.uniform(0.003, 0.01)))
    idx = rng.choice(len(xyz), size=min(n, len(xyz)), replace=False)
    size = np.maximum(10.0 * noise_m, rng.uniform(0.02, 0.05, size=len(idx)))
    out[idx] += unit(rng.normal(size=(len(idx), 3))) * size[:, None]
    return out


def add_gaps(rng: np.random.Generator, t: Array, xyz: Array, keep_before_s: float) -> Array:
    """``xyz`` with one to three occlusions of 0.1-0.5 s (NaN rows), none before ``keep_before_s``."""
    out = xyz.copy()
    for _ in range(int(rng.integers(1, 4))):
        start = rng.uniform(keep_before_s, max(keep_before_s, t[-1] - 0.2))
        out[(t >= start) & (t < start + rng.uniform(0.1, 0.5))] = np.nan
    return out


def thin(rng: np.random.Generator, t: Array, xyz: Array, keep_frac: float) -> tuple[Array, Array]:
    """A sparse track: a random ``keep_frac`` of the samples (the first always kept)."""
    keep = rng.uniform(size=len(t)) < keep_frac
    keep[0] = True
    return t[keep], xyz[keep]


def hold_repeats(rng: np.random.Generator, xyz: Array) -> Array:
    """``xyz`` with 2-5 % of samples repeating the previous one (a tracker that re-sends a stale value)."""
    out = xyz.copy()
    idx = np.flatnonzero(rng.uniform(size=len(xyz)) < rng.uniform(0.02, 0.05))
    for k in idx[idx > 0]:
        out[k] = out[k - 1]
    return out


def rotation_noise(rng: np.random.Generator, n: int, sigma_rad: float) -> Array:
    """Small random rotations (n, 3, 3) with a per-axis sigma of ``sigma_rad``."""
    return matrix_from_rotvec(rng.normal(0.0, sigma_rad, size=(n, 3)))


NAME_STYLES = ("marker_{k}", "Unlabeled {k}", "rb{j}/m{k}", "M{k:03d}", "/mocap/marker_{k}")
"""How motion-capture systems name markers they were not told about (Vicon, OptiTrack, Qualisys, ROS drivers)."""


def marker_names(rng: np.random.Generator, n: int) -> list[str]:
    """``n`` distinct marker names in one style drawn from ``NAME_STYLES``, numbered at random."""
    style = str(rng.choice(NAME_STYLES))
    base = 1000 if style.startswith("Unlabeled") else 0
    ks = rng.choice(np.arange(base, base + 40), size=n, replace=False)
    js = rng.integers(1, 4, size=n)
    return [style.format(k=int(k), j=int(j)) for k, j in zip(ks, js, strict=True)]
