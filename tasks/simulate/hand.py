"""The Barrett hand in execution: the open pre-grasp, closing finger by finger until blocked, and the palm
constraint of the ``"constraint"`` grasp mode."""

from __future__ import annotations

import numpy as np
import pybullet as pb

from tasks.arrays import FloatArray
from tasks.hand import barrett
from tasks.hand.grips import finger_straight_rad
from tasks.simulate import robot as rb
from tasks.simulate.session import STEPS_PER_WAYPOINT, TIME_STEP_S, Session, link_index

CLOSE_EXTRA_RAD = 0.5
"""The fingers are driven this far past the grasp's DOFs, so they squeeze when they stop on the object."""
OPEN_BEYOND_STRAIGHT_RAD = 0.3
"""Pre-grasp: fingers opened this far past pointing along the approach (where the hand's joint range allows) ..."""
WIDER_OPENINGS_RAD: tuple[float, ...] = (0.25, 0.5, 0.75)
"""... or this much further when a finger would be inside the scene at the grasp pose ..."""
PREGRASP_PENETRATION_M = 0.002
"""... more than this deep inside it (a finger merely touching, say, the door behind a bar handle is fine)."""
CLOSE_RATE_RAD_S = 2.0
"""Finger closing speed, rad/s (the BH8-280 closes in about 1 s)."""
SQUEEZE_RAD = 0.3
"""A finger's target leads it by at most this much: stopped on the object it squeezes with its force limit."""
HOLD_TORQUE_NM = 0.5
"""Finger torque once the palm constraint holds the part (N·m): enough to keep touching it; squeezing a small
cap with the full 5 N·m against the constraint made it jitter and spin back (2 rad/s after the turn)."""
CLOSE_STALL_TICKS = 4
CLOSE_STALL_RAD = 0.01
"""A finger that moved less than 0.01 rad over 4 control ticks (0.1 s) has stopped on the object."""
CLOSE_SETTLE_S = 0.15
"""Simulated seconds for the fingers to settle on the object once every finger has stopped."""
CLOSE_MAX_S = 2.0
BREAKAWAY = False
"""Whether a finger whose proximal link stopped curls its distal link on alone (the BH8's breakaway, which the
grasp planner's closing models): off, since distal links curled round a cap's rim jammed its turn (bottle seed 11:
68% instead of 100%) and it closed no grasp that failed without it."""


def pregrasp_opening(planner: rb.Robot, scene_body: int, q_grasp: FloatArray, spread_rad: float) -> FloatArray:
    """(4,) DOFs of the open hand to approach with: the fingers ``OPEN_BEYOND_STRAIGHT_RAD`` past pointing along
    the approach, or opened further (``WIDER_OPENINGS_RAD``) when at the grasp pose (arm at ``q_grasp`` in the
    planning client) a finger would already be inside the scene there (a wide cap: the fingertips land on its rim
    and slide off outside it), unless no opening is clear."""

    straight = finger_straight_rad()
    openings = [straight - OPEN_BEYOND_STRAIGHT_RAD - extra for extra in (0.0, *WIDER_OPENINGS_RAD)]
    saved = rb.arm_angles(planner)
    rb.set_arm(planner, q_grasp)
    fingers = [link for pair in rb.FINGER_LINKS for link in pair]
    chosen = openings[0]
    for opening in openings:
        if opening < float(barrett.DOF_LOWER[1]):
            break
        rb.set_hand(planner, [spread_rad, opening, opening, opening])
        pb.performCollisionDetection(physicsClientId=planner.client)
        clear = all(
            p[8] > -PREGRASP_PENETRATION_M
            for link in fingers
            for p in pb.getClosestPoints(planner.body, scene_body, 0.0, linkIndexA=link, physicsClientId=planner.client)
        )
        if clear:
            chosen = opening
            break
    rb.set_arm(planner, saved)
    rb.set_hand(planner, np.zeros(4))
    return np.array([spread_rad, chosen, chosen, chosen])


