"""Executing a grasp as the robot executes it (pybullet, DIRECT): GraspIt!'s approachToContact and autoGrasp, and a
search state's execution (the open hand at the state's palm pose, moved back while in collision, approached to
contact, fingers closed until blocked) with its quality (``quality.py``), its distance from the demonstration and its
robustness to a robot's wrist error.

The hand is moved and its joints are reset (no dynamics); contact means a pybullet closest distance below
``CONTACT_M``. Fingers close one at a time in small steps with bisection to the first contact; when the proximal link
stops first, the distal link keeps closing alone (the BH8's breakaway), otherwise it stays coupled.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial

import numpy as np
import numpy.typing as npt
import pybullet as pb
from scipy.spatial.transform import Rotation

from schemas.descriptor import Grasp
from tasks.arrays import FloatArray, Points, Vector3
from tasks.grasp.object_model import ObjectModel, load_object
from tasks.grasp.planner import PlannerParams, Proposal, SearchSpace
from tasks.grasp.quality import GraspQuality, grasp_quality
from tasks.hand import barrett

CONTACT_M = 0.001
"""A link touches the object when its closest distance is below 1 mm."""
PENETRATION_M = -0.002
"""A pose is illegal when any link is more than 2 mm inside the object."""
CLOSE_STEP_RAD = 0.06
BISECT_ITERS = 5


@dataclass(frozen=True)
class Contacts:
    """Contacts of a closed hand: ``positions`` (m, 3) on the object, world metres; ``normals_in`` (m, 3)
    unit, into the object; ``links`` (m,) hand link index (-1 = palm); ``pieces`` (m,) the object's convex piece
    touched (its index in ``ObjectModel.parts``; 0 for a primitive)."""

    positions: Points
    normals_in: Points
    links: npt.NDArray[np.int64]
    pieces: npt.NDArray[np.int64]


def set_pose(client_id: int, hand: int, position: npt.ArrayLike, quat_xyzw: npt.ArrayLike) -> None:
    """Place the hand's palm frame at a world pose (metres, [x, y, z, w])."""
    pos = [float(v) for v in np.asarray(position, dtype=np.float64)]
    quat = [float(v) for v in np.asarray(quat_xyzw, dtype=np.float64)]
    pb.resetBasePositionAndOrientation(hand, pos, quat, physicsClientId=client_id)


def min_distance(client_id: int, hand: int, obj: int, within: float = 0.05) -> float:
    """Smallest signed distance (m) between the hand and the object, capped at ``within``."""
    return float(min((p[8] for p in pb.getClosestPoints(hand, obj, within, physicsClientId=client_id)), default=within))


def approach_to_contact(  # noqa: PLR0917 -- pybullet ids then the pose, as in pybullet's own API
    client_id: int, hand: int, obj: int, position: FloatArray, quat_xyzw: FloatArray, max_m: float = 0.03
) -> FloatArray:
    """Move the palm along its approach axis (+z) until the hand touches the object or ``max_m``; new position."""
    rot = np.array(pb.getMatrixFromQuaternion([float(v) for v in quat_xyzw])).reshape(3, 3)
    approach = rot[:, 2]
    step = 0.002
    moved = 0.0
    pos = np.asarray(position, dtype=np.float64).copy()
    while moved < max_m - 1e-9:
        trial = pos + step * approach
        set_pose(client_id, hand, trial, quat_xyzw)
        if min_distance(client_id, hand, obj) < CONTACT_M:
            break
        pos = trial
        moved += step
    set_pose(client_id, hand, pos, quat_xyzw)
    return pos


def _pair_distances(client_id: int, hand: int, obj: int, links: tuple[int, ...]) -> dict[tuple[int, int], float]:
    """Closest distance (m, within 10 mm) of each (hand link, object piece) pair of ``links``."""
    out: dict[tuple[int, int], float] = {}
    for link in links:
        for p in pb.getClosestPoints(hand, obj, 0.01, linkIndexA=link, physicsClientId=client_id):
            key = (int(p[3]), int(p[4]))
            out[key] = min(out.get(key, 1.0), float(p[8]))
    return out


def _blocked(before: dict[tuple[int, int], float], after: dict[tuple[int, int], float]) -> bool:
    """Whether a move pressed a link into a piece: a pair touching after it that came closer (a finger touching
    the face behind a handle while it closes away from it is not blocked: the BH8 slides on)."""
    return any(d < CONTACT_M and d < before.get(key, 1.0) - 1e-4 for key, d in after.items())


