"""Automatic base placement: sweep candidate base poses until IK reaches every palm pose of the chain.

Candidates stand on circles about the centre of the palm path, behind the hand's approach direction first,
at a few radii and heights (the base is a fixed pedestal mount; the pedestal itself is not modelled). A
candidate is accepted when pybullet's limited IK, seeded along the path, reaches every key pose (within
``IK_POSITION_TOL_M``/``IK_ANGLE_TOL_RAD``) and no arm link penetrates the scene at any of them, with the scene's
joints set to where the chain puts them.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pybullet as pb

from tasks.arrays import FloatArray
from tasks.errors import SimulationError
from tasks.rotations import quat_from_matrix
from tasks.simulate.ik import solve_ik
from tasks.simulate.robot import ARM_JOINTS, ARM_LOWER, ARM_REST, ARM_UPPER, FLANGE_TO_PALM_M, Robot
from tasks.simulate.waypoints import angle_between_quats, approach_axis, matrix_from_axis_angle

RADII_M: tuple[float, ...] = (0.60, 0.50, 0.72, 0.40, 0.85)
"""Horizontal distances of the base from the palm path's centre, metres (the iiwa reaches 0.82 m)."""
HEIGHTS_M: tuple[float, ...] = (0.35, 0.15, 0.55, -0.05)
"""Palm-path centre height above the base, metres (the iiwa's shoulder is 0.36 m above its base)."""
YAWS_DEG: tuple[float, ...] = (0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 135.0, -135.0, 180.0)
"""Bearing of the base from the path centre relative to 'behind the approach', degrees."""
FINER_HEIGHTS_M: tuple[float, ...] = (0.25, 0.45)
FINER_YAWS_DEG: tuple[float, ...] = (15.0, -15.0, 45.0, -45.0)
"""After the coarse grid (200 candidates), the finer heights and bearings in between (a wide microwave opening
reached from none of the coarse ones in 2 of 25 instances)."""
SHOULDER_HEIGHT_M = 0.36
"""iiwa axis 2 above the base, metres."""
MAX_REACH_M = 0.82 + 0.205
"""Shoulder to wrist (0.42 + 0.40 m) plus wrist to palm (0.126 m flange + 0.08 m palm): no key farther than this."""
WRIST_TO_PALM_M = 0.081 + FLANGE_TO_PALM_M
"""The iiwa's wrist centre (where axes 5, 6 and 7 meet; link 6's frame) to the palm frame along the approach, m."""
WRIST_REACH_M: tuple[float, float] = (0.41 - 0.012, 0.82 + 0.012)
"""Shoulder (link 1's frame, where axes 1 and 2 meet) to wrist centre: at most upper arm plus forearm (0.42 +
0.40 m, elbow straight), at least 0.41 m (elbow at its 120° limit); widened by what IK's 3 mm / 2° tolerance lets
the wrist centre move (12 mm). A key outside this cannot be reached: a necessary test, no IK needed."""
PART_CLEARANCE_M = 0.15
"""The base must stay this far (horizontally) from the region a rotating part sweeps (axis foot to palm)."""
BASE_LINKS: tuple[int, ...] = (-1, 0, 1, 2, 3)
"""The pedestal and the arm links up to the elbow: they have no business touching the scene ..."""
BASE_CLEARANCE_M = 0.02
"""... so a comfortable placement keeps them 2 cm from it at every key (link 1 on a cart jammed the shoulder)."""
FALLBACK_WINDOW = 40
"""Candidates tried after the first merely reaching one, looking for a comfortable one."""
KEY_LIMIT_MARGIN_RAD = 0.05
"""A comfortable placement keeps every arm joint this far inside its limits at every key: the executor's Cartesian
control keeps a margin too, and a path that only IK's clipping at a limit reaches cannot be followed."""
PENETRATION_TOL_M = 0.005
WIDE_TURN_RAD = 1.5
"""A chain turning the palm by more than this (radians) also tries wrist-end seeds."""
WRIST_END_RAD = 2.6
"""Seed of the last wrist joint near an end of its ±3.05 rad range."""
"""Arm-scene penetration tolerated at a key pose, metres."""


@dataclass(frozen=True)
class KeyPose:
    """A palm pose the arm must reach: ``position`` (3,) m, ``quat`` (4,) [x,y,z,w] world, and the scene joint
    angles there (``scene_joints``: pybullet joint index -> radians or metres)."""

    position: FloatArray
    quat: FloatArray
    scene_joints: dict[int, float]
    axis_foot: FloatArray | None = None
    """For a rotation: the point of the rotation axis nearest the palm (the part spans axis_foot..palm)."""
    primitive: int = -1
    """The chain primitive this pose lies on (-1: pre-grasp and grasp) ..."""
    progress: float = 0.0
    """... and that primitive's motion there (rad or m)."""


