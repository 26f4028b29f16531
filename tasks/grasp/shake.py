"""Shake test: does a grasp hold the part as a free body under gravity and shaking (pybullet, DIRECT)?

The part (the planner's object model) is a dynamic body of 0.3 kg made
of its convex pieces or primitive. The hand is placed at the grasp's palm pose open at the grasp's spread
(``closing.open_free``), the fingers are closed kinematically to contact, then position-controlled 0.3 rad
past contact with at most ``squeeze_torque_nm`` (1.5 N m) so they press. A model with a known mount (the face
a handle or a lever stands on, ``object_model.labelled_model``) is closed on as a whole, held static; then the
part alone becomes the free body, and a finger the mount stopped holds its place instead of squeezing on: the
test asks whether the fingers that reach the part hold it, not whether they pinch what it is fixed to. The
palm is held by a fixed constraint that follows a trajectory: settle without gravity, switch gravity on
(world -z), then shake sinusoidally along world x, y, z and two diagonals (A (1 - cos ωt), A = 20 mm, 2.5 Hz:
4.9 m/s² peak), two cycles each. The grasp holds when the part's pose relative to the palm moves less than
``max_shift_m`` (10 mm) and ``max_turn_rad`` (10°) from where it settled; the test stops as soon as either is
exceeded.

Other programs (``ShakeParams.gravity`` and ``ShakeParams.motions``): gravity in several directions one phase
after another (each phase settles 0.5 s, then runs the motions), and motions of any direction, amplitude,
frequency and length, translations or turns of the palm about an axis through it (``Motion``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from schemas.descriptor import Grasp
from tasks.arrays import FloatArray, Points, Vector3
from tasks.grasp import closing
from tasks.grasp.object_model import ObjectModel, load_object
from tasks.hand import barrett

TIME_STEP_S = 1.0 / 240.0
SHAKE_DIRECTIONS: FloatArray = np.array(
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 0.0], [0.0, 1.0, 1.0]]
)


@dataclass(frozen=True)
class Motion:
    """One shake of the palm: along the unit ``direction`` (world) by A (1 - cos ωt) with A = ``amplitude_m``
    (m), or, when ``turn`` is set, turned about ``direction`` (through the palm origin) by A (1 - cos ωt) with A
    in rad; ``frequency_hz`` (Hz) for ``cycles`` cycles."""

    direction: tuple[float, float, float]
    amplitude_m: float
    frequency_hz: float
    cycles: float
    turn: bool = False


@dataclass(frozen=True)
class ShakeParams:
    """Shake test settings: part mass (kg), amplitude (m), frequency (Hz), cycles per direction, how many of
    ``SHAKE_DIRECTIONS`` (x, y, z, xy, yz) to shake along, squeeze past
    contact (rad) and its torque (N m), friction, tolerances; ``close`` False holds the eigengrasp posture itself;
    ``gravity``: world gravity vectors (m/s²), one phase each; ``motions``: the shakes of each phase (``program``);
    ``spinning_friction_m``: torsional friction of
    the rubber finger pads (pybullet point contacts have none otherwise); ``solver_iterations``: 150, since
    pybullet's default 50 lets squeezed contacts creep."""

    mass_kg: float = 0.3
    amplitude_m: float = 0.02
    frequency_hz: float = 2.5
    cycles: int = 2
    directions: int = 5
    squeeze_rad: float = 0.3
    squeeze_torque_nm: float = 1.5
    friction: float = 0.8
    max_shift_m: float = 0.01
    max_turn_rad: float = math.radians(10.0)
    close: bool = True
    spinning_friction_m: float = 0.002
    solver_iterations: int = 150
    gravity: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, -9.81),)
    motions: tuple[Motion, ...] = ()

    def program(self) -> tuple[Motion, ...]:
        """The motions of each gravity phase: ``motions``, else the first ``directions`` of ``SHAKE_DIRECTIONS``
        at ``amplitude_m``, ``frequency_hz`` and ``cycles``."""
        if self.motions:
            return self.motions
        units = (
            SHAKE_DIRECTIONS[: self.directions] / np.linalg.norm(SHAKE_DIRECTIONS[: self.directions], axis=1)[:, None]
        )
        return tuple(
            Motion((float(u[0]), float(u[1]), float(u[2])), self.amplitude_m, self.frequency_hz, self.cycles)
            for u in units
        )


