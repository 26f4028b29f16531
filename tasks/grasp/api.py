"""Grasp planning entry points used by the learn stage (``G`` of the descriptor, DESCRIPTOR.md).

The demonstrator's wrist tracker pose (world frame, metres, quaternion [x, y, z, w]) is turned into a seed palm
pose through the sensor-to-palm offset; the planner (``planner.py``) searches Barrett eigengrasp amplitudes and
a palm pose near it and returns a force-closure grasp near the demonstration: of the settled wraps
(``settle.settled_wraps``) and then the closest, the first that holds the part under the planner's hold check on
its own object model (``hold_check``; the mount the part stands on, ``mount.py``, an obstacle but not the free
body), else the one that lasted longest. ``Grasp.wrist_*`` is the pose of the hand base (palm) frame
of ``barrett.py`` in the world, +z the approach direction; ``Grasp.eigengrasps`` (a1, a2) is the posture the hand
closes towards: execute by opening the hand at spread 1.13 + a1 (fingers ``barrett.OPEN_FINGER_RAD``), moving the
palm along +z to the wrist pose and closing the fingers towards a2 (``barrett.CLOSE_AMPLITUDE``: fully) until they
stop on the part, as ``tasks.simulate`` and the scenes' truth grasps do. ``quality`` holds epsilon, volume,
force_closure, the contact count, the closed DOFs ``closed_dofs`` [spread, f1, f2, f3] (radians) found in
planning, ``demo_offset_m`` / ``demo_angle_rad``: how far the palm lies off the demonstrated approach, and
(``plan_grasp``) ``planned_on``: the fitted box or cylinder, a mounted part's cylinder or a cap's and convex
pieces, or the convex pieces the grasp was planned on.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from schemas.descriptor import Grasp
from tasks.arrays import FloatArray, Points, Vector3
from tasks.errors import GraspError
from tasks.grasp.bar_pinch import square_pinches
from tasks.grasp.candidate_grasp import grasp_from_candidate
from tasks.grasp.hold_budget import HoldBudget, Tried, closed_or_squeezed, held_closure, squeezed, with_closure
from tasks.grasp.hold_check import (
    CHECK_CYCLES,
    PRIMITIVE_CHECK_CYCLES,
)
from tasks.grasp.object_model import ObjectModel, build_object_model, check_object_points, crop_points
from tasks.grasp.pinch import ROLLED_PINCH_RAD, pinch_candidates, pinch_neighbours
from tasks.grasp.planner import GraspCandidate, PlannerParams, rank_tier, search
from tasks.grasp.seed import (
    GRASPIT_TRACKER_OFFSET,
    PalmOffset,
    check_seed,
    palm_from_sensor,
    stillest_time_ns,
    wrist_pose_at,
)
from tasks.grasp.settle import LATE_WRAP_SETTLES, WRAP_SETTLES, settled_wraps
from tasks.grasp.shake import QUICK_SHAKE
from tasks.grasp.slide import slide_candidates
from tasks.recording.load import PoseTrack

CROP_RADIUS_M = 0.15
"""Object points farther than this from the part nearest the seed palm are left out (the part to grasp)."""
SHAKE_CHECKS = 5
"""Force-closure candidates near the demonstration (in rank order) given the quick shake test."""
FALLBACK_CHECKS = 5
"""Further candidates given the quick shake test when none of those holds (reached ones, then the rest)."""
ROUNDS = 2
"""Annealing rounds tried while no near force closure holds (the second on the model's pieces drawn anew). On a part
with a bar or a mount, the grasps slid along the bar and the pinches (``_slid``, ``_pinch``) are checked before the
second round and the redraws: where a bar's plate or a lever's leaf stops fingers wrapping from near the
demonstrated palm, another annealing round near that palm (1.5-4 s a plan) meets the same obstacle, while a slid
grasp or a pinch avoids it."""
REDRAWS = 4
"""Then rounds of the demonstrated approach's poses alone (no annealing, about 0.2 s each), each on pieces drawn
anew: which of them close into force closure on a scan depends on how its convex pieces fall."""
DYNAMIC_CHECKS = 24
"""On a part with a mount (a handle or a lever) or a fitted box or cylinder, when none of the first round's force
closures holds: up to this many more hold checks, with a budget of their own (``hold_budget.CHECK_BUDGET_S``; most fail
within 0.1 s simulated), of its near grasps without a static force closure. Closed on a static model the fingers push a
bar away from the palm and touch it on one side; squeezing, they hold it (``squeezed``): a lever grasp may show
epsilon 0 closed statically and a force closure once squeezed. Not run on the convex pieces of a part without a
mount: there the squeezed closures it finds do not carry over to the real surface, and the pass lengthens a plan
by seconds; on a fitted primitive it runs, with checks of ``PRIMITIVE_CHECK_CYCLES``."""
PINCH_CHECKS = 10
"""When no grasp near the demonstration holds: hold checks of fingertip pinches held back on the demonstrated
approach (``pinch.py``), with a budget of their own; a pinch without a static force closure is kept when it shows
one once squeezed (``squeezed``). On a handle standing 18-30 mm in front of its plate, fingers wrapping the bar
from near the demonstrated palm meet the plate before they squeeze; a palm held back 70-90 mm reaches the bar with
the fingertips, clear of the plate (``pinch.py``)."""
SLIDE_CHECKS = 16
"""On a mounted part whose bar was found (``ObjectModel.cylinder``), when no grasp near the demonstration holds it
firmly: hold checks, with a budget of their own, of the grasps slid along the bar (``slide.py``; most fail within
0.1 s simulated), before the firm pinches and the loose near grasp."""
ROLLED_PINCH_CHECKS = 6
"""When no pinch of the demonstrated palm nor any of its neighbours holds with a force closure: hold checks of the
pinches rolled ``pinch.ROLLED_PINCH_RAD``, only of those with a force closure (static or squeezed, about 0.02 s CPU
each to find), with a budget of their own."""
SQUARE_PINCH_CHECKS = 6
"""Hold checks of the pinches square to the part's bar (``bar_pinch.square_pinches``), only of those with a force
closure, with a budget of their own, before the pinches of the demonstrated palm's orientation: a demonstrated palm
is commonly tilted and rolled 10-30° off the bar's square, and tilted fingertips meet a round bar at different
heights, so a squeeze rolls it out of them; square to the bar they close on its sides at its widest."""
NEIGHBOUR_CHECKS = 8
"""When a pinch held without a force closure: hold checks of its neighbours (``pinch.pinch_neighbours``), with a
budget of their own."""
SHAKE_BUDGET = 6
"""Hold checks one plan may run on near force closures (``FALLBACK_CHECKS`` more after them), within
``hold_budget.CHECK_BUDGET_S`` simulated seconds of shaking."""
CHECK_MAX_ANGLE_RAD = math.radians(15.5)
"""Only near force closures turned at most 15° from the demonstrated palm (the demonstrated approach's rolls,
``planner.LINE_POSES``) are checked and chosen for holding: a grasp turned further from the demonstrated palm
can hold under the check on the planner's model and close on nothing in execution (a thin bar handle)."""


def redecomposed(model: ObjectModel, rng: np.random.Generator) -> ObjectModel:
    """The model with its convex pieces drawn anew (``ObjectModel.with_pieces``: k-means from ``rng``, the part's
    and the mount's apart); a primitive model as it is. Which
    grasps close into force closure on a scan depends on how its pieces fall (the door's lever: near force
    closures with some draws, none with others)."""
    return model.with_pieces(rng)


def _slid(  # noqa: PLR0917 -- model, seed pose, params, two sinks
    model: ObjectModel,
    seed_rot: FloatArray,
    seed_pos: Vector3,
    prm: PlannerParams,
    loose: list[GraspCandidate],
    held: list[GraspCandidate],
) -> GraspCandidate | None:
    """The first grasp slid along the part's bar that holds firmly with a force closure (static or squeezed); the
    ones that hold loosely are added to ``loose``, those that hold without a force closure to ``held``."""
    found = ((c, model) for c in slide_candidates(model, seed_rot, seed_pos, prm))
    budget = HoldBudget(SLIDE_CHECKS, loose=loose)
    slid = budget.first_that_holds(found, SLIDE_CHECKS, accept=functools.partial(closed_or_squeezed, mu=prm.mu))
    held += budget.unaccepted
    return slid


def _pinch(
    model: ObjectModel,
    seed_rot: FloatArray,
    seed_pos: Vector3,
    prm: PlannerParams,
    held: list[GraspCandidate],
    *,
    loose: list[GraspCandidate] | None = None,
) -> GraspCandidate | None:
    """The first fingertip pinch square to the part's bar (``bar_pinch.square_pinches``, of those with a force
    closure, static or squeezed) that holds under ``hold_check``; then the first pinch of the demonstrated palm's
    orientation (``pinch.pinch_candidates``) that holds with a force closure, static or squeezed; when one held
    without any, the first of its neighbours (``pinch.pinch_neighbours``) that
    does; then the first of the pinches rolled ``pinch.ROLLED_PINCH_RAD`` that does; else None. The pinches that
    held without a force closure are added to ``held``; when ``loose`` is given, only a firm pinch is returned
    (``hold_budget.FIRM_SHIFT_M``) and the loose ones are added to it."""

    square = square_pinches(model, seed_rot, seed_pos, prm)
    square_budget = HoldBudget(SQUARE_PINCH_CHECKS, loose=loose)
    squared = square_budget.first_that_holds(with_closure(square, model, prm.mu), SQUARE_PINCH_CHECKS)
    if squared is not None:
        return squared
    closed = functools.partial(closed_or_squeezed, mu=prm.mu)
    budget = HoldBudget(PINCH_CHECKS, loose=loose)
    found = pinch_candidates(model, seed_rot, seed_pos, prm)
    pinched = budget.first_that_holds([(c, model) for c in found], PINCH_CHECKS, accept=closed)
    held += budget.unaccepted
    if pinched is not None:
        return pinched
    if budget.unaccepted:
        near = pinch_neighbours(model, seed_rot, seed_pos, prm, budget.unaccepted[0])
        neighbours = HoldBudget(NEIGHBOUR_CHECKS, loose=loose)
        neighbour = neighbours.first_that_holds(with_closure(near, model, prm.mu), NEIGHBOUR_CHECKS)
        if neighbour is not None:
            return neighbour
    rolled = pinch_candidates(model, seed_rot, seed_pos, prm, rolls_rad=ROLLED_PINCH_RAD)
    rolled_budget = HoldBudget(ROLLED_PINCH_CHECKS, loose=loose)
    return rolled_budget.first_that_holds(with_closure(rolled, model, prm.mu), ROLLED_PINCH_CHECKS)


def plan_on_model(
    model: ObjectModel,
    seed_position: Vector3,
    seed_quat_xyzw: FloatArray,
    rng: np.random.Generator,
    params: PlannerParams | None = None,
    *,
    shake_checks: int = SHAKE_CHECKS,
) -> GraspCandidate:
    """Best candidate on a built model from a palm seed: the first that holds under ``hold_check`` (three cycles,
    ``PRIMITIVE_CHECK_CYCLES``, on a fitted primitive) of the first round's settled wraps (``settle.settled_wraps``),
    then the force-closure grasps near the demonstration in order of closeness (up to ``shake_checks`` a round,
    ``SHAKE_BUDGET`` and ``hold_budget.CHECK_BUDGET_S`` in all; when none of the first round's holds, the wraps of its
    4th to 10th closest grasps, ``settle.LATE_WRAP_SETTLES``; while none holds and a whole check still fits, ``ROUNDS``
    annealing rounds then ``REDRAWS`` rounds of the demonstrated approach's poses, each after the first on the model's
    pieces drawn anew, ``redecomposed``; on a mounted part, after the first round, its near grasps without a static
    force closure that hold and show one once squeezed, ``DYNAMIC_CHECKS``, and so on a fitted primitive; on a part
    with a bar, the grasps slid along it, ``_slid``, and on a mounted part the fingertip pinches (square to its bar
    first), ``_pinch``, both checked after the first round and before the second (``ROUNDS``); on a part planned on its
    bar, a grasp that held loosely, ``hold_budget.FIRM_SHIFT_M``, is kept back for the later passes and returned when
    none of them holds firmly); then the first grasp that held
    without a force closure at ``params.mu`` whose squeezed contacts show one at the hold check's friction,
    ``hold_budget.held_closure``. When none holds: the checked force closure that lasted longest, else the first near
    force closure. Without any near force closure (nothing within reach of the demonstrated palm), up to
    ``FALLBACK_CHECKS`` under ``QUICK_SHAKE`` of: the force closures reached further along the demonstrated approach,
    the other near grasps, the other reached ones; when none holds, the first reached force closure, else the closest
    grasp near the demonstration (force_closure False: a distant grasp would not be the demonstrated one), else the
    closest."""
    pos, quat = check_seed(seed_position, seed_quat_xyzw)
    seed_rot = Rotation.from_quat(quat).as_matrix()
    # a fitted primitive is cheap to shake: three cycles, so slow slip shows before it is chosen
    loose: list[GraspCandidate] = []
    kept_back = loose if model.cylinder is not None else None  # a round bar may roll out of a grasp that held 6 s
    budget = HoldBudget(
        SHAKE_BUDGET, cycles=CHECK_CYCLES if model.primitive is None else PRIMITIVE_CHECK_CYCLES, loose=kept_back
    )
    tried: list[Tried] = []
    closure: list[Tried] = []
    without_closure: list[GraspCandidate] = []  # held under the check, no force closure at prm.mu even squeezed
    prm = params or PlannerParams()
    bar_or_mount = model.cylinder is not None or model.mount is not None
    passed = False  # the passes away from the demonstrated grasp (slid along the bar, pinches) have run

    def passes() -> GraspCandidate | None:
        """The first firm grasp slid along the bar, else the first pinch that holds (``_slid``, ``_pinch``)."""
        nonlocal passed
        passed = True
        if model.cylinder is not None:  # a bar: held anywhere along it
            slid = _slid(model, seed_rot, pos, prm, loose, without_closure)
            if slid is not None:
                return slid
        if model.mount is not None:  # a handle or lever whose mount may stop the fingers wrapping it
            # with a loosely held grasp in hand, only a firm pinch is taken over it
            return _pinch(model, seed_rot, pos, prm, without_closure, loose=[] if loose else None)
        return None

    for k in range(ROUNDS + REDRAWS):
        if k == 1 and bar_or_mount:  # before searching the demonstration's neighbourhood again (``ROUNDS``)
            moved = passes()
            if moved is not None:
                return moved
        if k == ROUNDS and not tried:
            break  # the hand fits nowhere near the seed: redrawing the pieces would only find grazing pockets
        variant = model if k == 0 else redecomposed(model, rng)
        round_prm = prm if k < ROUNDS else dataclasses.replace(prm, chains=0)
        found = [(c, variant) for c in search(variant, seed_rot, pos, rng, round_prm)]
        tried += found
        new = [t for t in found if t[0].near and rank_tier(t[0].quality) == 0]
        wraps_of = functools.partial(
            settled_wraps,
            [c for c, _ in found],
            variant,
            pos,
            seed_rot,
            prm.near_position_m,
            CHECK_MAX_ANGLE_RAD,
            mu=prm.mu,
        )
        if k == 0:  # wraps the static closing misses: fingers that pull the part into the palm
            new = [(c, variant) for c in wraps_of()] + new  # a palm-on-part wrap first: it held where fingertips slid
        closure += new
        held = budget.first_that_holds([t for t in new if t[0].angle_rad <= CHECK_MAX_ANGLE_RAD], shake_checks)
        if held is None and k == 0 and not budget.spent():  # wraps from grasps further from the demonstration
            late = wraps_of(count=LATE_WRAP_SETTLES, skip=WRAP_SETTLES)
            closure += [(c, variant) for c in late]
            held = budget.first_that_holds([(c, variant) for c in late], shake_checks)
        if held is None and k == 0 and (variant.mount is not None or variant.primitive is not None):
            dynamic = [
                t for t in found if t[0].near and rank_tier(t[0].quality) != 0 and t[0].angle_rad <= CHECK_MAX_ANGLE_RAD
            ]
            extra = HoldBudget(DYNAMIC_CHECKS, cycles=budget.cycles, loose=kept_back)  # most fail within 0.1 s
            held = extra.first_that_holds(dynamic, DYNAMIC_CHECKS, accept=lambda t: squeezed(t, prm.mu))
            without_closure += extra.unaccepted
        if held is not None:
            return held
        if closure and budget.spent():
            break
    if not passed:
        moved = passes()
        if moved is not None:
            return moved
    if loose:  # the grasp that held loosely, when nothing held firmly
        return loose[0]
    held_fc = held_closure(without_closure, model)  # a grasp that held, in force closure at the check's friction
    if held_fc is not None:
        return held_fc
    if not tried:
        msg = "no collision-free grasp found near the seed pose"
        raise GraspError(msg)

    def ordered(keep: Callable[[GraspCandidate], bool]) -> list[Tried]:
        return sorted((t for t in tried if keep(t[0])), key=lambda t: t[0].closeness)

    if closure:
        return budget.longest or closure[0][0]
    budget = HoldBudget(FALLBACK_CHECKS, math.inf)  # quick checks, as many as FALLBACK_CHECKS
    others = ordered(lambda c: c.near and rank_tier(c.quality) != 0)
    reached = ordered(lambda c: c.reach and not c.near and rank_tier(c.quality) == 0)
    further = ordered(lambda c: c.reach and not c.near and rank_tier(c.quality) != 0)
    held = budget.first_that_holds(reached + others + further, FALLBACK_CHECKS, lambda _: QUICK_SHAKE)
    if held is not None:
        return held
    if reached:
        return reached[0][0]
    return min((t[0] for t in tried), key=lambda c: (not c.near, c.closeness, rank_tier(c.quality)))


def plan_grasp(
    object_points: Points,
    seed_position: Vector3,
    seed_quat_xyzw: npt.NDArray[np.float64],
    rng: np.random.Generator,
    *,
    params: PlannerParams | None = None,
) -> Grasp:
    """Plan a Barrett grasp on ``object_points`` (n, 3) (world, metres) near a seed **palm** pose (the hand base
    frame, world; +z approach); the mount behind the part is looked for along that approach.
    ``quality["force_closure"]`` is false only when no force-closure grasp was found."""
    pos, quat = check_seed(seed_position, seed_quat_xyzw)
    approach = Rotation.from_quat(quat).as_matrix()[:, 2]
    model = build_object_model(object_points, rng, viewpoint=pos, approach=approach)
    grasp = grasp_from_candidate(plan_on_model(model, seed_position, seed_quat_xyzw, rng, params))
    return dataclasses.replace(grasp, quality={**grasp.quality, "planned_on": planned_on(model)})


def planned_on(model: ObjectModel) -> str:
    """What a grasp was planned on: ``"box"`` or ``"cylinder"`` (a primitive fitted to the points), ``"cylinder
    and convex pieces"`` (a mounted part's bar, ``part_cylinders``, the rest of it and its mount in pieces), ``"cap
    and convex pieces"`` (a cap's cylinder, ``tasks.grasp.cap``, its mount in pieces), else ``"convex pieces"`` (of
    the points; the part's and its mount's when a mount was found)."""
    if model.primitive is not None:
        return model.primitive.kind
    if model.cap is not None:
        return "cap and convex pieces"
    return "cylinder and convex pieces" if model.cylinder is not None else "convex pieces"


def part_near(points: Points, palm_position: Vector3, radius_m: float = CROP_RADIUS_M) -> Points:
    """The object points within ``radius_m`` of the point nearest the palm (the part the hand reaches for)."""
    nearest = points[int(np.argmin(np.linalg.norm(points - palm_position, axis=1)))]
    part = crop_points(points, nearest, radius_m)
    return part if len(part) >= 30 else points


def plan_grasp_for_recording(
    object_points: Points | None,
    wrist: PoseTrack | None,
    t_seed_s: float | None,
    start_ns: int,
    rng: np.random.Generator,
    *,
    offset: PalmOffset = GRASPIT_TRACKER_OFFSET,
    params: PlannerParams | None = None,
) -> Grasp | None:
    """Plan the grasp of a recording: None without an object model. The seed is the wrist tracker pose at the
    stillest moment of the second before ``start_ns + t_seed_s`` (the track's first sample when None) through
    ``offset``; without a wrist track the
    seed looks down at the object's top from 10 cm above it. Only the part near the seed is grasped."""
    if object_points is None:
        return None
    points = check_object_points(object_points)
    if wrist is not None:
        if t_seed_s is not None and not math.isfinite(t_seed_s):
            msg = f"seed time is not finite: {t_seed_s}"
            raise GraspError(msg)
        if t_seed_s is not None:
            stamp = stillest_time_ns(wrist, start_ns + round(t_seed_s * 1e9))
        else:
            stamp = int(wrist.stamps_ns[0]) if len(wrist.stamps_ns) else start_ns
        sensor_pos, sensor_quat = wrist_pose_at(wrist, stamp)
        palm_pos, palm_quat = palm_from_sensor(sensor_pos, sensor_quat, offset)
    else:
        top = points[np.argmax(points[:, 2])]
        palm_pos = np.array([points[:, 0].mean(), points[:, 1].mean(), top[2] + 0.10])
        palm_quat = Rotation.from_euler("x", math.pi).as_quat()
    part = part_near(points, palm_pos)
    return plan_grasp(part, palm_pos, palm_quat, rng, params=params)