def _close_joint(  # noqa: PLR0917 -- private helper
    client_id: int,
    hand: int,
    obj: int,
    start: float,
    stop: float,
    set_angle: Callable[[float], None],
    links: tuple[int, ...],
) -> float:
    """Increase one angle from ``start`` to ``stop`` until ``links`` are blocked (pressed into the object, not
    merely touching it while moving away: ``_blocked``); returns the angle."""
    prev = angle = start
    set_angle(start)
    before = _pair_distances(client_id, hand, obj, links)
    while angle < stop - 1e-9:
        angle = min(angle + CLOSE_STEP_RAD, stop)
        set_angle(angle)
        after = _pair_distances(client_id, hand, obj, links)
        if _blocked(before, after):
            lo, hi = prev, angle
            for _ in range(BISECT_ITERS):
                mid = 0.5 * (lo + hi)
                set_angle(mid)
                if _blocked(before, _pair_distances(client_id, hand, obj, links)):
                    hi = mid
                else:
                    lo = mid
            set_angle(lo)
            return lo
        prev, before = angle, after
    return angle


def close_fingers(client_id: int, hand: int, obj: int, dofs: npt.ArrayLike) -> FloatArray:
    """Close each finger from (4,) ``dofs`` until contact, its distal link on alone when only the proximal one
    touches (the BH8's breakaway); returns (7,) [spread, prox1..3, dist1..3] radians."""
    d = barrett.clamp_dofs(dofs)
    barrett.apply_dofs(client_id, hand, d)
    prox_out = d[1:].copy()
    dist_out = barrett.coupled_distal(d[1:])
    for finger, (plink, dlink) in enumerate(barrett.FINGER_LINKS):

        def set_finger(proximal: float, distal: float | None = None, finger: int = finger) -> None:
            bent = float(barrett.coupled_distal(proximal)) if distal is None else distal
            pb.resetJointState(hand, barrett.PROXIMAL_JOINTS[finger], proximal, 0.0, physicsClientId=client_id)
            pb.resetJointState(hand, barrett.DISTAL_JOINTS[finger], bent, 0.0, physicsClientId=client_id)

        top = float(barrett.DOF_UPPER[finger + 1])
        angle = _close_joint(client_id, hand, obj, float(d[finger + 1]), top, set_finger, (plink, dlink))
        prox_out[finger], dist_out[finger] = angle, float(barrett.coupled_distal(angle))
        touching = {
            link for (link, _), gap in _pair_distances(client_id, hand, obj, (plink, dlink)).items() if gap < CONTACT_M
        }
        if plink in touching and dlink not in touching:
            bend = partial(set_finger, angle)  # the proximal joint stays where it stopped
            dist_out[finger] = _close_joint(
                client_id, hand, obj, dist_out[finger], barrett.DISTAL_UPPER, bend, (dlink,)
            )
    return np.concatenate([[d[0]], prox_out, dist_out])


def contacts_of(client_id: int, hand: int, obj: int, within: float = 0.002, merge_m: float = 0.003) -> Contacts:
    """Contacts between the hand and the object closer than ``within`` metres, merged within ``merge_m`` per link."""
    found: list[tuple[FloatArray, FloatArray, int, int]] = []
    for p in pb.getClosestPoints(hand, obj, within, physicsClientId=client_id):
        pos = np.array(p[6], dtype=np.float64)
        normal_to_hand = np.array(p[7], dtype=np.float64)  # normal on B (object) pointing towards A (hand)
        norm = float(np.linalg.norm(normal_to_hand))
        if norm < 1e-9 or any(link == p[3] and np.linalg.norm(pos - q) < merge_m for q, _, link, _ in found):
            continue
        found.append((pos, -normal_to_hand / norm, int(p[3]), int(p[4]) + 1))  # base is piece 0, link k piece k + 1
    positions, normals, links, pieces = zip(*found, strict=True) if found else ((), (), (), ())
    return Contacts(
        np.array(positions).reshape(-1, 3),
        np.array(normals).reshape(-1, 3),
        np.array(links, dtype=np.int64),
        np.array(pieces, dtype=np.int64),
    )


