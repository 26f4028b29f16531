"""Shake test: does a grasp hold the part as a free body under gravity and shaking (pybullet, DIRECT)?

The part (the planner's object model) is a dynamic body of 0.3 kg; the hand closes on it and squeezes (``grip``); the
palm, held by a fixed constraint, follows the program (``ShakeParams``: gravity phases, each settling 0.5 s, then the
motions, ``Motion``). The grasp holds while the part moves less than ``max_shift_m`` and turns less than
``max_turn_rad`` in the hand from where it settled. ``hold_check`` is the planner's program, run on its own model.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from schemas.descriptor import Grasp
from tasks.arrays import FloatArray, Points, Vector3
from tasks.grasp.execution import close_fingers, contacts_of, open_free
from tasks.grasp.object_model import ObjectModel, load_object
from tasks.hand import barrett

TIME_STEP_S = 1.0 / 240.0
TRACK_STEPS = 12
"""The part's pose in the hand is read every 12 steps (20 Hz, several samples per cycle of a 2-4 Hz shake)."""


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
    """Shake test settings: part mass (kg), squeeze past contact (rad) and its torque (N m), friction, tolerances
    (m, rad); ``gravity``: world gravity vectors (m/s²), one phase each; ``motions``: the shakes of each phase;
    ``spinning_friction_m``: torsional friction of the rubber finger pads (pybullet point contacts have none
    otherwise); ``solver_iterations``: 150, since pybullet's default 50 lets squeezed contacts creep."""

    mass_kg: float = 0.3
    squeeze_rad: float = 0.3
    squeeze_torque_nm: float = 1.5
    friction: float = 0.8
    max_shift_m: float = 0.01
    max_turn_rad: float = math.radians(10.0)
    spinning_friction_m: float = 0.002
    solver_iterations: int = 150
    gravity: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, -9.81),)
    motions: tuple[Motion, ...] = ()


@dataclass(frozen=True)
class ShakeResult:
    """Whether the part stayed in the hand; its largest shift (m) and turn (rad) relative to the palm (up to when
    the test stopped: a dropped part's shift is only known to exceed the tolerance); how many simulated seconds
    of gravity and shaking it stayed within the tolerances (the whole test when it holds)."""

    holds: bool
    max_shift_m: float
    max_turn_rad: float
    survived_s: float
    squeezed_positions: Points
    squeezed_normals: Points
    """The contacts (m, 3) once the fingers have squeezed the part for 0.3 s without gravity, and their normals into
    the part, expressed where the model has the part (world, m): what the squeezing hand holds."""


def _relative(client_id: int, hand: int, obj: int) -> tuple[FloatArray, Rotation]:
    hp, hq = pb.getBasePositionAndOrientation(hand, physicsClientId=client_id)
    op, oq = pb.getBasePositionAndOrientation(obj, physicsClientId=client_id)
    r_hand = Rotation.from_quat(hq)
    return r_hand.inv().apply(np.array(op) - np.array(hp)), r_hand.inv() * Rotation.from_quat(oq)