@dataclass(frozen=True)
class Placement:
    """An accepted base pose (world, metres, [x,y,z,w]), the arm angles (k, 7) at the key poses, and how many
    candidates were tried."""

    base_position: FloatArray
    base_quat: FloatArray
    q_path: FloatArray
    candidates_tried: int


def candidate_bases(keys: Sequence[KeyPose], floor_z: float = 0.0) -> list[tuple[FloatArray, FloatArray]]:
    """Candidate base poses (position (3,), quat (4,)) in preference order, the coarse grid first, then the finer
    one; each faces the path centre."""
    centre = np.mean([k.position for k in keys], axis=0)
    approach = approach_axis(keys[0].quat)
    horizontal = np.array([approach[0], approach[1], 0.0])
    behind = -horizontal / np.linalg.norm(horizontal) if np.linalg.norm(horizontal) > 1e-3 else np.array([-1.0, 0, 0])
    out: list[tuple[FloatArray, FloatArray]] = []
    finer = [(h, y) for h in (*HEIGHTS_M, *FINER_HEIGHTS_M) for y in (*YAWS_DEG, *FINER_YAWS_DEG)]
    coarse = [(h, y) for h in HEIGHTS_M for y in YAWS_DEG]
    grid = [(r, h, y) for r in RADII_M for h, y in coarse]
    grid += [(r, h, y) for r in RADII_M for h, y in finer if (h, y) not in coarse]
    z = [0.0, 0.0, 1.0]
    bearings = {y: matrix_from_axis_angle(z, math.radians(y)) @ behind for y in (*YAWS_DEG, *FINER_YAWS_DEG)}
    facings = {y: quat_from_matrix(matrix_from_axis_angle(z, math.atan2(-b[1], -b[0]))) for y, b in bearings.items()}
    for radius, height, yaw in grid:
        base = centre + radius * bearings[yaw]
        base[2] = max(floor_z, centre[2] - height)
        out.append((base, facings[yaw].copy()))
    return out


def _segment_distance_xy(point: FloatArray, a: FloatArray, b: FloatArray) -> float:
    """Horizontal distance of ``point`` from the segment a..b (all projected on the xy plane)."""
    p, a2, b2 = point[:2], a[:2], b[:2]
    ab = b2 - a2
    denom = float(ab @ ab)
    t = 0.0 if denom < 1e-12 else min(1.0, max(0.0, float((p - a2) @ ab) / denom))
    return float(np.linalg.norm(p - (a2 + t * ab)))


def clear_of_parts(base: FloatArray, keys: Sequence[KeyPose]) -> bool:
    """Whether the base stands clear of every rotating part's swept segment (``PART_CLEARANCE_M``)."""
    return all(
        _segment_distance_xy(base, k.axis_foot, k.position) >= PART_CLEARANCE_M for k in keys if k.axis_foot is not None
    )


def _penetrates(robot: Robot, scene_body: int, base_clearance_m: float) -> bool:
    """Whether an arm link is inside the scene (beyond ``PENETRATION_TOL_M``), or the pedestal or a link up to
    the elbow (``BASE_LINKS``) is closer to it than ``base_clearance_m``."""

    for link in (-1, *ARM_JOINTS):
        limit = base_clearance_m if link in BASE_LINKS else -PENETRATION_TOL_M
        within = max(limit, 0.0)
        pts = pb.getClosestPoints(robot.body, scene_body, within, linkIndexA=link, physicsClientId=robot.client)
        if any(p[8] < limit for p in pts):
            return True
    return False


def seeds_for(keys: Sequence[KeyPose]) -> list[FloatArray]:
    """IK seeds for the first key: the rest posture, and, when the palm turns by more than ``WIDE_TURN_RAD``
    along the chain (a cap, a knob), the rest posture with the last wrist joint near either end of its range, so
    the turn fits within the joint's limits."""
    seeds = [ARM_REST.copy()]
    turn = sum(angle_between_quats(a.quat, b.quat) for a, b in itertools.pairwise(keys))
    if turn > WIDE_TURN_RAD:
        for q7 in (-WRIST_END_RAD, WRIST_END_RAD):
            seed = ARM_REST.copy()
            seed[6] = q7
            seeds.append(seed)
    return seeds


