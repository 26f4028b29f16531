"""Grasp planning entry points used by the learn stage (``G`` of the descriptor, DESCRIPTOR.md).

The demonstrator's wrist tracker pose (world frame, metres, quaternion [x, y, z, w]) is turned into a seed palm
pose through the sensor-to-palm offset (``seed.py``). ``plan_on_model`` is the planner, one search:

1. every generator of ``generators.GENERATORS`` proposes states of one search space around the demonstrated palm
   (``planner.SearchSpace``; the annealing's best unique states among them);
2. each is executed as the robot executes a grasp (``execution.py``) and the grasps are ranked once: force closure
   first, then closeness to the demonstration (``rank``);
3. in that order, grasps that survive the wrist pose error of a robot (``execution.robust``: closed with the palm
   displaced by millimetres and degrees, the same fingers still reach the part) are
   shaken by the hold check (``hold_check``, on the planner's own object model) within
   one time budget (``PlannerParams.hold_checks`` whole checks of simulated time): the first that holds firmly with
   a force closure, static or once the fingers have squeezed it, is the plan (``choose``).

``Grasp.wrist_*`` is the pose of the hand base (palm) frame of ``barrett.py`` in the world, +z the approach
direction; ``Grasp.eigengrasps`` (a1, a2) is the posture the hand closes towards: execute by opening the hand at
spread 1.13 + a1 (fingers ``barrett.OPEN_FINGER_RAD``), moving the palm along +z to the wrist pose and closing the
fingers towards a2 (``barrett.CLOSE_AMPLITUDE``: fully) until they stop on the part, as ``tasks.simulate`` and the
scenes' truth grasps do. ``quality`` holds epsilon, volume, force_closure, the contact count, the friction ``mu``,
the closed DOFs ``closed_dofs`` [spread, f1, f2, f3] (radians), ``demo_offset_m`` / ``demo_angle_rad``: how far the
palm lies off the demonstrated approach, and (``plan_grasp``) ``planned_on``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from schemas.descriptor import Grasp
from tasks.arrays import FloatArray, Points, Vector3
from tasks.errors import GraspError
from tasks.grasp.candidate_grasp import grasp_from_candidate
from tasks.grasp.execution import GraspCandidate, execute_states, hand_and_object, robust
from tasks.grasp.generators import GENERATORS
from tasks.grasp.hold_check import CHECK_LENGTH_S, CHECK_SHIFT_M, CHECK_TURN_TOL_RAD, hold_check
from tasks.grasp.object_model import ObjectModel, build_object_model, check_object_points, crop_points
from tasks.grasp.planner import PlannerParams, search_space
from tasks.grasp.quality import GraspQuality, grasp_quality
from tasks.grasp.seed import (
    GRASPIT_TRACKER_OFFSET,
    PalmOffset,
    check_seed,
    palm_from_sensor,
    stillest_time_ns,
    wrist_pose_at,
)
from tasks.grasp.shake import ShakeResult, shake_test
from tasks.recording.load import PoseTrack

CROP_RADIUS_M = 0.15
"""Object points farther than this from the part nearest the seed palm are left out (the part to grasp)."""
HELD_MU = 0.8
"""Friction coefficient of the hold check's contacts: the part's 0.8 (``shake.ShakeParams.friction``) times the
finger pads' 1.0, as Bullet combines them: a grasp that held without a force closure at ``PlannerParams.mu`` is
judged at the friction it was held with."""
FIRM = 0.5
"""A grasp that held but let the part move or turn more than this fraction of the check's tolerances is kept back
while a firmer one may be found: slip that starts in a short check goes on in a longer one."""


def rank(cand: GraspCandidate) -> tuple[bool, float]:
    """The one ranking: force closure first, then closeness to the demonstration (``execution.closeness``)."""
    return not cand.quality.force_closure, cand.closeness


def plan_on_model(
    model: ObjectModel,
    seed_position: Vector3,
    seed_quat_xyzw: FloatArray,
    rng: np.random.Generator,
    params: PlannerParams | None = None,
) -> GraspCandidate:
    """The planned grasp on a built model from a palm seed (world): see the module docstring. Raises
    ``GraspError`` when no proposal can be executed (the open hand collides everywhere near the seed)."""
    pos, quat = check_seed(seed_position, seed_quat_xyzw)
    prm = params or PlannerParams()
    space = search_space(model, Rotation.from_quat(quat).as_matrix(), pos, prm)
    proposals = [p for generate in GENERATORS.values() for p in generate(model, space, prm, rng)]
    ranked = sorted(execute_states(model, space, proposals, prm), key=rank)
    if not ranked:
        msg = "no collision-free grasp found near the seed pose"
        raise GraspError(msg)
    return choose(model, ranked, prm)


def _squeezed(result: ShakeResult, model: ObjectModel, mu: float) -> GraspQuality:
    if result.squeezed_positions is None or result.squeezed_normals is None:
        return GraspQuality(0, mu=mu)
    return grasp_quality(result.squeezed_positions, result.squeezed_normals, model.center, model.radius, mu)


def choose(model: ObjectModel, ranked: list[GraspCandidate], params: PlannerParams) -> GraspCandidate:
    """The first of ``ranked`` that survives the wrist error (``execution.robust``) and holds firmly (``FIRM``) under
    ``hold_check`` with a force closure at ``params.mu``, static or squeezed (then with the squeezed quality), while
    the budget lasts (a check starts only while a whole one fits in the simulated time left); else the first that
    held loosely; else the first that held with a squeezed force closure at ``HELD_MU``; else the checked force
    closure that lasted longest; else the first force closure; else the first."""
    left = params.hold_checks * CHECK_LENGTH_S
    loose: list[GraspCandidate] = []
    held: list[GraspCandidate] = []
    longest: tuple[float, GraspCandidate] | None = None
    with hand_and_object(model) as ids:
        for cand in ranked:
            if left < CHECK_LENGTH_S:
                break
            if not robust(ids, model, cand, params.mu):
                continue  # a grasp that only holds at the exact planned pose is not a grasp
            result = shake_test(model, grasp_from_candidate(cand), hold_check(cand.quat_xyzw))
            left -= result.survived_s
            quality = cand.quality if cand.quality.force_closure else _squeezed(result, model, params.mu)
            if result.holds and quality.force_closure:
                chosen = dataclasses.replace(cand, quality=quality)
                if result.max_shift_m <= FIRM * CHECK_SHIFT_M and result.max_turn_rad <= FIRM * CHECK_TURN_TOL_RAD:
                    return chosen
                loose.append(chosen)
            elif result.holds:
                at_held = _squeezed(result, model, HELD_MU)
                if at_held.force_closure:
                    held.append(dataclasses.replace(cand, quality=at_held))
            if cand.quality.force_closure and (longest is None or result.survived_s > longest[0]):
                longest = (result.survived_s, cand)
    if loose or held:
        return (loose + held)[0]
    if longest is not None:
        return longest[1]
    return next((c for c in ranked if c.quality.force_closure), ranked[0])


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
