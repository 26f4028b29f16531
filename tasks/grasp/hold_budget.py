"""The hold checks one plan may run (``HoldBudget``): how many, how many simulated seconds of shaking, which grasp
lasted longest, and on a part planned on its bar which held only loosely; and what counts as held with a force
closure (``squeezed``, ``closed_or_squeezed``).
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import itertools
import math
from collections.abc import Callable, Iterable, Iterator

import numpy as np

from tasks.arrays import FloatArray
from tasks.grasp import worker_pool
from tasks.grasp.candidate_grasp import grasp_from_candidate
from tasks.grasp.hold_check import CHECK_CYCLES, CHECK_LENGTH_S, check_length_s, hold_check
from tasks.grasp.object_model import ObjectModel
from tasks.grasp.planner import GraspCandidate, rank_tier
from tasks.grasp.settle import settle
from tasks.grasp.shake import ShakeParams, ShakeResult, shake_test
from tasks.grasp.worker_pool import Beside

CHECK_BUDGET_S = 20.0
"""Simulated seconds of shaking the hold checks of one plan (``api.SHAKE_BUDGET`` of them) may take in all (a
check stops when the part slips; one that holds takes ``CHECK_LENGTH_S``, 0.08-0.12 s CPU per simulated second on a
scan's convex pieces). A further round is searched, and a check started, only while a whole check still fits in what
is left: about three whole checks, so that one or two checks that slip part-way still leave room for a whole one."""
FIRM_SHIFT_M = 0.0025
FIRM_TURN_RAD = math.radians(2.5)
"""On a part planned on its bar: a grasp that held under the check but let the part move or turn more than these
(half the check's tolerances) is kept back while a firmer one may be found (the later passes, then the grasps slid
along the bar, then the pinches), and chosen only when none is: a round bar that turns a few degrees in the 6 s
check goes on rolling in a longer shake, while a firm grasp stays within 1-2°."""
HELD_MU = 0.8
"""Friction coefficient of the hold check's contacts: the part's 0.8 (``shake.ShakeParams.friction``) times the
finger pads' 1.0, as Bullet combines them. The planner's qualities use ``quality.DEFAULT_MU`` (0.5); a grasp that
held under the check without a force closure there is, as a last resort, judged at this one
(``held_closure``)."""
Tried = tuple[GraspCandidate, ObjectModel]


class HoldBudget:
    """Hold checks left for one plan (a count and simulated seconds); the checked grasp that lasted longest."""

    def __init__(
        self,
        count: int,
        seconds: float | None = None,
        cycles: float = CHECK_CYCLES,
        loose: list[GraspCandidate] | None = None,
    ) -> None:
        """Allow ``count`` checks of ``cycles`` (``hold_check``) and ``seconds`` of simulated shaking (by default
        ``CHECK_BUDGET_S`` scaled with the checks' length)."""
        self.left = count
        self.cycles = cycles
        self.seconds = CHECK_BUDGET_S * check_length_s(cycles) / CHECK_LENGTH_S if seconds is None else seconds
        self.longest: GraspCandidate | None = None
        self.longest_s = -1.0
        self.loose = loose
        """When given: accepted grasps that held but let the part move more than ``FIRM_SHIFT_M`` or turn more than
        ``FIRM_TURN_RAD`` are put here instead of returned."""
        self.unaccepted: list[GraspCandidate] = []
        """Candidates that held but that ``accept`` turned down, in the order checked."""

    def spent(self) -> bool:
        """Whether no further check may start: none left, or a check that holds (``check_length_s``) would
        overrun the simulated seconds left."""
        return self.left <= 0 or self.seconds < check_length_s(self.cycles)

    def first_that_holds(
        self,
        candidates: Iterable[Tried],
        checks: int,
        program: Callable[[FloatArray], ShakeParams] | None = None,
        accept: Callable[[Tried], GraspCandidate | None] = lambda t: t[0],
    ) -> GraspCandidate | None:
        """The first of up to ``checks`` (candidate, model) pairs whose grasp holds under ``program`` (of the
        palm's orientation; by default ``hold_check`` with the budget's cycles) and that ``accept`` returns a grasp
        for (the candidate itself by default). The next checks (``worker_pool.workers()`` in all) run while one is
        awaited; the grasps and the budget left are those of checking one after another."""
        check = program or functools.partial(hold_check, cycles=self.cycles)
        queue = itertools.islice(candidates, checks)  # a lazy iterable is only drawn as far as checks are started
        window: collections.deque[tuple[Tried, Beside[ShakeResult]]] = collections.deque()
        found: GraspCandidate | None = None
        width = max(1, worker_pool.workers())
        while True:
            while len(window) < width and len(window) < self.left:
                tried = next(queue, None)
                if tried is None:
                    break
                grasp = grasp_from_candidate(tried[0])
                window.append((tried, Beside(shake_test, tried[1], grasp, check(np.asarray(grasp.wrist_orientation)))))
            if not window or self.spent():
                break
            tried, running = window.popleft()
            cand = tried[0]
            self.left -= 1
            result = running.result()
            self.seconds -= result.survived_s
            accepted = accept(tried) if result.holds else None
            firm = result.max_shift_m <= FIRM_SHIFT_M and result.max_turn_rad <= FIRM_TURN_RAD
            if accepted is not None and self.loose is not None and not firm:
                self.loose.append(accepted)
                continue
            if accepted is not None:
                found = accepted
                break
            if result.holds:
                self.unaccepted.append(cand)
            if result.survived_s > self.longest_s and rank_tier(cand.quality) == 0:
                self.longest, self.longest_s = cand, result.survived_s
        for _, running in window:  # checks started ahead that are not needed
            running.drop()
        return found


def squeezed(tried: Tried, mu: float) -> GraspCandidate | None:
    """A grasp without a static force closure that held under the hold check, with the qualities of its contacts
    once the fingers have squeezed it (``settle.settle``, friction ``mu``), or None when even then it
    shows no force closure."""
    cand, model = tried
    quality = settle(model, cand.position, cand.quat_xyzw, float(cand.closed[0]), mu).quality
    return dataclasses.replace(cand, quality=quality) if quality.force_closure else None


def closed_or_squeezed(tried: Tried, mu: float) -> GraspCandidate | None:
    """A grasp that held: as it is with a static force closure, else ``squeezed`` (None without one either way)."""
    return tried[0] if rank_tier(tried[0].quality) == 0 else squeezed(tried, mu)


def with_closure(candidates: Iterable[GraspCandidate], model: ObjectModel, mu: float) -> Iterator[Tried]:
    """The candidates with a force closure at friction ``mu``, static or squeezed (``closed_or_squeezed``), each with
    ``model``, found lazily: squeezing one (about 0.02 s CPU) costs less than checking one that holds without a
    force closure (6 s simulated, about 0.4 s CPU)."""
    for cand in candidates:
        closed = closed_or_squeezed((cand, model), mu)
        if closed is not None:
            yield closed, model


def held_closure(held: Iterable[GraspCandidate], model: ObjectModel) -> GraspCandidate | None:
    """The first of ``held`` (grasps that held under the hold check without a force closure, even squeezed, at the
    planner's friction) that shows one at the check's own friction ``HELD_MU`` (``with_closure``), its qualities at
    that friction (``GraspQuality.mu``); else None. A grasp that held through the check was held at that friction,
    so its force closure there is the consistent judgement of it."""
    return next((cand for cand, _ in with_closure(held, model, HELD_MU)), None)