def reach_keys(
    robot: Robot, scene_body: int, keys: Sequence[KeyPose], seed: FloatArray | None = None
) -> tuple[FloatArray, bool] | None:
    """(k, 7) arm angles reaching every key pose from the robot's current base, seeded along (the first key
    from ``seed``, default ``ARM_REST``), and whether they are comfortable (every joint ``KEY_LIMIT_MARGIN_RAD``
    inside its limits, the base links ``BASE_CLEARANCE_M`` clear of the scene); None if some key is out of reach
    or the arm is inside the scene there."""

    q = ARM_REST.copy() if seed is None else seed.copy()
    path = []
    comfortable = True
    for i, key in enumerate(keys):
        sol = solve_ik(robot, key.position, key.quat, q, rounds=3, iterations=100 if i == 0 else 40)
        if not sol.ok:
            return None
        for joint, value in key.scene_joints.items():
            pb.resetJointState(scene_body, joint, value, 0.0, physicsClientId=robot.client)
        pb.performCollisionDetection(physicsClientId=robot.client)
        if _penetrates(robot, scene_body, -PENETRATION_TOL_M):
            return None
        if comfortable:
            margin = float(np.min(np.minimum(sol.q - ARM_LOWER, ARM_UPPER - sol.q)))
            comfortable = margin >= KEY_LIMIT_MARGIN_RAD and not _penetrates(robot, scene_body, BASE_CLEARANCE_M)
        q = sol.q
        path.append(q)
    return np.array(path), comfortable


def wrists_within_reach(robot: Robot, keys: Sequence[KeyPose]) -> bool:
    """Whether every key's wrist centre lies within ``WRIST_REACH_M`` of the shoulder at the robot's current base
    (a cheap necessary condition for ``reach_keys``)."""

    shoulder = np.array(pb.getLinkState(robot.body, 1, physicsClientId=robot.client)[4], dtype=np.float64)
    lo, hi = WRIST_REACH_M
    for key in keys:
        d = float(np.linalg.norm(key.position - WRIST_TO_PALM_M * approach_axis(key.quat) - shoulder))
        if not lo <= d <= hi:
            return False
    return True


def _farthest_key_reached(robot: Robot, keys: Sequence[KeyPose], base: FloatArray, seeds: list[FloatArray]) -> bool:
    """A cheap screen of a candidate base: does IK from some seed reach the key farthest from the shoulder?"""
    shoulder = base + np.array([0.0, 0.0, SHOULDER_HEIGHT_M])
    far = max(keys, key=lambda k: float(np.linalg.norm(k.position - shoulder)))
    return any(solve_ik(robot, far.position, far.quat, seed, rounds=2, iterations=60).ok for seed in seeds)


def _sweep(
    robot: Robot,
    scene_body: int,
    keys: Sequence[KeyPose],
    cands: list[tuple[FloatArray, FloatArray]],
    seeds: list[FloatArray],
    *,
    screen: bool,
) -> Placement | None:
    """One pass over the candidates (``screen``: skip those failing ``_farthest_key_reached`` first)."""

    fallback: tuple[int, Placement] | None = None
    for tried, (base, quat) in enumerate(cands, start=1):
        if fallback is not None and tried - fallback[0] > FALLBACK_WINDOW:
            break
        shoulder = base + np.array([0.0, 0.0, SHOULDER_HEIGHT_M])
        if max(float(np.linalg.norm(k.position - shoulder)) for k in keys) > MAX_REACH_M:
            continue
        if not clear_of_parts(base, keys):
            continue
        pb.resetBasePositionAndOrientation(robot.body, base.tolist(), quat.tolist(), physicsClientId=robot.client)
        if not wrists_within_reach(robot, keys):
            continue
        if screen and not _farthest_key_reached(robot, keys, base, seeds):
            continue
        for seed in seeds:
            found = reach_keys(robot, scene_body, keys, seed)
            if found is None:
                continue
            placement = Placement(base, quat, found[0], tried)
            if found[1]:
                return placement
            if fallback is None:
                fallback = (tried, placement)
    return fallback[1] if fallback is not None else None


def place_base(robot: Robot, scene_body: int, keys: Sequence[KeyPose], floor_z: float = 0.0) -> Placement:
    """Sweep ``candidate_bases`` in the planning client: the first candidate whose path is comfortable (see
    ``reach_keys``) wins; failing that within ``FALLBACK_WINDOW`` candidates of the first one that merely reaches
    every key, that one. The first sweep skips candidates from which IK does not reach the farthest key at once;
    if it finds nothing, a second sweep tries them all.

    ``SimulationError`` if none reaches (names the number of candidates and the path centre).
    """

    if not keys:
        msg = "no key poses to place the robot for"
        raise SimulationError(msg)
    saved = {j: pb.getJointState(scene_body, j, physicsClientId=robot.client)[0] for k in keys for j in k.scene_joints}
    cands = candidate_bases(keys, floor_z)
    seeds = seeds_for(keys)
    try:
        for screen in (True, False):
            found = _sweep(robot, scene_body, keys, cands, seeds, screen=screen)
            if found is not None:
                return found
    finally:
        for joint, value in saved.items():
            pb.resetJointState(scene_body, joint, value, 0.0, physicsClientId=robot.client)
    centre = np.mean([k.position for k in keys], axis=0)
    msg = (
        f"no base placement among {len(cands)} candidates reaches the whole chain "
        f"(palm path centre {np.round(centre, 3).tolist()} m)"
    )
    raise SimulationError(msg)
