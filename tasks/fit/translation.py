"""Translation fit (Section III): the direction is the largest eigenvector of the pooled scatter of the
markers of one rigid part (each marker centred on its own mean); sign fixed so the motion is positive."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tasks.arrays import Points, Vector3
from tasks.fit.geometry import net_change, unit


@dataclass(frozen=True)
class TranslationFit:
    """Unit direction (motion positive along it), distance moved (m, >= 0), centroid (m), residual rms (m),
    scatter eigenvalues (m^2, largest first) and direction standard deviation (rad)."""

    dir: Vector3
    distance_m: float
    centroid: Vector3
    rms_m: float
    eigenvalues: tuple[float, float, float]
    dir_std_rad: float
    rss: float
    n: int


def fit_translation(tracks: list[Points]) -> TranslationFit:
    """Fit one translation direction to the (n_m, 3) tracks of the markers of one rigid part (metres)."""
    centred = np.concatenate([t - t.mean(axis=0) for t in tracks])
    n = len(centred)
    evals, evecs = np.linalg.eigh(centred.T @ centred / n)
    evals = np.maximum(evals, 0.0)
    d = evecs[:, 2]
    nets = [net_change((t - t.mean(axis=0)) @ d) for t in tracks]
    net = float(np.average(nets, weights=[len(t) for t in tracks]))
    if net < 0:
        d = -d
    rss = float(n * (evals[0] + evals[1]))
    perp_var = float(evals[0] + evals[1]) / 2.0
    dir_std = float(np.sqrt(2.0 * perp_var / max(n * evals[2], 1e-300)))
    return TranslationFit(
        dir=unit(d),
        distance_m=abs(net),
        centroid=np.concatenate(tracks).mean(axis=0),
        rms_m=float(np.sqrt(rss / n)),
        eigenvalues=(float(evals[2]), float(evals[1]), float(evals[0])),
        dir_std_rad=dir_std,
        rss=rss,
        n=n,
    )