@dataclass(frozen=True)
class ShakeResult:
    """Whether the part stayed in the hand; its largest shift (m) and turn (rad) relative to the palm (up to when
    the test stopped: a dropped part's shift is only known to exceed the tolerance); how many simulated seconds
    of gravity and shaking it stayed within the tolerances (the whole test when it holds)."""

    holds: bool
    max_shift_m: float
    max_turn_rad: float
    survived_s: float = 0.0
    squeezed_positions: Points | None = None
    squeezed_normals: Points | None = None
    """The contacts (m, 3) once the fingers have squeezed the part for 0.3 s without gravity, and their normals into
    the part, expressed where the model has the part (world, m): what the squeezing hand holds."""


def _relative(client_id: int, hand: int, obj: int) -> tuple[FloatArray, Rotation]:
    hp, hq = pb.getBasePositionAndOrientation(hand, physicsClientId=client_id)
    op, oq = pb.getBasePositionAndOrientation(obj, physicsClientId=client_id)
    r_hand = Rotation.from_quat(hq)
    return r_hand.inv().apply(np.array(op) - np.array(hp)), r_hand.inv() * Rotation.from_quat(oq)


def grip(  # noqa: PLR0917 -- pybullet client, model, palm pose, posture, settings
    client: int, model: ObjectModel, position: Vector3, quat_xyzw: FloatArray, dofs: FloatArray, prm: ShakeParams
) -> tuple[int, int, int]:
    """Set up a grasp in pybullet ``client``: the hand at the palm pose (world, m, [x, y, z, w]) closed from the
    open hand at spread ``dofs[0]`` (or set to the (4,) DOFs ``dofs`` when ``prm.close`` is False), on the part as
    a free body (its mount, if any, an obstacle while the fingers close, then removed; a finger it stopped holds
    its place), the fingers squeezing, the spread held, the palm held by a fixed constraint. Returns the hand,
    the part and the constraint ids."""
    pos = np.asarray(position, dtype=np.float64)
    quat = np.asarray(quat_xyzw, dtype=np.float64)
    part_only = model.without_mount()  # the free body is the part, not the face it stands on
    mounted = prm.close and part_only is not model  # close on the part and its mount (static), then swap
    loaded = model if prm.close else part_only
    obj = load_object(client, loaded, mass_kg=0.0 if mounted else prm.mass_kg, friction=prm.friction)
    hand = barrett.load_hand(client, pos, quat)
    for link in range(-1, 9):
        pb.changeDynamics(
            hand, link, lateralFriction=1.0, spinningFriction=prm.spinning_friction_m, physicsClientId=client
        )
    blocked = np.zeros(3, dtype=bool)  # fingers stopped by the mount: they hold still, not squeeze on
    if prm.close:
        opened = closing.open_free(client, hand, obj, float(dofs[0]))
        closed = closing.close_fingers(client, hand, obj, opened)
        if mounted:
            contacts = closing.contacts_of(client, hand, obj)
            on_mount = model.is_mount_piece(contacts.pieces)
            for finger, links in enumerate(barrett.FINGER_LINKS):
                blocked[finger] = bool(np.any(on_mount & np.isin(contacts.links, links)))
            pb.removeBody(obj, physicsClientId=client)
            obj = load_object(client, part_only, mass_kg=prm.mass_kg, friction=prm.friction)
    else:
        barrett.apply_dofs(client, hand, dofs)
        closed = np.concatenate([dofs, barrett.coupled_distal(dofs[1:])])
    squeeze = np.where(blocked, 0.0, prm.squeeze_rad if prm.close else 0.0)
    target_prox = np.minimum(closed[1:4] + squeeze, barrett.DOF_UPPER[1:])
    target_dist = np.minimum(closed[4:7] + squeeze, barrett.DISTAL_UPPER)
    barrett.drive_dofs(
        client,
        hand,
        np.concatenate([[closed[0]], target_prox]),
        max_torque_nm=prm.squeeze_torque_nm,
        distal=target_dist,
    )
    for joint in barrett.SPREAD_JOINTS:
        pb.setJointMotorControl2(
            hand, joint, pb.POSITION_CONTROL, targetPosition=float(closed[0]), force=20.0, physicsClientId=client
        )
    anchor = pb.createConstraint(
        hand,
        -1,
        -1,
        -1,
        pb.JOINT_FIXED,
        [0, 0, 0],
        [0, 0, 0],
        pos.tolist(),
        childFrameOrientation=quat.tolist(),
        physicsClientId=client,
    )
    pb.changeConstraint(anchor, pos.tolist(), quat.tolist(), maxForce=5000.0, physicsClientId=client)
    return hand, obj, anchor


