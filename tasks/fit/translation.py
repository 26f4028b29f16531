"""Translation fit (Section III): the direction is the largest eigenvector of the pooled scatter of the
markers of one rigid part (each marker centred on its own mean); sign fixed so the motion is positive."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tasks.arrays import FloatArray, Points, Vector3
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


TRAVEL_TOLERANCE = 0.25
"""Largest relative difference in travel between two markers of one sliding part: a drawer or slide that yaws by
its play as it moves shifts one marker's travel against another's by a few percent; a turn about an axis through
or near the part changes them by the ratio of their radii."""
TRAVEL_SIGMAS = 4.0
"""Standard errors by which the markers' travel ratio must differ from 1 before the part cannot be translating."""
MAX_INTERP_GAP_S = 0.1
"""Longest gap (s) in the reference marker's samples that its position is interpolated across: a hand-driven
part's speed changes little within 0.1 s."""


def travel_ratio(t_ref: FloatArray, u_ref: FloatArray, t: FloatArray, u: FloatArray) -> tuple[float, float] | None:
    """Travel of one marker along a line relative to a reference marker's: the slope (and its standard error) of
    the total-least-squares line through (reference coordinate interpolated at the marker's times (s), marker
    coordinate) (m). A rigid translation moves every marker the same distance, slope 1; a rotation moves each by
    its radius times the angle. Markers of one rigid part share its path's wobble, so paired samples differ by
    sensor noise, independent from sample to sample. None without 4 paired samples or with no travel to compare."""
    if len(t_ref) < 2 or len(t) < 4:
        return None
    k = np.clip(np.searchsorted(t_ref, t), 1, len(t_ref) - 1)
    paired = (t >= t_ref[0]) & (t <= t_ref[-1]) & (t_ref[k] - t_ref[k - 1] <= MAX_INTERP_GAP_S)
    if paired.sum() < 4:
        return None
    xy = np.column_stack([np.interp(t[paired], t_ref, u_ref), u[paired]])
    xy = xy - xy.mean(axis=0)
    evals, evecs = np.linalg.eigh(xy.T @ xy / len(xy))
    along, across = float(evals[1]), float(max(evals[0], 0.0))
    a, b = evecs[:, 1]
    if along <= across or abs(a) < 1e-12:
        return None
    slope = float(b / a)
    n = float(len(xy))
    angle_std = float(np.sqrt(across / (along * (n - 2.0))))
    return slope, angle_std * (1.0 + slope**2)


def travels_agree(times: list[FloatArray], coords: list[FloatArray]) -> bool:
    """Whether markers of one part travel equal distances along a line, as a rigid translation moves them: each
    marker's travel ratio (``travel_ratio``) to the best-sampled marker's is 1 within ``TRAVEL_TOLERANCE`` or
    ``TRAVEL_SIGMAS`` standard errors. Per-marker times (s) and coordinates along the line (m)."""
    if len(times) < 2:
        return True
    ref = max(range(len(times)), key=lambda i: len(times[i]))
    for i, (t, u) in enumerate(zip(times, coords, strict=True)):
        if i == ref or (got := travel_ratio(times[ref], coords[ref], t, u)) is None:
            continue
        slope, std = got
        if abs(slope - 1.0) > max(TRAVEL_TOLERANCE, TRAVEL_SIGMAS * std):
            return False
    return True
