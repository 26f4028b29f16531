"""Primitive boundaries moved out to where the part leaves and reaches its rests.

The change-point search places a boundary where a moving model starts to pay for itself; a slow start of a part
whose markers lie near its axis (a bottle cap turned by a min-jerk twist) stays cheaper as "still" for a second or
more. Here the part's coordinate along its fitted primitive (angle about the axis, weighted by r^2 over the
markers, or distance along the direction) is followed back from the primitive into the rest before it, and on
into the rest after it: the boundary becomes the last (first) time the smoothed coordinate is within
``REST_SIGMAS`` noise sigmas of the rest level, that is where the motion is first seen above the noise.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tasks.arrays import FloatArray
from tasks.fit.geometry import perpendicular_basis
from tasks.fit.noise import independent_draws, series_noise
from tasks.learn.chain import SegmentFit, fit_span, rest_window
from tasks.learn.params import LearnParams
from tasks.learn.prepare import MIN_SAMPLES, PreparedRecording
from tasks.segment.tracks import Track

SMOOTH_S = 0.1
"""Moving-average window (s) of the part's coordinate before the rest test."""
REST_SIGMAS = 4.0
"""The smoothed coordinate leaves the rest when it is this many of its noise sigmas from the rest level."""
MIN_REST_SAMPLES = 3
"""Samples a rest level is the median of: the fewest whose median rejects one outlying sample."""


def part_coordinate(f: SegmentFit, tracks: list[Track], grid: FloatArray) -> tuple[FloatArray, float] | None:
    """The part's coordinate on ``grid`` (rad or m; NaN where a marker is missing) and its per-sample noise. A
    marker's angle weighs by its squared radius (the inverse variance of an angle) over the grid's span, where the
    angle is measured: a marker resting near the axis there has an angle of noise alone, whatever radius it reaches
    later in the recording."""
    cols = []
    wts = []
    sig2 = []
    for tr in tracks:
        if len(tr.t_s) < MIN_SAMPLES:
            continue
        if f.kind == "rotation" and f.rotation is not None:
            e1, e2 = perpendicular_basis(f.rotation.dir)
            q = tr.points - f.rotation.pos
            rho = np.hypot(q @ e1, q @ e2)
            seen = (tr.t_s >= grid[0]) & (tr.t_s <= grid[-1]) if len(grid) else np.ones(len(q), dtype=bool)
            radius = float(np.median(rho[seen] if seen.any() else rho))
            coord = np.unwrap(np.arctan2(q @ e2, q @ e1))
            weight = radius**2
            noise2 = tr.sigma_hf_m**2 / max(radius**2, 1e-12)
        elif f.kind == "translation" and f.translation is not None:
            coord = tr.points @ f.translation.dir
            weight = 1.0
            noise2 = tr.sigma_hf_m**2
        else:
            return None
        idx = np.searchsorted(tr.t_s, grid)
        ok = (idx > 0) & (idx < len(tr.t_s))
        col = np.interp(grid, tr.t_s, coord)
        col[~ok] = np.nan
        cols.append(col - np.nanmedian(col))
        wts.append(weight)
        sig2.append(weight**2 * noise2)
    if not cols:
        return None
    stack = np.array(cols)
    w = np.array(wts)[:, None] * np.isfinite(stack)
    total = w.sum(axis=0)
    with np.errstate(invalid="ignore"):
        out: FloatArray = np.where(total > 0, np.nansum(stack * w, axis=0) / np.where(total > 0, total, 1.0), np.nan)
    noise = float(np.sqrt(np.sum(sig2))) / float(np.sum(wts))
    return out, noise


