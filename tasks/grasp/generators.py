"""Candidate generators: where the planner's states come from, registered in one place (``GENERATORS``).

Each generator maps (object model, search space, parameters, random generator) to ``Proposal`` s, states of the one
search space (``planner.SearchSpace``) to execute; ``tasks.grasp.api.plan_on_model`` executes them all and ranks
the grasps together. A generator proposes nothing where its mechanism does not apply.

- ``annealed``: the best unique states of simulated annealing under the contact energy (``planner.anneal``), a
  chain from the demonstrated palm per start spread: GraspIt!'s online eigengrasp planner.
- ``demonstrated``: the demonstrated palm itself, held back 20 mm and rolled ±15°, at three spreads: what the
  demonstrator did, which the energy does not always rank first.
- ``along the bar``: on a part with a bar (``ObjectModel.cylinder``), the demonstrated palm slid 25 or 50 mm either
  way along it: a bar is held anywhere along it, and the demonstrated place may be where a post or the fingers'
  sweep into the plate behind it gets in the way.
- ``pinch``: on a mounted part, the demonstrated palm held back 60-100 mm, rolled 0 or ±15°, the fingertips alone
  closing on the part: fingers curled round a bar reach 45 mm or more in front of the palm, so on a bar 20-50 mm
  before its plate they meet the plate and cannot squeeze; the open fingertips close 80-100 mm in front of it.
- ``square pinch``: on a part with a bar, the same pinch with the palm square to the bar (its approach at right
  angles to the axis): tilted fingertips meet a round bar at different heights and a squeeze rolls it out of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.grasp.execution import Proposal
from tasks.grasp.object_model import ObjectModel
from tasks.grasp.planner import BestList, PlannerParams, SearchSpace, anneal, state_energy
from tasks.hand import barrett

SPREADS_RAD = (0.0, 1.13, math.pi / 2)
"""Spreads of the demonstrated palm's proposals: the thumb opposite fingers 1 and 2, GraspIt!'s origin posture, and
fingers 1 and 2 face to face."""
TIP_SPREADS_RAD = (0.0, math.pi / 2)
"""Spreads of the fingertip proposals: three fingertips two against one, then two face to face."""
ROLLS_RAD = (0.0, math.radians(15.0), math.radians(-15.0))
"""Rolls about the demonstrated approach: a hand closes round a bar or a box at any roll within a few tens of
degrees of the demonstrated one."""
HOLD_BACK_M = 0.02
"""The demonstrated palm held back by about a finger's width, so the fingers close round the part, not on top."""
SLIDES_M = (0.025, 0.05)
"""Distances slid along a bar: a finger's width and two."""
TIP_DISTANCES_M = (0.06, 0.07, 0.08, 0.09, 0.10)
"""Palm distances from the part's surface at which the open fingertips (126 mm fingers on 50 mm knuckles) close on
a part 10-50 mm across."""
CHAIN_SPREADS = (-1.13, 0.0, 0.44, 2.0)
"""Start amplitude a1 of the annealing chains: spread 0, 1.13 (the origin), π/2 and π."""

Generator = Callable[[ObjectModel, SearchSpace, PlannerParams, np.random.Generator], list[Proposal]]


def _at(spread: float, d: float, roll: float = 0.0, u: float = 0.0, v: float = 0.0) -> np.ndarray:
    """The state of the open hand at ``spread`` (rad), ``d`` before the pivot, rolled, moved (u, v) across."""
    return np.array([barrett.spread_amplitude(spread), 0.0, d, roll, 0.0, 0.0, u, v])


def annealed(model: ObjectModel, space: SearchSpace, params: PlannerParams, rng: np.random.Generator) -> list[Proposal]:
    """The best unique states of ``params.chains`` annealing chains from the demonstrated palm."""
    best = BestList(params.candidates, space.upper - space.lower)
    d0 = float(np.clip(space.pivot_m, *params.distance_range_m))
    for a1 in CHAIN_SPREADS[: params.chains]:
        start = np.array([a1, -1.0, d0, 0.0, 0.0, 0.0, 0.0, 0.0])
        anneal(lambda x: state_energy(model, space, x), start, space, rng, params.steps, best, params.schedule)
    return [Proposal("annealed", x, params.approach_max_m) for _, x in best.states]


