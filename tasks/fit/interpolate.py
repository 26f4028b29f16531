"""A marker's position at other times: linear interpolation between its samples, never across an occlusion.

Comparing two markers (their distance, their travel along a line, a rigid part's configuration) needs both at the
same times, so one is interpolated at the other's sample times. Across an occlusion the interpolated position is
the chord of whatever the part did meanwhile, not where the marker was.
"""

from __future__ import annotations

import numpy as np

from tasks.arrays import BoolArray, FloatArray, Points

MAX_INTERP_GAP_S = 0.1
"""Longest interval (s) between samples that a position is interpolated across: a hand-driven part's speed changes
little within 0.1 s (at 2 m/s^2 the chord is off by 2.5 mm)."""
MAX_GAP_SAMPLES = 3.0
"""An interval longer than this many of the track's median sample intervals is an occlusion, whatever the rate
(at a low rate, interpolating between regular samples is all there is)."""


def longest_interval_s(t_s: FloatArray) -> float:
    """Longest interval (s) between a track's samples that is not an occlusion (see the module constants)."""
    dt = float(np.median(np.diff(t_s))) if len(t_s) > 1 else 0.0
    return max(MAX_INTERP_GAP_S, MAX_GAP_SAMPLES * dt)


def bracketed(t_ref: FloatArray, t_s: FloatArray) -> BoolArray:
    """Whether each time in ``t_s`` (s) lies on a sample of ``t_ref`` (sorted, s) or between two of its samples
    that are not an occlusion apart."""
    if len(t_ref) < 2:
        out: BoolArray = np.isin(t_s, t_ref)
        return out
    k = np.clip(np.searchsorted(t_ref, t_s), 1, len(t_ref) - 1)
    inside = (t_s >= t_ref[0]) & (t_s <= t_ref[-1])
    exact = (t_ref[k] == t_s) | (t_ref[k - 1] == t_s)
    ok: BoolArray = inside & (exact | (t_ref[k] - t_ref[k - 1] <= longest_interval_s(t_ref)))
    return ok


def positions_at(t_ref: FloatArray, p_ref: Points, t_s: FloatArray) -> Points:
    """Positions (m) of a marker sampled at ``t_ref`` (s), linearly interpolated at ``t_s`` (s)."""
    out: Points = np.column_stack([np.interp(t_s, t_ref, p_ref[:, i]) for i in range(p_ref.shape[1])])
    return out