def shake_test(model: ObjectModel, grasp: Grasp, params: ShakeParams | None = None) -> ShakeResult:
    """Close ``grasp`` on the part as a free body and shake it; see the module docstring."""
    prm = params or ShakeParams()
    client = pb.connect(pb.DIRECT)
    try:
        pb.setTimeStep(TIME_STEP_S, physicsClientId=client)
        pb.setPhysicsEngineParameter(numSolverIterations=prm.solver_iterations, physicsClientId=client)
        pos = np.array(grasp.wrist_position)
        quat = np.array(grasp.wrist_orientation)
        hand, obj, anchor = grip(client, model, pos, quat, barrett.dofs_from_eigengrasps(*grasp.eigengrasps), prm)
        start = pb.getBasePositionAndOrientation(obj, physicsClientId=client)
        for _ in range(int(0.3 / TIME_STEP_S)):
            pb.stepSimulation(physicsClientId=client)
        squeezed = _squeezed_contacts(client, hand, obj, start)
        ref_pos, ref_rot = _relative(client, hand, obj)
        shift = 0.0
        turn = 0.0

        def track() -> None:
            nonlocal shift, turn
            p, r = _relative(client, hand, obj)
            shift = max(shift, float(np.linalg.norm(p - ref_pos)))
            turn = max(turn, float((ref_rot.inv() * r).magnitude()))

        def dropped() -> bool:  # the largest shift and turn only grow: past a tolerance the grasp has failed
            return shift > prm.max_shift_m or turn > prm.max_turn_rad

        palm = Rotation.from_quat(quat)
        steps = 0
        for gravity in prm.gravity:
            pb.setGravity(*gravity, physicsClientId=client)
            for i in range(int(0.5 / TIME_STEP_S)):
                pb.stepSimulation(physicsClientId=client)
                steps += 1
                if i % 12 == 11:
                    track()
                    if dropped():
                        break
            track()
            for motion in prm.program() if not dropped() else ():
                unit = np.array(motion.direction) / np.linalg.norm(motion.direction)
                omega = 2.0 * math.pi * motion.frequency_hz
                for i in range(int(motion.cycles / motion.frequency_hz / TIME_STEP_S)):
                    amount = motion.amplitude_m * (1.0 - math.cos(omega * (i + 1) * TIME_STEP_S))
                    if motion.turn:
                        at, q = pos, (Rotation.from_rotvec(amount * unit) * palm).as_quat().tolist()
                    else:
                        at, q = pos + amount * unit, quat.tolist()
                    pb.changeConstraint(anchor, at.tolist(), q, maxForce=5000.0, physicsClientId=client)
                    pb.stepSimulation(physicsClientId=client)
                    steps += 1
                    if i % 12 == 0:
                        track()
                        if dropped():
                            break
                track()
                if dropped():
                    break
            if dropped():
                break
    finally:
        pb.disconnect(client)
    holds = shift <= prm.max_shift_m and turn <= prm.max_turn_rad
    return ShakeResult(holds, shift, turn, steps * TIME_STEP_S, *squeezed)


def _squeezed_contacts(client: int, hand: int, obj: int, start: tuple[object, object]) -> tuple[Points, Points]:
    """The hand's contacts on the part and their normals into it, the part's motion since ``start`` (its base
    position and orientation then) undone."""
    end_pos, end_quat = pb.getBasePositionAndOrientation(obj, physicsClientId=client)
    back = Rotation.from_quat(start[1]) * Rotation.from_quat(end_quat).inv()
    contacts = closing.contacts_of(client, hand, obj)
    if not len(contacts.positions):
        return np.zeros((0, 3)), np.zeros((0, 3))
    positions = back.apply(contacts.positions - np.asarray(end_pos)) + np.asarray(start[0])
    return np.asarray(positions, dtype=np.float64).reshape(-1, 3), back.apply(contacts.normals_in).reshape(-1, 3)