def open_free(  # noqa: PLR0917 -- pybullet ids, then the opening
    client_id: int, hand: int, obj: int, spread_rad: float, min_finger_rad: float = 0.0, tolerance_m: float = 0.0
) -> FloatArray:
    """(4,) DOFs of the open hand at ``spread_rad`` (fingers at ``barrett.OPEN_FINGER_RAD``), opened further in
    0.1 rad steps (down to ``min_finger_rad``) while it is inside the object by more than ``tolerance_m`` at its
    current pose; applied."""
    finger = barrett.OPEN_FINGER_RAD
    while True:
        dofs = barrett.open_dofs(spread_rad, finger)
        barrett.apply_dofs(client_id, hand, dofs)
        if finger <= min_finger_rad or min_distance(client_id, hand, obj) >= -tolerance_m:
            return dofs
        finger = max(min_finger_rad, finger - 0.1)


OPEN_MIN_RAD = barrett.OPEN_FINGER_RAD - 0.75
"""The fingers may open 0.75 rad wider than the pre-grasp when the open hand touches the object, as the simulated
robot does (``tasks.simulate.hand.WIDER_OPENINGS_RAD``)."""
PREGRASP_TOL_M = 0.004
"""An open pre-grasp may touch the object by up to 4 mm (a fingertip grazing the face behind a handle): the fingers
close away from it (``close_fingers`` stops a finger only when blocked)."""
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
class GraspCandidate:
    """An executed state: palm pose (world, after the approach), closed joints (7,) [spread,
    proximal 1-3, distal 1-3] rad, quality, ranking cost ``closeness``, offset (m) from the demonstrated approach
    and angle (rad) from the demonstrated palm, the generator that proposed it (``source``), and the fingers (0-2)
    that touch the part (``fingers``)."""

    position: Vector3
    quat_xyzw: FloatArray
    closed: FloatArray
    quality: GraspQuality
    closeness: float
    offset_m: float
    angle_rad: float
    source: str = ""
    fingers: tuple[int, ...] = ()


def grasp_from_candidate(candidate: GraspCandidate) -> Grasp:
    """The descriptor's grasp ``G`` (DESCRIPTOR.md) of a candidate: the Barrett hand, the pre-grasp amplitudes, the
    palm pose (world, m, [x, y, z, w]) and the qualities."""
    q, pos, quat = candidate.quality, candidate.position, candidate.quat_xyzw
    return Grasp(
        hand="barrett",
        eigengrasps=(barrett.spread_amplitude(float(candidate.closed[0])), barrett.CLOSE_AMPLITUDE),
        wrist_position=(float(pos[0]), float(pos[1]), float(pos[2])),
        wrist_orientation=(float(quat[0]), float(quat[1]), float(quat[2]), float(quat[3])),
        quality={
            "epsilon": q.epsilon,
            "volume": q.volume,
            "force_closure": q.force_closure,
            "contacts": q.contacts,
            "mu": q.mu,
            "closed_dofs": [float(v) for v in candidate.closed[:4]],
            "demo_offset_m": candidate.offset_m,
            "demo_angle_rad": candidate.angle_rad,
        },
    )


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
        dofs = _opened((client, hand, obj), start, quat, spread)
        if dofs is not None:
            break
    else:
        return None
    final = approach_to_contact(client, hand, obj, start, quat, approach_max_m)
    closed = close_fingers(client, hand, obj, dofs)
    contacts = contacts_of(client, hand, obj)
    on_part = ~model.is_mount_piece(contacts.pieces)  # a finger pressing the mount holds nothing of the part
    quality = grasp_quality(contacts.positions[on_part], contacts.normals_in[on_part], model.center, model.radius, mu)
    links = contacts.links[on_part]
    fingers = tuple(f for f, pair in enumerate(barrett.FINGER_LINKS) if np.any(np.isin(links, pair)))
    return final, closed, quality, fingers


def _opened(ids: tuple[int, int, int], pos: Vector3, quat: FloatArray, spread: float) -> FloatArray | None:
    """(4,) DOFs of the hand opened at the palm pose (world) in the client ``ids``, wider while it touches the object
    (``OPEN_MIN_RAD``); None when it is still inside the object by more than ``PREGRASP_TOL_M``."""
    client, hand, obj = ids
    set_pose(client, hand, pos, quat)
    dofs = open_free(client, hand, obj, spread, OPEN_MIN_RAD, PREGRASP_TOL_M)
    return dofs if min_distance(client, hand, obj) >= -PREGRASP_TOL_M else None


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
            out.append(GraspCandidate(final, quat, closed, quality, cost, lateral, angle, prop.source, fingers))
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
    if any(_opened(ids, p, Rotation.from_matrix(r).as_quat(), spread) is None for r, p in poses):
        return False  # the open hand alone first: cheap, and where a pose pressed into the part fails
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
