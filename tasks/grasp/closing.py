"""Kinematic approach and finger closing in pybullet (GraspIt!'s approachToContact and autoGrasp).

The hand is moved and its joints are reset (no dynamics); contact means a pybullet closest distance below ``CONTACT_M``.
Fingers close one at a time in small steps with bisection to the first contact; when the proximal link stops first, the
distal link keeps closing alone (the BH8's breakaway), otherwise it stays coupled.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
import numpy.typing as npt
import pybullet as pb

from tasks.arrays import FloatArray, Points
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


def min_distance(client_id: int, hand: int, obj: int, link: int | None = None, within: float = 0.05) -> float:
    """Smallest signed distance (m) between the hand (or one of its links) and the object, capped at ``within``."""
    kwargs = {} if link is None else {"linkIndexA": link}
    pts = pb.getClosestPoints(hand, obj, within, physicsClientId=client_id, **kwargs)
    if not pts:
        return within
    return float(min(p[8] for p in pts))


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
