"""Grasp planning entry points used by the learn stage (``G`` of the descriptor, DESCRIPTOR.md).

The seed is the demonstrator's wrist tracker pose (world frame, metres, quaternion [x, y, z, w]) at the stillest moment
before the first primitive, turned into a palm pose through the sensor-to-palm offset (``PalmOffset``).

``plan_on_model`` is the planner, one search (docs/grasp.md): every generator of ``planner.GENERATORS`` proposes
states of one search space around the demonstrated palm (``planner.SearchSpace``), each is executed as the robot
executes a grasp (``execution.py``), the grasps are ranked once (``rank``) and, in that order, those that survive a
robot's wrist error (``execution.robust``) are shaken by the hold check within one time budget (``choose``).

``Grasp.wrist_*`` is the palm (hand base) frame of ``barrett.py`` in the world, +z the approach; ``Grasp.eigengrasps``
(a1, a2) the posture the hand closes towards from the open hand at spread 1.13 + a1, as ``tasks.simulate`` executes it.
``quality``: epsilon, volume, force_closure, contacts, ``mu``, ``closed_dofs`` [spread, f1, f2, f3] (rad),
``demo_offset_m`` / ``demo_angle_rad`` from the demonstrated approach.
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
from tasks.grasp.execution import GraspCandidate, execute_states, grasp_from_candidate, hand_and_object, robust
from tasks.grasp.object_model import ObjectModel, build_object_model, check_object_points
from tasks.grasp.planner import GENERATORS, PlannerParams, search_space
from tasks.grasp.quality import GraspQuality, grasp_quality
from tasks.grasp.shake import CHECK_LENGTH_S, CHECK_SHIFT_M, CHECK_TURN_TOL_RAD, ShakeResult, hold_check, shake_test
from tasks.hand.tracker import GRASPIT_TRACKER_OFFSET, PalmOffset, palm_from_sensor, stillest_time_ns, wrist_pose_at
from tasks.recording.load import PoseTrack


def check_seed(seed_position: object, seed_quat_xyzw: object) -> tuple[Vector3, FloatArray]:
    """The seed palm pose as a position (3,) m and a unit quaternion [x, y, z, w] (world); ``GraspError`` naming
    what is wrong when it is not one."""
    pos = np.asarray(seed_position, dtype=np.float64)
    quat = np.asarray(seed_quat_xyzw, dtype=np.float64)
    if pos.shape != (3,) or quat.shape != (4,):
        msg = f"seed pose: expected position (3,) and quaternion (4,), got {pos.shape} and {quat.shape}"
        raise GraspError(msg)
    if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(quat))):
        msg = f"seed pose is not finite: position {pos.tolist()}, quaternion {quat.tolist()}"
        raise GraspError(msg)
    norm = float(np.linalg.norm(quat))
    if norm < 1e-6:
        msg = f"seed quaternion has zero length: {quat.tolist()}"
        raise GraspError(msg)
    return pos, quat / norm


CROP_RADIUS_M = 0.15
"""Object points farther than this from the part nearest the seed palm are left out (the part to grasp)."""
FIRM = 0.5
"""A grasp that held but let the part move or turn more than this fraction of the check's tolerances is kept back
while a firmer one may be found: slip that starts in a short check goes on in a longer one."""


def rank(cand: GraspCandidate) -> tuple[bool, float]:
    """The one ranking: force closure first, then closeness to the demonstration (``execution.closeness``)."""
    return not cand.quality.force_closure, cand.closeness


def ranked_grasps(
    model: ObjectModel, seed_pos: Vector3, seed_quat_xyzw: FloatArray, rng: np.random.Generator, params: PlannerParams
) -> list[GraspCandidate]:
    """Every generator's proposals about a palm seed (world) executed and ranked (``rank``): what ``choose`` takes."""
    pos, quat = check_seed(seed_pos, seed_quat_xyzw)
    space = search_space(model, Rotation.from_quat(quat).as_matrix(), pos, params)
    proposals = [p for generate in GENERATORS.values() for p in generate(model, space, params, rng)]
    return sorted(execute_states(model, space, proposals, params), key=rank)


def plan_on_model(
    model: ObjectModel,
    seed_position: Vector3,
    seed_quat_xyzw: FloatArray,
    rng: np.random.Generator,
    params: PlannerParams | None = None,
) -> GraspCandidate:
    """The planned grasp on a built model from a palm seed (world): see the module docstring. Raises
    ``GraspError`` when no proposal can be executed (the open hand collides everywhere near the seed)."""
    prm = params or PlannerParams()
    ranked = ranked_grasps(model, seed_position, seed_quat_xyzw, rng, prm)
    if not ranked:
        msg = "no collision-free grasp found near the seed pose"
        raise GraspError(msg)
    return choose(model, ranked, prm)


def check_hold(model: ObjectModel, cand: GraspCandidate, mu: float) -> tuple[ShakeResult, GraspQuality]:
    """``hold_check`` of ``cand`` on ``model`` and the grasp's quality at friction ``mu``: its own when a force
    closure, else that of the contacts once the fingers have squeezed the part."""
    result = shake_test(model, grasp_from_candidate(cand), hold_check(cand.quat_xyzw))
    if cand.quality.force_closure:
        return result, cand.quality
    return result, grasp_quality(result.squeezed_positions, result.squeezed_normals, model.center, model.radius, mu)


def firm(result: ShakeResult) -> bool:
    """Whether a hold check's part moved and turned at most ``FIRM`` of its tolerances."""
    return result.max_shift_m <= FIRM * CHECK_SHIFT_M and result.max_turn_rad <= FIRM * CHECK_TURN_TOL_RAD


def choose(model: ObjectModel, ranked: list[GraspCandidate], params: PlannerParams) -> GraspCandidate:
    """The first of ``ranked`` that survives the wrist error (``execution.robust``) and holds firmly (``FIRM``) under
    ``hold_check`` with a force closure at ``params.mu``, static or squeezed (then with the squeezed quality), while
    the budget lasts (a check starts only while a whole one fits in the simulated time left); else the first that
    held; else the first force closure; else the first."""
    left = params.hold_checks * CHECK_LENGTH_S
    held: list[GraspCandidate] = []
    with hand_and_object(model) as ids:
        for cand in ranked:
            if left < CHECK_LENGTH_S:
                break
            if not robust(ids, model, cand, params.mu):
                continue  # a grasp that only holds at the exact planned pose is not a grasp
            result, quality = check_hold(model, cand, params.mu)
            left -= result.survived_s
            if result.holds and quality.force_closure:
                held.append(dataclasses.replace(cand, quality=quality))
                if firm(result):
                    return held[-1]
    return held[0] if held else next((c for c in ranked if c.quality.force_closure), ranked[0])


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
    return grasp_from_candidate(plan_on_model(model, seed_position, seed_quat_xyzw, rng, params))


def part_near(points: Points, palm_position: Vector3, radius_m: float = CROP_RADIUS_M) -> Points:
    """The object points within ``radius_m`` of the point nearest the palm (the part the hand reaches for)."""
    nearest = points[int(np.argmin(np.linalg.norm(points - palm_position, axis=1)))]
    part = points[np.linalg.norm(points - nearest, axis=1) <= radius_m]
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
    if t_seed_s is not None and not math.isfinite(t_seed_s):
        msg = f"seed time is not finite: {t_seed_s}"
        raise GraspError(msg)
    if wrist is not None:
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
