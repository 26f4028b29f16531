"""The demonstrator's hand found by its motion (Section III-D of the paper: the approach is undefined and dropped).

A hand marker reaches for the object while every marker of the part it will move rests, moves rigidly with that
part while the part moves, and withdraws while the part rests again; reaching and withdrawing, it changes its
distance to the part (a marker of the part itself, seen to move before another one near the axis at a slow start,
keeps its distance). A marker of a part that moves first and then rides on another part (a lever pressed before its
door swings) reaches and rides but never withdraws alone, so it stays an object marker. Names and the wrist pose
stream are hints used beside this (``tasks.learn.prepare``). A marker that moves rigidly with a hand marker both
while it reaches and while it withdraws is on the hand too, though it was not seen riding the part (hidden or
sparsely sampled while the part moved).
"""

from __future__ import annotations

import itertools

import numpy as np

from tasks.arrays import FloatArray
from tasks.learn.chain import displaced, distances_to, marker_kind, noise_draws, rigid_with
from tasks.learn.params import LearnParams
from tasks.learn.prepare import ORIENTATION_SEPARATOR, PreparedRecording
from tasks.segment.tracks import Track, span_indices


def body_of(name: str) -> str:
    """The rigid body a marker belongs to: a point made from a body's orientation belongs to that body."""
    return name.split(ORIENTATION_SEPARATOR, 1)[0]


WINDOW_S = 0.5
"""Longest time (s) over which a body is judged moving or resting: a reach, a ride or a withdrawal by a human arm
lasts at least this long, so none hides inside a longer span that also holds the part's motion or rest."""


def windows(spans: list[tuple[float, float]], longest_s: float) -> tuple[list[tuple[float, float]], list[int]]:
    """Each span (s) cut into equal pieces of at most ``longest_s``, and the index of the span each piece is of."""
    out: list[tuple[float, float]] = []
    parent: list[int] = []
    for n, (a, b) in enumerate(spans):
        k = max(1, int(np.ceil((b - a) / longest_s)))
        edges = np.linspace(a, b, k + 1)
        out.extend((float(x), float(y)) for x, y in itertools.pairwise(edges))
        parent.extend([n] * k)
    return out, parent


def _moving(tracks: list[Track], spans: list[tuple[float, float]], undefined: float) -> list[bool]:
    """Per span (s), whether a marker of the body is best explained by a motion model there."""
    kinds = [[marker_kind(tr, a, b, undefined) for a, b in spans] for tr in tracks]
    return [any(k[i] not in (None, "still") for k in kinds) for i in range(len(spans))]


def hand_by_motion(prep: PreparedRecording, spans: list[tuple[float, float]], params: LearnParams) -> frozenset[str]:
    """Names of the markers that reach, ride with a moving part and withdraw (see the module docstring). Each body
    is judged moving over the spans cut into ``WINDOW_S`` windows where both the window and its span show motion:
    a window's few samples alone would let noise pass for motion now and then."""
    bodies: dict[str, list[Track]] = {}
    for tr in prep.tracks:
        bodies.setdefault(body_of(tr.name), []).append(tr)
    if len(bodies) < 2:
        return frozenset()
    cut, parent = windows(spans, WINDOW_S)
    moving: dict[str, list[bool]] = {}
    for body, tracks in bodies.items():
        in_span = _moving(tracks, spans, params.undefined_nats)
        in_window = [any(displaced(tr, a, b) for tr in tracks) for a, b in cut]
        moving[body] = [w and in_span[parent[i]] for i, w in enumerate(in_window)]
    tol = params.rigid_tol_m
    hand: set[str] = set()
    rode: dict[str, tuple[int, int]] = {}
    for h, o in itertools.permutations(bodies, 2):
        mov_h, mov_o = moving[h], moving[o]
        if not any(mov_o):
            continue
        first = mov_o.index(True)
        last = len(mov_o) - 1 - mov_o[::-1].index(True)
        hb, ob = bodies[h], bodies[o]
        reach = any(mov_h[:first]) and any(_distance_changes(hb, ob, cut[i], cut[first], tol) for i in range(first))
        withdraw = any(mov_h[last + 1 :]) and any(
            _distance_changes(hb, ob, cut[last], cut[i], tol) for i in range(last + 1, len(cut))
        )
        if not (reach and withdraw):
            continue
        ride = any(mov_h[i] and mov_o[i] and _rides(hb, ob, *cut[i], tol) for i in range(first, last + 1))
        if ride:
            hand.update(tr.name for tr in bodies[h])
            rode[h] = (first, last)
    for b, (h, (first, last)) in itertools.product(bodies, rode.items()):
        if b in rode:
            continue
        both = [i for i, m in enumerate(moving[b]) if m and moving[h][i]]
        along = [i for i in both if _rides(bodies[b], bodies[h], *cut[i], tol)]
        if any(i < first for i in along) and any(i > last for i in along):
            hand.update(tr.name for tr in bodies[b])
    return frozenset(hand)


def _rides(hand: list[Track], part: list[Track], t0: float, t1: float, tol_m: float) -> bool:
    """Whether a marker of ``hand`` keeps its distance to a marker of ``part`` over [t0, t1) within the rigid
    tolerance, widened by the two markers' sensor noise."""
    for h, p in itertools.product(hand, part):
        noise = float(np.hypot(h.sigma_hf_m, p.sigma_hf_m)) * np.sqrt(3.0)
        if rigid_with(h, p, t0, t1, max(tol_m, 3.0 * noise)):
            return True
    return False


DISTANCE_SIGMAS = 4.0
"""A hand's distance to the part has changed when the two windows' median distances differ by this many of their
standard errors over their independent samples (``noise_draws``; and by more than the rigid tolerance)."""


def _distance_changes(
    hand: list[Track], part: list[Track], a: tuple[float, float], b: tuple[float, float], tol_m: float
) -> bool:
    """Whether a marker of ``hand`` is at another distance from a marker of ``part`` over window ``a`` than over
    window ``b`` (s), by more than ``tol_m`` (m, the rigid tolerance): it reached or withdrew, where a marker of the
    part keeps its distance to all of the part however its motion is seen to start."""
    for h in hand:
        draws_a = noise_draws(h, *span_indices(h, *a))
        draws_b = noise_draws(h, *span_indices(h, *b))
        for p in part:
            da = _distances(h, p, *a)
            db = _distances(h, p, *b)
            if len(da) < 2 or len(db) < 2:
                continue
            sigma = float(np.hypot(h.sigma_hf_m, p.sigma_hf_m))
            na, nb = min(len(da), draws_a), min(len(db), draws_b)
            stderr = MEDIAN_EFFICIENCY * sigma * float(np.sqrt(1.0 / na + 1.0 / nb))
            if abs(float(np.median(da) - np.median(db))) > max(tol_m, DISTANCE_SIGMAS * stderr):
                return True
    return False


MEDIAN_EFFICIENCY = 1.2533
"""Standard error of a median over that of a mean, for Gaussian samples (sqrt(pi / 2))."""


def _distances(track: Track, ref: Track, t0: float, t1: float) -> FloatArray:
    """Distances (m) of ``track``'s samples in [t0, t1) (s) to ``ref`` interpolated at their times."""
    i, j = span_indices(track, t0, t1)
    if len(ref.t_s) < 2 or j <= i:
        return np.zeros(0)
    return distances_to(track.t_s[i:j], track.points[i:j], ref.t_s, ref.points)