def close_fingers(run: Session, target_dofs: FloatArray) -> None:
    """Close the hand from its open pre-grasp towards ``target_dofs`` (4,) radians (``CLOSE_EXTRA_RAD`` further,
    so a finger stopped by the object squeezes it) with each finger's target ramped at ``CLOSE_RATE_RAD_S`` and
    never more than ``SQUEEZE_RAD`` ahead of the finger: a finger the object blocks stops and squeezes with its
    force limit while the others close on (the BH8 closes finger by finger; driven at the motors' full speed a
    fingertip passed through a small cap in one physics step). With ``BREAKAWAY``, a finger whose proximal link
    the object stops short of its goal then curls its distal link on alone. Done when every finger is at its goal
    or stopped (no motion for ``CLOSE_STALL_TICKS`` ticks)."""
    assert run.robot is not None
    tick_s = STEPS_PER_WAYPOINT * TIME_STEP_S
    step = CLOSE_RATE_RAD_S * tick_s
    goal = target_dofs.copy()
    goal[1:] = np.minimum(goal[1:] + CLOSE_EXTRA_RAD, barrett.DOF_UPPER[1:])
    command = rb.hand_dofs(run.robot)
    command[0] = goal[0]
    distal = barrett.coupled_distal(command[1:])
    phase = [0, 0, 0]  # 0 proximal closing, 1 distal breakaway, 2 done
    since = [0, 0, 0]  # tick at which the phase began
    prox_hist = [rb.hand_dofs(run.robot)[1:]]
    dist_hist = [rb.distal_angles(run.robot)]
    for tick in range(1, int(CLOSE_MAX_S / tick_s) + 1):
        prox_now, dist_now = prox_hist[-1], dist_hist[-1]
        for f in range(3):
            if phase[f] == 0:
                command[f + 1] = min(command[f + 1] + step, prox_now[f] + SQUEEZE_RAD, goal[f + 1])
                distal[f] = float(barrett.coupled_distal(command[f + 1]))
            elif phase[f] == 1:
                distal[f] = min(distal[f] + step, dist_now[f] + SQUEEZE_RAD, barrett.DISTAL_UPPER)
        rb.drive_hand(run.robot, command, distal=distal)
        run.step(STEPS_PER_WAYPOINT)
        prox_hist.append(rb.hand_dofs(run.robot)[1:])
        dist_hist.append(rb.distal_angles(run.robot))
        for f in range(3):
            if tick - since[f] < CLOSE_STALL_TICKS:
                continue
            if phase[f] == 0 and command[f + 1] >= goal[f + 1]:
                phase[f] = 2
            elif phase[f] == 0 and abs(prox_hist[-1][f] - prox_hist[-1 - CLOSE_STALL_TICKS][f]) < CLOSE_STALL_RAD:
                phase[f], since[f] = (1 if BREAKAWAY else 2), tick
            elif phase[f] == 1 and (
                abs(dist_hist[-1][f] - dist_hist[-1 - CLOSE_STALL_TICKS][f]) < CLOSE_STALL_RAD
                or distal[f] >= barrett.DISTAL_UPPER
            ):
                phase[f] = 2
        if all(p == 2 for p in phase):
            break
    run.step(int(CLOSE_SETTLE_S / TIME_STEP_S))


def grasp_constraint(run: Session, link: int) -> int:
    """A fixed constraint holding the palm to scene ``link`` in their current relative pose."""
    pb = run.pb
    assert run.robot is not None
    palm = pb.getLinkState(run.robot.body, rb.PALM_LINK, physicsClientId=run.sim)
    if link == -1:
        child_pos, child_orn = pb.getBasePositionAndOrientation(run.scene, physicsClientId=run.sim)
    else:
        child = pb.getLinkState(run.scene, link, physicsClientId=run.sim)
        child_pos, child_orn = child[0], child[1]
    inv_pos, inv_orn = pb.invertTransform(child_pos, child_orn)
    rel_pos, rel_orn = pb.multiplyTransforms(inv_pos, inv_orn, palm[0], palm[1])
    cid = int(
        pb.createConstraint(
            run.robot.body,
            rb.PALM_LINK,
            run.scene,
            link,
            pb.JOINT_FIXED,
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            rel_pos,
            parentFrameOrientation=[0.0, 0.0, 0.0, 1.0],
            childFrameOrientation=rel_orn,
            physicsClientId=run.sim,
        )
    )
    pb.changeConstraint(cid, maxForce=2000.0, physicsClientId=run.sim)
    return cid


def attach(run: Session, grasp_link: str | None, first_part: set[int]) -> str | None:
    """The ``"constraint"`` grasp: fix the palm to the link it holds, once the fingers have closed, and let the
    fingers rest on it (``HOLD_TORQUE_NM``). The link is ``grasp_link`` when named, else the link of the first
    driven part the hand touches most; no constraint (and a note why) when the hand touches no such link."""
    assert run.robot is not None
    touched = run.hand_contacts()
    if grasp_link is not None:
        link = link_index(run, grasp_link)
        if link not in touched:
            return f"the hand does not touch the grasp link {grasp_link} after closing: no grasp constraint made"
    else:
        on_part = [t for t in touched if t in first_part]
        if not on_part:
            return "no hand contact with the driven part after closing: no grasp constraint made"
        link = max(set(on_part), key=on_part.count)
    grasp_constraint(run, link)
    rest = rb.hand_dofs(run.robot)
    rest[1:] += SQUEEZE_RAD
    distal = np.minimum(rb.distal_angles(run.robot) + SQUEEZE_RAD, barrett.DISTAL_UPPER)
    rb.drive_hand(run.robot, rest, max_torque_nm=HOLD_TORQUE_NM, distal=distal)
    return None