def demonstrated(
    model: ObjectModel, space: SearchSpace, params: PlannerParams, rng: np.random.Generator
) -> list[Proposal]:
    """The demonstrated palm, held back ``HOLD_BACK_M`` and rolled ``ROLLS_RAD``, at ``SPREADS_RAD``."""
    del model, rng
    return [
        Proposal("demonstrated", _at(spread, space.pivot_m + back, roll), params.approach_max_m)
        for back in (0.0, HOLD_BACK_M)
        for roll in ROLLS_RAD
        for spread in SPREADS_RAD
    ]


def _bar_axis(model: ObjectModel) -> np.ndarray | None:
    return None if model.cylinder is None else Rotation.from_quat(model.cylinder.quat_xyzw).apply([0.0, 0.0, 1.0])


def along_the_bar(
    model: ObjectModel, space: SearchSpace, params: PlannerParams, rng: np.random.Generator
) -> list[Proposal]:
    """The demonstrated palm slid ``SLIDES_M`` either way along the bar (its axis taken across the approach), at
    the pivot and held back, at ``TIP_SPREADS_RAD``, closed where it is; none when the bar points within 60° of the
    approach (sliding would move the palm onto the part)."""
    del rng, params
    axis = _bar_axis(model)
    if axis is None:
        return []
    u, v = float(axis @ space.seed_rot[:, 0]), float(axis @ space.seed_rot[:, 1])
    if math.hypot(u, v) < 0.5:
        return []
    u, v = u / math.hypot(u, v), v / math.hypot(u, v)
    return [
        Proposal("along the bar", _at(spread, space.pivot_m + back, 0.0, s * u, s * v), 0.0)
        for slide in SLIDES_M
        for s in (slide, -slide)
        for back in (0.0, HOLD_BACK_M)
        for spread in TIP_SPREADS_RAD
    ]


def pinch(model: ObjectModel, space: SearchSpace, params: PlannerParams, rng: np.random.Generator) -> list[Proposal]:
    """On a mounted part: the demonstrated palm held back ``TIP_DISTANCES_M`` from the pivot, rolled ``ROLLS_RAD``,
    at ``TIP_SPREADS_RAD``, closed where it is."""
    del rng, params, space
    if model.mount is None:
        return []
    return [
        Proposal("pinch", _at(spread, d, roll), 0.0)
        for roll in ROLLS_RAD
        for d in TIP_DISTANCES_M
        for spread in TIP_SPREADS_RAD
    ]


def square_pinch(
    model: ObjectModel, space: SearchSpace, params: PlannerParams, rng: np.random.Generator
) -> list[Proposal]:
    """On a part with a bar: palms square to the bar, +x along it, through its axis where it passes nearest the
    demonstrated palm, ``TIP_DISTANCES_M`` from its surface, at ``TIP_SPREADS_RAD``, closed where they are; those
    outside the search space left out."""
    del rng, params
    axis = _bar_axis(model)
    if axis is None or model.cylinder is None:
        return []
    approach = space.seed_rot[:, 2]
    square = approach - float(approach @ axis) * axis
    z = square / max(float(np.linalg.norm(square)), 1e-9)
    x = axis if float(axis @ space.seed_rot[:, 0]) >= 0.0 else -axis
    rot = np.stack([x, np.cross(z, x), z], axis=1)
    centre = np.asarray(model.cylinder.position, dtype=np.float64)
    half = float(model.cylinder.size[1])
    front = centre + float(np.clip((space.seed_pos - centre) @ axis, -half, half)) * axis - z * model.cylinder.size[0]
    states = [space.state(rot, front - z * d, spread) for spread in TIP_SPREADS_RAD for d in TIP_DISTANCES_M]
    return [Proposal("square pinch", s, 0.0) for s in states if space.inside(s)]


GENERATORS: dict[str, Generator] = {
    "demonstrated": demonstrated,
    "annealed": annealed,
    "along the bar": along_the_bar,
    "pinch": pinch,
    "square pinch": square_pinch,
}
"""Every generator, by name: ``tasks.grasp.api.plan_on_model`` executes the proposals of all of them."""