def smooth(t_s: FloatArray, values: FloatArray, window_s: float) -> tuple[FloatArray, FloatArray]:
    """Centred moving average over ``window_s`` seconds of time, ignoring NaNs, and how many samples each average
    holds (the average is NaN where none). A window in time, not in samples: across an occlusion gap or uneven
    sampling it never mixes values seconds apart."""
    ok = np.isfinite(values)
    sums = np.concatenate([[0.0], np.cumsum(np.where(ok, values, 0.0))])
    counts = np.concatenate([[0.0], np.cumsum(ok.astype(np.float64))])
    lo = np.searchsorted(t_s, t_s - window_s / 2, side="left")
    hi = np.searchsorted(t_s, t_s + window_s / 2, side="right")
    den = counts[hi] - counts[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        out: FloatArray = np.where(den > 0, (sums[hi] - sums[lo]) / np.where(den > 0, den, 1.0), np.nan)
    return out, den


def _departure(t: FloatArray, c: FloatArray, rest: FloatArray, noise: FloatArray) -> float | None:
    """Time (s) nearest the motion where the coordinate is last within ``REST_SIGMAS`` of its noise sigmas
    (per sample) of the rest level, scanning from the motion (``t`` ordered from the motion outwards, ``rest``
    the rest samples' coordinates)."""
    finite = rest[np.isfinite(rest)]
    if len(finite) < MIN_REST_SAMPLES:
        return None
    level = float(np.median(finite))
    within = np.abs(c - level) <= np.maximum(REST_SIGMAS * noise, 1e-12)
    hits = np.flatnonzero(within & np.isfinite(c))
    if not len(hits):
        return None
    return float(t[hits[0]])


def refine_boundaries(prep: PreparedRecording, fits: list[SegmentFit], params: LearnParams) -> list[SegmentFit]:
    """Each primitive's start and end (s) moved into the neighbouring rests of its part up to where the part is
    seen to leave or reach them. Segments never overlap: the still segments it reaches into shrink to match, and
    any other segment it reaches into is fitted again on what is left of it (each goes when nothing is left)."""
    by_name = {tr.name: tr for tr in prep.tracks}
    out = list(fits)
    for i in range(len(out)):
        f = out[i]
        if f.kind not in ("rotation", "translation"):
            continue
        names = [n for n in f.markers if n not in prep.hand] or list(f.markers)
        tracks = [by_name[n] for n in names]
        windows = [rest_window(n, out, i, -1) for n in names], [rest_window(n, out, i, +1) for n in names]
        lo = max((w[0] for w in windows[0] if w is not None), default=None)
        hi = min((w[1] for w in windows[1] if w is not None), default=None)
        start, end = f.t_start, f.t_end
        grid = max(tracks, key=lambda tr: len(tr.t_s)).t_s
        got = part_coordinate(f, tracks, grid)
        if got is None or len(grid) < 2:
            continue
        coord, sample_noise = got
        level, counts = smooth(grid, coord, SMOOTH_S)
        noise = sample_noise / np.sqrt(np.maximum(counts, 1.0))
        if lo is not None:
            before = (grid >= lo) & (grid < f.t_start)
            rest = level[before][: max(len(level[before]) // 2, 1)]
            t_back = grid[before][::-1]
            found = _departure(t_back, level[before][::-1], rest, noise[before][::-1])
            start = min(start, found) if found is not None else start
        if hi is not None:
            after = (grid >= f.t_end) & (grid < hi)
            rest = level[after][len(level[after]) // 2 :]
            found = _departure(grid[after], level[after], rest, noise[after])
            end = max(end, found) if found is not None else end
        out[i] = _widened(prep, f, float(start), float(end), params)
        k = i - 1
        while k >= 0 and out[k].t_end > start:
            out[k] = _cut(prep, out[k], out[k].t_start, max(float(start), out[k].t_start), params)
            k -= 1
        k = i + 1
        while k < len(out) and out[k].t_start < end:
            out[k] = _cut(prep, out[k], min(float(end), out[k].t_end), out[k].t_end, params)
            k += 1
    return [f for f in out if f.t_end > f.t_start]


def _widened(prep: PreparedRecording, f: SegmentFit, start: float, end: float, params: LearnParams) -> SegmentFit:
    """Primitive ``f`` over [start, end] (s). When its span grew, the part's path is classified again from the last
    rest sample before the motion to the first after it (across an occlusion gap, those are all that is seen of
    the motion's end): a path that this shows decisively to be of the other kind of motion gets that kind's fit;
    otherwise ``f``'s fit stands, which may hold more evidence than its span (a swing cut at a reversal keeps the
    fit of the whole to-and-fro)."""
    if (start, end) == (f.t_start, f.t_end):
        return f
    refit = fit_span(prep, start, float(np.nextafter(end, np.inf)), params)
    if refit.kind in ("rotation", "translation") and refit.kind != f.kind and _decisive(refit, f.kind):
        return replace(refit, t_end=end)
    return replace(f, t_start=start, t_end=end)


OVERTURN_NATS = 3.0
"""Evidence (nats) a widened span's own fit needs over the kind its primitive was fitted as before that kind is
overturned: strong odds (20 to 1, Jeffreys' scale), since the primitive's kind may rest on more than this span."""


def _decisive(refit: SegmentFit, kind: str) -> bool:
    """Whether the widened span's fit beats ``kind`` by ``OVERTURN_NATS``: a door's short push back, cut at its
    reversal from the swing it undoes, fits a line about as well as an arc over its few samples."""
    return refit.scores.get(kind, np.inf) - refit.scores.get(refit.kind, np.inf) > OVERTURN_NATS


def _cut(prep: PreparedRecording, f: SegmentFit, t0: float, t1: float, params: LearnParams) -> SegmentFit:
    """Segment ``f`` cut to [t0, t1) (s): a still one keeps its kind, any other is fitted again on the samples
    left (a span too short to fit is still); an empty span has ``t_end == t_start``."""
    if (t0, t1) == (f.t_start, f.t_end):
        return f
    if f.kind == "still" or t1 <= t0:
        return replace(f, t_start=t0, t_end=max(t0, t1))
    return fit_span(prep, t0, t1, params)


def _settled(level: FloatArray, tol: float, edge: int) -> tuple[int, int]:
    """The last index before the sequence first leaves its starting level by more than ``tol``, and the first index
    from which it stays within ``tol`` of its final level (NaN-free input). The levels are taken ``edge`` samples in
    from each end, the first values whose moving average had a full window: a value at the very end averages half as
    many samples, and its larger noise would read as motion."""
    edge = min(max(edge, 0), (len(level) - 1) // 2)
    away_start = np.flatnonzero(np.abs(level - level[edge]) > tol)
    away_end = np.flatnonzero(np.abs(level - level[len(level) - 1 - edge]) > tol)
    first = int(away_start[0]) - 1 if len(away_start) else 0
    last = int(away_end[-1]) + 1 if len(away_end) else len(level) - 1
    return max(first, 0), min(last, len(level) - 1)


def smoothed_coordinate(
    prep: PreparedRecording, f: SegmentFit, min_samples: int
) -> tuple[FloatArray, FloatArray, float] | None:
    """The part's coordinate along primitive ``f`` over its span (object markers, else all of its markers) on the
    densest marker's times, smoothed over ``SMOOTH_S``: times (s), smoothed values (rad or m; NaN where no marker
    is seen) and their noise sigma; None with fewer than ``min_samples`` times."""
    by_name = {tr.name: tr for tr in prep.tracks}
    names = [n for n in f.markers if n not in prep.hand] or list(f.markers)
    tracks = [by_name[n] for n in names]
    grid_all = max(tracks, key=lambda tr: len(tr.t_s)).t_s
    grid = grid_all[(grid_all >= f.t_start) & (grid_all < f.t_end)]
    got = part_coordinate(f, tracks, grid) if len(grid) >= max(min_samples, 2) else None
    if got is None:
        return None
    coord, noise = got
    level, counts = smooth(grid, coord, SMOOTH_S)
    return grid, level, level_noise(grid, coord, noise, float(np.median(counts)))


def level_noise(t_s: FloatArray, coord: FloatArray, noise: float, count: float) -> float:
    """Noise sigma of a moving average of ``count`` samples of the coordinate ``coord`` (at times ``t_s``, s;
    NaN where unseen) whose per-sample sigma the markers' noise gives as ``noise``: or, when larger, as the series
    itself shows it along the coordinate, where the noise may be anisotropic (a camera's depth); averaged down by
    the independent draws the window holds (``independent_draws``: at most one per camera frame, fewer under
    noise correlated over tens of milliseconds)."""
    ok = np.isfinite(coord)
    own, tau = series_noise(coord[ok], t_s[ok])
    dt = float(np.median(np.diff(t_s[ok]))) if ok.sum() > 1 else 0.0
    draws = independent_draws(count, (count - 1.0) * dt, tau)  # one draw at most for a count of one or less
    return max(noise, own) / float(np.sqrt(draws))


def trim_to_motion(prep: PreparedRecording, fits: list[SegmentFit]) -> list[SegmentFit]:
    """Each primitive's span shrunk to where its part moves: a pause before or after the motion, which the
    change-point search left inside the primitive (too short to pay for a segment of its own), becomes a still
    segment of the part's markers."""
    out: list[SegmentFit] = []
    for f in fits:
        got = smoothed_coordinate(prep, f, MIN_SAMPLES) if f.kind in ("rotation", "translation") else None
        if got is None:
            out.append(f)
            continue
        grid, level, noise = got
        ok = np.isfinite(level)
        if ok.sum() < MIN_SAMPLES:
            out.append(f)
            continue
        t_ok = grid[ok]
        dt = float(np.median(np.diff(t_ok)))
        first, last = _settled(level[ok], REST_SIGMAS * noise, round(SMOOTH_S / dt) // 2 if dt > 0 else 0)
        start = float(t_ok[first]) if first > 0 else f.t_start
        end = float(t_ok[last]) if last < len(t_ok) - 1 else f.t_end
        if end - start < SMOOTH_S:
            out.append(f)
            continue
        still = frozenset(f.markers) | f.still_markers
        if start > f.t_start:
            out.append(SegmentFit("still", f.t_start, start, still_markers=still, note="pause before the motion"))
        out.append(replace(f, t_start=start, t_end=end))
        if end < f.t_end:
            out.append(SegmentFit("still", end, f.t_end, still_markers=still, note="pause after the motion"))
    return out
