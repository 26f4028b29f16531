"""Executing a search state as the robot executes a grasp (pybullet, DIRECT): the hand open at the state's spread
(fingers ``barrett.OPEN_FINGER_RAD``, opened wider while they touch the object) at the state's palm pose (moved
back along the approach while in collision), approached up to 30 mm to contact, fingers closed until blocked
(``closing.py``); the grasp's epsilon and volume (``quality.py``) and where it lies from the demonstration."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Vector3
from tasks.grasp import closing
from tasks.grasp.object_model import ObjectModel, load_object
from tasks.grasp.planner import PlannerParams, SearchSpace
from tasks.grasp.quality import GraspQuality, grasp_quality
from tasks.hand import barrett

OPEN_MIN_RAD = barrett.OPEN_FINGER_RAD - 0.75
"""The fingers may open 0.75 rad wider than the pre-grasp when the open hand touches the object, as the simulated
robot does (``tasks.simulate.hand.WIDER_OPENINGS_RAD``)."""
PREGRASP_TOL_M = 0.004
"""An open pre-grasp may touch the object by up to 4 mm (a fingertip grazing the face behind a handle): the fingers
close away from it (``closing.close_fingers`` stops a finger only when blocked)."""
BACK_OFF_M = 0.02
BACK_OFF_STEP_M = 0.004
"""A pre-grasp in collision is moved back along its approach by up to 20 mm, in 4 mm steps (the scan's noise and
the hand's width)."""
WRIST_ERROR_M = 0.003
WRIST_ERROR_RAD = math.radians(2.0)
"""Wrist pose error a grasp must survive: an arm's inverse kinematics places the palm within 3 mm and 2° of the
plan, and a transferred object frame adds its axis uncertainty of a millimetre and a fraction of a degree."""
HOLDING_FINGERS = 2
"""Fingers that must touch the part: a hand holds a part between its fingers; the palm and one finger let it turn
about that finger when the arm moves it."""


@dataclass(frozen=True)
class Proposal:
    """A state to execute: who proposed it (``source``), the state x (8,), how far (m) the palm may approach to
    contact (0 for a fingertip grasp whose palm is to stay where it is)."""

    source: str
    state: FloatArray
    approach_m: float


@dataclass(frozen=True)
class GraspCandidate:
    """An executed state: the state x (8,), palm pose (world, after the approach), closed joints (7,) [spread,
    proximal 1-3, distal 1-3] rad, quality, ranking cost ``closeness``, offset (m) from the demonstrated approach
    and angle (rad) from the demonstrated palm, the generator that proposed it (``source``), and the fingers (0-2)
    that touch the part (``fingers``)."""

    state: FloatArray
    position: Vector3
    quat_xyzw: FloatArray
    closed: FloatArray
    quality: GraspQuality
    closeness: float
    offset_m: float
    angle_rad: float
    source: str = ""
    fingers: tuple[int, ...] = ()


def closeness(space: SearchSpace, rot: FloatArray, pos: Vector3, params: PlannerParams) -> tuple[float, float, float]:
    """(ranking cost, lateral offset m, angle rad) of a palm pose (world) from the demonstrated one: the offset from
    the demonstrated approach segment (the demonstrated palm moved on up to ``approach_max_m``, no further than the
    pivot), over 20 mm, plus the angle over 20°, plus the advance past the demonstrated palm over 50 mm or the
    distance behind it over 10 mm (``PlannerParams``)."""
    approach = space.seed_rot[:, 2]
    rel = np.asarray(pos) - space.seed_pos
    advance = float(rel @ approach)
    on_segment = float(np.clip(advance, 0.0, min(max(space.pivot_m, 0.0), params.approach_max_m)))
    lateral = float(np.linalg.norm(rel - on_segment * approach))
    angle = float(Rotation.from_matrix(space.seed_rot.T @ rot).magnitude())
    cost = (
        lateral / params.position_scale_m
        + angle / params.angle_scale_rad
        + max(advance, 0.0) / params.advance_scale_m
        + max(-advance, 0.0) / params.behind_scale_m
    )
    return cost, lateral, angle


def execute_pose(  # noqa: PLR0917 -- pybullet ids, model, pose, spread, params
    client: int,
    hand: int,
    obj: int,
    model: ObjectModel,
    rot: FloatArray,
    pos: Vector3,
    spread: float,
    approach_max_m: float,
    mu: float,
    back_off_m: float = BACK_OFF_M,
) -> tuple[Vector3, FloatArray, GraspQuality, tuple[int, ...]] | None:
    """Execute one grasp in a pybullet client holding the hand and the (static) object: the palm position after the
    approach, the closed joints (7,), the quality of the contacts on the part (not its mount) and the fingers (0-2)
    touching the part; None when the open hand is in collision even backed off (by at most ``back_off_m``)."""
    quat = Rotation.from_matrix(rot).as_quat()
    for back in np.arange(0.0, back_off_m + 1e-9, BACK_OFF_STEP_M):
        start = pos - back * rot[:, 2]
        closing.set_pose(client, hand, start, quat)
        dofs = closing.open_free(client, hand, obj, spread, OPEN_MIN_RAD, PREGRASP_TOL_M)
        if closing.min_distance(client, hand, obj) >= -PREGRASP_TOL_M:
            break
    else:
        return None
    final = closing.approach_to_contact(client, hand, obj, start, quat, approach_max_m)
    closed = closing.close_fingers(client, hand, obj, dofs)
    contacts = closing.contacts_of(client, hand, obj)
    on_part = ~model.is_mount_piece(contacts.pieces)  # a finger pressing the mount holds nothing of the part
    quality = grasp_quality(contacts.positions[on_part], contacts.normals_in[on_part], model.center, model.radius, mu)
    links = contacts.links[on_part]
    fingers = tuple(f for f, pair in enumerate(barrett.FINGER_LINKS) if np.any(np.isin(links, pair)))
    return final, closed, quality, fingers


@contextmanager
def hand_and_object(model: ObjectModel) -> Iterator[tuple[int, int, int]]:
    """A pybullet client (DIRECT) holding the object model (static) and the hand: (client, hand, object) ids."""
    client = pb.connect(pb.DIRECT)
    try:
        obj = load_object(client, model)
        yield client, barrett.load_hand(client), obj
    finally:
        pb.disconnect(client)


def execute_states(
    model: ObjectModel, space: SearchSpace, proposals: list[Proposal], params: PlannerParams
) -> list[GraspCandidate]:
    """Execute each proposal in one pybullet client (``execute_pose``), in order; those in collision are left out,
    and so are those that closed into the grasp of an earlier one (``distinct``)."""
    out: list[GraspCandidate] = []
    with hand_and_object(model) as (client, hand, obj):
        for prop in proposals:
            x = prop.state
            rot, pos = space.pose(x)
            spread = float(barrett.dofs_from_eigengrasps(float(x[0]), 0.0)[0])
            done = execute_pose(client, hand, obj, model, rot, pos, spread, prop.approach_m, params.mu)
            if done is None:
                continue
            final, closed, quality, fingers = done
            cost, lateral, angle = closeness(space, rot, final, params)
            quat = Rotation.from_matrix(rot).as_quat()
            out.append(
                GraspCandidate(x.copy(), final, quat, closed, quality, cost, lateral, angle, prop.source, fingers)
            )
    return distinct(out)


def displaced_poses(rot: FloatArray, pos: Vector3) -> list[tuple[FloatArray, Vector3]]:
    """The palm pose (rotation (3, 3), position (3,) m, world) moved ``WRIST_ERROR_M`` either way along each of
    its axes and turned ``WRIST_ERROR_RAD`` either way about each (through the palm origin): 12 poses."""
    out: list[tuple[FloatArray, Vector3]] = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            out.append((rot, np.asarray(pos, dtype=np.float64) + sign * WRIST_ERROR_M * rot[:, axis]))
            turn = Rotation.from_rotvec(sign * WRIST_ERROR_RAD * rot[:, axis]).as_matrix()
            out.append((turn @ rot, np.asarray(pos, dtype=np.float64)))
    return out


def robust(ids: tuple[int, int, int], model: ObjectModel, cand: GraspCandidate, mu: float) -> bool:
    """Whether ``cand``'s grasp survives the wrist error, tried in the client ``ids`` (``hand_and_object``): with
    the palm at each of ``displaced_poses`` instead of the planned pose (neither backed off nor approached: the arm
    puts the palm where it puts it), the open hand is not inside the object (``PREGRASP_TOL_M``, opened wider as
    ``execute_pose`` opens it) and, the fingers closed there, every finger that touched the part (at least
    ``HOLDING_FINGERS``) still touches it. Whether those contacts still make a force closure is not asked: a
    closure of three point contacts is a kinematic idealisation that a millimetre changes, and the squeezing fingers
    settle the part into the grasp again (the hold check squeezes); a finger that misses the part does not."""
    if len(cand.fingers) < HOLDING_FINGERS:
        return False
    client, hand, obj = ids
    spread = float(cand.closed[0])
    poses = displaced_poses(Rotation.from_quat(cand.quat_xyzw).as_matrix(), cand.position)
    for rot_d, pos_d in poses:  # the open hand alone first: cheap, and where a pose pressed into the part fails
        closing.set_pose(client, hand, pos_d, Rotation.from_matrix(rot_d).as_quat())
        closing.open_free(client, hand, obj, spread, OPEN_MIN_RAD, PREGRASP_TOL_M)
        if closing.min_distance(client, hand, obj) < -PREGRASP_TOL_M:
            return False
    for rot_d, pos_d in poses:
        done = execute_pose(client, hand, obj, model, rot_d, pos_d, spread, 0.0, mu, 0.0)
        if done is None or not set(cand.fingers) <= set(done[3]):
            return False
    return True


def distinct(candidates: list[GraspCandidate]) -> list[GraspCandidate]:
    """Drop candidates that closed into the same grasp as an earlier one (palm within 2 mm and 2°, joints within
    0.02 rad): different pre-grasps often end in one grasp."""
    kept: list[GraspCandidate] = []
    for cand in candidates:
        same = any(
            np.linalg.norm(cand.position - k.position) < 0.002
            and abs(float(np.dot(cand.quat_xyzw, k.quat_xyzw))) > math.cos(math.radians(1.0))
            and np.max(np.abs(cand.closed - k.closed)) < 0.02
            for k in kept
        )
        if not same:
            kept.append(cand)
    return kept