def grip(  # noqa: PLR0917 -- pybullet client, model, palm pose, spread, settings
    client: int, model: ObjectModel, position: Vector3, quat_xyzw: FloatArray, spread: float, prm: ShakeParams
) -> tuple[int, int, int]:
    """Set up a grasp in pybullet ``client``: the hand at the palm pose (world, m, [x, y, z, w]) closed from the
    open hand at ``spread`` (rad) on the part as a free body (its mount, if any, an obstacle while the fingers
    close, then removed; a finger it stopped holds its place: the test asks whether the fingers that reach the part
    hold it), the other fingers squeezing ``prm.squeeze_rad`` past contact, the spread held, the palm held by a fixed
    constraint. Returns the hand, the part and the constraint ids."""
    pos = np.asarray(position, dtype=np.float64)
    quat = np.asarray(quat_xyzw, dtype=np.float64)
    part_only = model.without_mount()  # the free body is the part, not the face it stands on
    mounted = part_only is not model  # close on the part and its mount (static), then swap
    obj = load_object(client, model, mass_kg=0.0 if mounted else prm.mass_kg, friction=prm.friction)
    hand = barrett.load_hand(client, pos, quat)
    for link in range(-1, 9):
        pb.changeDynamics(
            hand, link, lateralFriction=1.0, spinningFriction=prm.spinning_friction_m, physicsClientId=client
        )
    closed = close_fingers(client, hand, obj, open_free(client, hand, obj, spread))
    blocked = np.zeros(3, dtype=bool)  # fingers stopped by the mount: they hold still, not squeeze on
    if mounted:
        contacts = contacts_of(client, hand, obj)
        on_mount = model.is_mount_piece(contacts.pieces)
        for finger, links in enumerate(barrett.FINGER_LINKS):
            blocked[finger] = bool(np.any(on_mount & np.isin(contacts.links, links)))
        pb.removeBody(obj, physicsClientId=client)
        obj = load_object(client, part_only, mass_kg=prm.mass_kg, friction=prm.friction)
    squeeze = np.where(blocked, 0.0, prm.squeeze_rad)
    prox = np.minimum(closed[1:4] + squeeze, barrett.DOF_UPPER[1:])
    dist = np.minimum(closed[4:7] + squeeze, barrett.DISTAL_UPPER)
    barrett.drive_dofs(
        client, hand, np.concatenate([[closed[0]], prox]), max_torque_nm=prm.squeeze_torque_nm, distal=dist
    )
    for joint in barrett.SPREAD_JOINTS:
        pb.setJointMotorControl2(
            hand, joint, pb.POSITION_CONTROL, targetPosition=float(closed[0]), force=20.0, physicsClientId=client
        )
    fixed = (hand, -1, -1, -1, pb.JOINT_FIXED, [0, 0, 0], [0, 0, 0], pos.tolist())
    anchor = pb.createConstraint(*fixed, childFrameOrientation=quat.tolist(), physicsClientId=client)
    pb.changeConstraint(anchor, pos.tolist(), quat.tolist(), maxForce=5000.0, physicsClientId=client)
    return hand, obj, anchor


def shake_test(model: ObjectModel, grasp: Grasp, params: ShakeParams | None = None) -> ShakeResult:
    """Close ``grasp`` on the part as a free body and run the program; see the module docstring."""
    prm = params or ShakeParams()
    client = pb.connect(pb.DIRECT)
    try:
        pb.setTimeStep(TIME_STEP_S, physicsClientId=client)
        pb.setPhysicsEngineParameter(numSolverIterations=prm.solver_iterations, physicsClientId=client)
        pos = np.array(grasp.wrist_position)
        quat = np.array(grasp.wrist_orientation)
        spread = float(barrett.dofs_from_eigengrasps(*grasp.eigengrasps)[0])
        hand, obj, anchor = grip(client, model, pos, quat, spread, prm)
        start = pb.getBasePositionAndOrientation(obj, physicsClientId=client)
        for _ in range(int(0.3 / TIME_STEP_S)):
            pb.stepSimulation(physicsClientId=client)
        squeezed = _squeezed_contacts(client, hand, obj, start)
        ref_pos, ref_rot = _relative(client, hand, obj)
        shift = turn = 0.0
        steps = 0

        def dropped() -> bool:  # the largest shift and turn only grow: past a tolerance the grasp has failed
            return shift > prm.max_shift_m or turn > prm.max_turn_rad

        def run(count: int, phase: int, move: Callable[[int], None] | None = None) -> None:
            """Step ``count`` times (``move(i)`` first), reading the part every ``TRACK_STEPS`` from ``phase``."""
            nonlocal shift, turn, steps
            for i in range(count):
                if move is not None:
                    move(i)
                pb.stepSimulation(physicsClientId=client)
                steps += 1
                if i % TRACK_STEPS == phase or i == count - 1:
                    p, r = _relative(client, hand, obj)
                    shift = max(shift, float(np.linalg.norm(p - ref_pos)))
                    turn = max(turn, float((ref_rot.inv() * r).magnitude()))
                    if dropped():
                        return

        def mover(motion: Motion) -> Callable[[int], None]:
            unit = np.array(motion.direction) / np.linalg.norm(motion.direction)
            omega = 2.0 * math.pi * motion.frequency_hz

            def move(i: int) -> None:
                amount = motion.amplitude_m * (1.0 - math.cos(omega * (i + 1) * TIME_STEP_S))
                if motion.turn:
                    at, q = pos, (Rotation.from_rotvec(amount * unit) * Rotation.from_quat(quat)).as_quat()
                else:
                    at, q = pos + amount * unit, quat
                pb.changeConstraint(anchor, at.tolist(), q.tolist(), maxForce=5000.0, physicsClientId=client)

            return move

        for gravity in prm.gravity:
            pb.setGravity(*gravity, physicsClientId=client)
            run(int(0.5 / TIME_STEP_S), TRACK_STEPS - 1)
            for motion in prm.motions:
                if dropped():
                    break
                run(int(motion.cycles / motion.frequency_hz / TIME_STEP_S), 0, mover(motion))
            if dropped():
                break
    finally:
        pb.disconnect(client)
    return ShakeResult(not dropped(), shift, turn, steps * TIME_STEP_S, *squeezed)


