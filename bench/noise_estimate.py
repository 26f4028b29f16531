"""Per-marker noise covariance: ``tasks.fit.noise.noise_covariance`` beside scikit-learn's MinCovDet on the same
fourth differences (time per marker and the estimated per-axis sigmas against the truth).

Development: isotropic and camera-like (depth 8x) noise at 100 Hz, seed 0; held out: seed 1 at 240 Hz.

    .venv/bin/python bench/noise_estimate.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from sklearn.covariance import MinCovDet

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tasks.fit.noise import DIFFERENCE, NOISE_LAG_S, noise_covariance


def _track(rng: np.random.Generator, hz: float, sigmas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, 20.0, 1.0 / hz)
    s = np.clip((t - 5.0) / 4.0, 0.0, 1.0)
    angle = 1.2 * (10 * s**3 - 15 * s**4 + 6 * s**5)
    pts = np.column_stack([0.5 * np.cos(angle), 0.5 * np.sin(angle), np.zeros_like(t)])
    return t, pts + rng.normal(0.0, 1.0, pts.shape) * sigmas


def _mincovdet(points: np.ndarray, t: np.ndarray) -> np.ndarray:
    lag = max(1, round(NOISE_LAG_S / float(np.median(np.diff(t)))))
    n = len(points) - lag * (len(DIFFERENCE) - 1)
    d4 = sum(w * points[k * lag : k * lag + n] for k, w in enumerate(DIFFERENCE))
    out: np.ndarray = MinCovDet(random_state=0).fit(d4).covariance_ / float(np.sum(DIFFERENCE**2))
    return out


def main() -> None:
    print(f"{'part':<12} {'noise (mm)':<18} {'method':<22} {'ms / marker':>12} {'sigmas found (mm)':>26}")
    for part, seed, hz in (("development", 0, 100.0), ("held out", 1, 240.0)):
        for label, sig in (("isotropic 1", np.array([1e-3] * 3)), ("depth 8x", np.array([0.5e-3, 0.5e-3, 4e-3]))):
            t, pts = _track(np.random.default_rng(seed), hz, sig)
            for name, fn in (("ours (MAD on axes)", noise_covariance), ("sklearn MinCovDet", _mincovdet)):
                t0 = time.perf_counter()
                cov = fn(pts, t)
                ms = (time.perf_counter() - t0) * 1e3
                found = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * 1e3
                cells = ", ".join(f"{v:.2f}" for v in found)
                print(f"{part:<12} {label:<18} {name:<22} {ms:>12.1f} {cells:>26}")


if __name__ == "__main__":
    main()
