"""The demonstrator's hand found by its motion (Section III-D of the paper: the approach is undefined and dropped).

A hand marker reaches for the object while every marker of the part it will move rests, moves rigidly with that
part while the part moves, and withdraws while the part rests again. A marker of a part that moves first and then
rides on another part (a lever pressed before its door swings) reaches and rides but never withdraws alone, so
it stays an object marker. Names and the wrist pose stream are hints used beside this (``tasks.learn.prepare``).
"""

from __future__ import annotations

import itertools

import numpy as np

from tasks.learn.chain import marker_kind, rigid_with
from tasks.learn.params import LearnParams
from tasks.learn.prepare import ORIENTATION_SEPARATOR, PreparedRecording
from tasks.segment.tracks import Track


def body_of(name: str) -> str:
    """The rigid body a marker belongs to: a point made from a body's orientation belongs to that body."""
    return name.split(ORIENTATION_SEPARATOR, 1)[0]


def hand_by_motion(prep: PreparedRecording, spans: list[tuple[float, float]], params: LearnParams) -> frozenset[str]:
    """Names of the markers that reach, ride with a moving part and withdraw (see the module docstring)."""
    bodies: dict[str, list[Track]] = {}
    for tr in prep.tracks:
        bodies.setdefault(body_of(tr.name), []).append(tr)
    if len(bodies) < 2:
        return frozenset()
    moving: dict[str, list[bool]] = {}
    for body, tracks in bodies.items():
        kinds = [[marker_kind(tr, a, b, params.undefined_nats) for a, b in spans] for tr in tracks]
        moving[body] = [any(k[i] not in (None, "still") for k in kinds) for i in range(len(spans))]
    hand: set[str] = set()
    for h, o in itertools.permutations(bodies, 2):
        mov_h, mov_o = moving[h], moving[o]
        if not any(mov_o):
            continue
        first = mov_o.index(True)
        last = len(mov_o) - 1 - mov_o[::-1].index(True)
        reach = any(mov_h[i] for i in range(first))
        withdraw = any(mov_h[i] for i in range(last + 1, len(spans)))
        if not (reach and withdraw):
            continue
        ride = any(
            mov_h[i] and mov_o[i] and _rides(bodies[h], bodies[o], *spans[i], params.rigid_tol_m)
            for i in range(first, last + 1)
        )
        if ride:
            hand.update(tr.name for tr in bodies[h])
    return frozenset(hand)


def _rides(hand: list[Track], part: list[Track], t0: float, t1: float, tol_m: float) -> bool:
    """Whether a marker of ``hand`` keeps its distance to a marker of ``part`` over [t0, t1) within the rigid
    tolerance, widened by the two markers' sensor noise."""
    for h, p in itertools.product(hand, part):
        noise = float(np.hypot(h.sigma_hf_m, p.sigma_hf_m)) * np.sqrt(3.0)
        if rigid_with(h, p, t0, t1, max(tol_m, 3.0 * noise)):
            return True
    return False