def _squeezed_contacts(client: int, hand: int, obj: int, start: tuple[object, object]) -> tuple[Points, Points]:
    """The hand's contacts on the part and their normals into it, the part's motion since ``start`` (its base
    position and orientation then) undone."""
    end_pos, end_quat = pb.getBasePositionAndOrientation(obj, physicsClientId=client)
    back = Rotation.from_quat(start[1]) * Rotation.from_quat(end_quat).inv()
    contacts = contacts_of(client, hand, obj)
    positions = back.apply(contacts.positions - np.asarray(end_pos)) + np.asarray(start[0])
    return np.asarray(positions, dtype=np.float64).reshape(-1, 3), back.apply(contacts.normals_in).reshape(-1, 3)


CHECK_TILT_RAD = math.radians(30.0)
CHECK_PEAK_MS2 = 6.5
CHECK_FREQUENCY_HZ = 3.0
CHECK_TURN_RAD = math.radians(7.5)
CHECK_TURN_HZ = 2.0
CHECK_CYCLES = 1.0
"""``hold_check``'s program: gravity tilt (rad), translation peak acceleration (m/s²) and frequency (Hz), palm
turn amplitude (rad) and frequency (Hz), cycles of each motion (whole cycles: A (1 - cos ωt) ends where it
began)."""


CHECK_LENGTH_S = 3 * (0.5 + CHECK_CYCLES * (3 / CHECK_FREQUENCY_HZ + 1 / CHECK_TURN_HZ))
"""Simulated length of ``hold_check`` (s): three gravity phases, each 0.5 s settling then the four motions (6 s)."""
CHECK_SHIFT_M = 0.005
CHECK_TURN_TOL_RAD = math.radians(5.0)
"""``hold_check`` fails a grasp whose part moved 5 mm or turned 5° in the hand: half the slip a longer, harsher
shake allows (10 mm, 10°), since slip that starts in a short check goes on in a longer one."""


def hold_check(palm_quat_xyzw: FloatArray) -> ShakeParams:
    """The planner's hold check for a grasp whose palm has orientation ``palm_quat_xyzw`` (world [x, y, z, w]):
    gravity world down, then tilted 30° towards either end of the palm's x axis (the axis of a bar the fingers
    close round: a lever slides along it) laid horizontal, or of its y axis when x is near vertical; in each
    phase translations along world x, y and z with 6.5 m/s² peaks at 3 Hz and a turn of the palm of 7.5° about
    the world diagonal at 2 Hz, one cycle each (6 s in all), within 5 mm and 5°. Run on the planner's own
    object model. The tilts and the palm turn load a fingertip grasp along and about the bar, the directions it
    slips in, which world gravity and translations alone do not."""
    rot = Rotation.from_quat(palm_quat_xyzw).as_matrix()
    down = np.array([0.0, 0.0, -1.0])
    side = rot[:, 0] - float(rot[:, 0] @ down) * down
    if float(np.linalg.norm(side)) < 0.3:
        side = rot[:, 1] - float(rot[:, 1] @ down) * down
    side = side / float(np.linalg.norm(side))
    gravity = [(0.0, 0.0, -9.81)]
    for sign in (1.0, -1.0):
        g = 9.81 * (math.cos(CHECK_TILT_RAD) * down + sign * math.sin(CHECK_TILT_RAD) * side)
        gravity.append((float(g[0]), float(g[1]), float(g[2])))
    amplitude = CHECK_PEAK_MS2 / (2.0 * math.pi * CHECK_FREQUENCY_HZ) ** 2
    axes = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    motions = [Motion(a, amplitude, CHECK_FREQUENCY_HZ, CHECK_CYCLES) for a in axes]
    diagonal = 1.0 / math.sqrt(3.0)
    motions.append(Motion((diagonal, diagonal, diagonal), CHECK_TURN_RAD, CHECK_TURN_HZ, CHECK_CYCLES, turn=True))
    return ShakeParams(
        max_shift_m=CHECK_SHIFT_M, max_turn_rad=CHECK_TURN_TOL_RAD, gravity=tuple(gravity), motions=tuple(motions)
    )
