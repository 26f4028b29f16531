"""Execute a descriptor with the iiwa + Barrett hand in pybullet (paper Section V-A).

Order: place the base (IK sweep), start at the pre-grasp pose (``PREGRASP_BACK_M`` back along the approach),
approach along the palm's +z, close the hand towards the grasp's eigengrasp DOFs until the fingers stop on the
object, then run each primitive: Cartesian palm waypoints along the arc about the axis (the hand turns with the
part) or the line along the direction, IK seeded from the last solution, position control with the iiwa's torque
limits; move on when the driven joint has reached the extent or progress stops. Finally hold still for
``HOLD_S`` and judge success (``result.py``).

Grasp modes: ``"friction"`` relies on the closed fingers' contact friction alone; ``"constraint"`` adds a fixed
constraint between palm and the grasped link once the fingers have closed on it (a common simulation stand-in
for a firm grasp, which pybullet's soft contacts do not hold under large wrist torques). Contact is measured the
same way in both modes.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import numpy as np

from schemas.descriptor import Descriptor, Primitive
from tasks.arrays import FloatArray
from tasks.errors import SimulationError
from tasks.grasp import barrett
from tasks.simulate import robot as rb
from tasks.simulate.control import command_for_twist, line_twist, pose_error, screw_twist
from tasks.simulate.matching import JointAxis, JointMatch, match_chain
from tasks.simulate.placement import KeyPose, place_base
from tasks.simulate.render import save_frame
from tasks.simulate.result import (
    CONTACT_KEPT_FRACTION,
    STILL_ANGULAR_RAD_S,
    STILL_LINEAR_M_S,
    SUCCESS_FRACTION,
    JointTrace,
    PrimitiveResult,
    SimulationResult,
    StopReason,
)
from tasks.simulate.waypoints import (
    ARC_STEP_RAD,
    LINE_STEP_M,
    Waypoints,
    approach_axis,
    arc_waypoints,
    line_waypoints,
    matrix_from_axis_angle,
)

TIME_STEP_S = 1.0 / 120.0
"""Physics step, seconds (pybullet's default; at 1/120 s a light bottle cap slipped out of the grasp)."""
SOLVER_ITERATIONS = 50
"""Constraint solver iterations per step (pybullet's default; 20 let the cap slip under the palm constraint)."""
STEPS_PER_WAYPOINT = 3
"""Physics steps per waypoint: 1° or 5 mm per 25 ms, i.e. 0.7 rad/s or 0.2 m/s along the path."""
MAX_PATH_FACTOR = 1.6
"""A primitive gets at most 1.6x the control ticks of its planned waypoints (a part lagging a compliant hand)."""
SETTLED_SPEED = 0.02
"""After a primitive, the arm holds until the driven joint is slower than this (rad/s or m/s) ..."""
PREGRASP_BACK_M = 0.10
"""Pre-grasp palm pose: 10 cm back along the approach direction."""
APPROACH_SETTLE_TICKS = 20
"""At most this many extra control ticks to bring the palm onto the grasp pose ..."""
APPROACH_TOL_M = 0.001
APPROACH_TOL_RAD = math.radians(0.5)
"""... within 1 mm and 0.5°."""
CLOSE_EXTRA_RAD = 0.5
"""The fingers are driven this far past the grasp's DOFs, so they squeeze when they stop on the object."""
OPEN_BEYOND_STRAIGHT_RAD = 0.3
"""Pre-grasp: fingers opened this far past pointing along the approach (where the hand's joint range allows)."""
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
HOLD_S = 0.5
"""Simulated seconds held still after the chain before judging stillness."""
SETTLE_MAX_S = 0.5
"""... or at most this long."""
STALL_WINDOW = 30
"""Waypoints over which progress is judged (0.75 s) ..."""
STALL_MIN_FRACTION = 0.02
"""... a primitive has stalled when its joint moved less than 2% of the extent over the window."""
KEY_EVERY = 15
"""Every 15th waypoint (15° or 7.5 cm) is a key pose for base placement."""
SCENE_JOINT_FRICTION_NM = 0.3
"""Dry friction of scene joints (a velocity motor with this force limit), N·m or N, where the URDF gives none
(``<dynamics friction>``, which pybullet reads but does not apply; the built-in scenes give theirs)."""

GraspMode = Literal["constraint", "friction"]


@dataclass(frozen=True)
class SceneSetup:
    """How to build the scene in a pybullet client: ``load(client) -> body id``; the joints the chain may drive
    (``joints``; None = every revolute/prismatic joint); the link the grasp holds (None = the link the fingers
    touch most); ``floor_z`` the lowest base height (metres)."""

    name: str
    load: Callable[[int], int]
    joints: tuple[str, ...] | None = None
    grasp_link: str | None = None
    floor_z: float = 0.0
    set_joint_friction: bool = True


@dataclass(frozen=True)
class _Joint:
    index: int
    axis: JointAxis
    lower: float
    upper: float


def scene_joints(client: int, body: int, names: Sequence[str] | None, scene_name: str = "scene") -> list[_Joint]:
    """The scene body's revolute/prismatic joints (world axes at the current state), optionally only ``names``."""
    import pybullet as pb  # noqa: PLC0415

    found: list[_Joint] = []
    by_name: dict[str, int] = {}
    for j in range(pb.getNumJoints(body, physicsClientId=client)):
        info = pb.getJointInfo(body, j, physicsClientId=client)
        name = info[1].decode()
        by_name[name] = j
        if info[2] not in (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC):
            continue
        if names is not None and name not in names:
            continue
        state = pb.getLinkState(body, j, computeForwardKinematics=True, physicsClientId=client)
        rot = np.array(pb.getMatrixFromQuaternion(state[5]), dtype=np.float64).reshape(3, 3)
        direction = rot @ np.array(info[13], dtype=np.float64)
        kind: Literal["revolute", "prismatic"] = "revolute" if info[2] == pb.JOINT_REVOLUTE else "prismatic"
        axis = JointAxis(name, kind, np.array(state[4], dtype=np.float64), direction / np.linalg.norm(direction))
        found.append(_Joint(j, axis, float(info[8]), float(info[9])))
    if names is not None:
        missing = [n for n in names if n not in {f.axis.name for f in found}]
        if missing:
            names_found = ", ".join(sorted(by_name))
            msg = f"scene {scene_name}: no revolute/prismatic joint named {', '.join(missing)} (joints: {names_found})"
            raise SimulationError(msg)
        found.sort(key=lambda f: list(names).index(f.axis.name))
    return found


def primitive_waypoints(primitive: Primitive, position: FloatArray, quat: FloatArray) -> Waypoints:
    """Palm waypoints for one primitive from the palm pose (``position``, ``quat``), world frame."""
    if primitive.kind == "rotation":
        if primitive.pos is None:
            msg = "rotation primitive without an axis point"
            raise SimulationError(msg)
        return arc_waypoints(position, quat, primitive.pos, primitive.dir, primitive.extent)
    return line_waypoints(position, quat, primitive.dir, primitive.extent)


def key_poses(
    desc: Descriptor, matches: Sequence[JointMatch], joints: dict[str, _Joint], q0: dict[int, float]
) -> list[KeyPose]:
    """Palm poses the arm must reach: pre-grasp, grasp, then every ``KEY_EVERY``-th waypoint along the chain."""
    assert desc.grasp is not None
    p = np.array(desc.grasp.wrist_position, dtype=np.float64)
    q = np.array(desc.grasp.wrist_orientation, dtype=np.float64)
    q /= np.linalg.norm(q)
    state = dict(q0)
    keys = [
        KeyPose(p - PREGRASP_BACK_M * approach_axis(q), q, dict(state)),
        KeyPose(p, q, dict(state)),
    ]
    for index, (prim, match) in enumerate(zip(desc.chain, matches, strict=True)):
        wps = primitive_waypoints(prim, p, q)
        joint = joints[match.joint].index
        start = state[joint]
        for i in range(KEY_EVERY, len(wps) + KEY_EVERY - 1, KEY_EVERY):
            k = min(i, len(wps) - 1)
            state[joint] = start + match.sign * float(wps.progress[k])
            foot = None
            if prim.kind == "rotation" and prim.pos is not None:
                axis_dir = np.asarray(prim.dir, dtype=np.float64) / np.linalg.norm(prim.dir)
                rel = wps.positions[k] - np.asarray(prim.pos, dtype=np.float64)
                foot = np.asarray(prim.pos, dtype=np.float64) + (rel @ axis_dir) * axis_dir
            keys.append(KeyPose(wps.positions[k], wps.quats[k], dict(state), foot, index, float(wps.progress[k])))
        p, q = wps.positions[-1], wps.quats[-1]
    return keys


class _Run:
    """The mutable state of one execution (physics and planning clients, clocks, contact counts)."""

    def __init__(self, setup: SceneSetup, frames_dir: Path | None) -> None:
        import pybullet as pb  # noqa: PLC0415

        self.pb = pb
        self.setup = setup
        self.frames_dir = frames_dir
        self.frames: list[str] = []
        self.sim = int(pb.connect(pb.DIRECT))
        self.plan = int(pb.connect(pb.DIRECT))
        for c in (self.sim, self.plan):
            pb.setGravity(0.0, 0.0, -9.81, physicsClientId=c)
            pb.setTimeStep(TIME_STEP_S, physicsClientId=c)
        pb.setPhysicsEngineParameter(numSolverIterations=SOLVER_ITERATIONS, physicsClientId=self.sim)
        self.scene = setup.load(self.sim)
        self.plan_scene = setup.load(self.plan)
        self.steps = 0
        self.contact_checks = 0
        self.contact_hits = 0
        self.q = rb.ARM_REST.copy()
        self.robot: rb.Robot | None = None
        self.planner: rb.Robot | None = None
        self.camera_target = np.zeros(3)
        self.camera_eye = np.ones(3)
        self.part_links: set[int] = set()
        self.trace_joints: tuple[int, ...] = ()
        self.trace_t: list[float] = []
        self.trace_q: list[tuple[float, ...]] = []

    def close(self) -> None:
        for c in (self.sim, self.plan):
            self.pb.disconnect(physicsClientId=c)

    # --- physics ---------------------------------------------------------------------------------------
    def step(self, n: int) -> None:
        for _ in range(n):
            self.pb.stepSimulation(physicsClientId=self.sim)
        self.steps += n

    @property
    def sim_time_s(self) -> float:
        return self.steps * TIME_STEP_S

    def hand_contacts(self, part_only: bool = False) -> list[int]:
        """Scene links touched by any hand link now (one entry per contact point); ``part_only``: only links
        that the driven joints move."""
        assert self.robot is not None
        pts = self.pb.getContactPoints(self.robot.body, self.scene, physicsClientId=self.sim)
        links = [int(p[4]) for p in pts if p[3] in rb.HAND_LINKS]
        return [k for k in links if k in self.part_links] if part_only else links

    def fingers_touching(self) -> int:
        """How many fingers touch a moving part of the scene."""
        return sum(self.finger_contacts(part_only=True))

    def finger_contacts(self, part_only: bool = False) -> list[bool]:
        """Per finger (1, 2, 3): whether its proximal or distal link touches the scene (``part_only``: a moving
        part of it)."""
        assert self.robot is not None
        pts = self.pb.getContactPoints(self.robot.body, self.scene, physicsClientId=self.sim)
        links = {int(p[3]) for p in pts if not part_only or int(p[4]) in self.part_links}
        return [prox in links or dist in links for prox, dist in rb.FINGER_LINKS]

    def check_contact(self) -> bool:
        touching = bool(self.hand_contacts(part_only=True))
        self.contact_checks += 1
        self.contact_hits += int(touching)
        if self.trace_joints:
            self.trace_t.append(self.sim_time_s)
            self.trace_q.append(tuple(self.joint_value(j)[0] for j in self.trace_joints))
        return touching

    def joint_value(self, index: int) -> tuple[float, float]:
        state = self.pb.getJointState(self.scene, index, physicsClientId=self.sim)
        return float(state[0]), float(state[1])

    def frame(self, label: str) -> None:
        if self.frames_dir is None:
            return
        path = self.frames_dir / f"{len(self.frames):02d}-{label}.png"
        save_frame(self.sim, path, self.camera_eye, self.camera_target)
        self.frames.append(str(path))

    # --- motion --------------------------------------------------------------------------------------------
    def move_to(self, position: FloatArray, quat: FloatArray) -> None:
        """One control tick towards a fixed palm pose (resolved rate from the measured arm state)."""
        assert self.robot is not None
        p, q = rb.palm_pose(self.robot)
        self.q = command_for_twist(self.robot, pose_error(p, q, position, quat))
        rb.drive_arm(self.robot, self.q)

    def hold(self) -> None:
        """Hold the arm where it measurably is."""
        assert self.robot is not None
        self.q = rb.arm_angles(self.robot)
        rb.drive_arm(self.robot, self.q)

    def move_by(self, twist: FloatArray, posture: FloatArray | None = None) -> None:
        """One control tick moving the palm by ``twist`` (world, m and rad) from where it measurably is, the arm
        drifting towards ``posture`` (7,) radians in its null space."""
        assert self.robot is not None
        self.q = command_for_twist(self.robot, twist, posture)
        rb.drive_arm(self.robot, self.q)


def close_fingers(run: _Run, target_dofs: FloatArray) -> None:
    """Close the hand from its open pre-grasp towards ``target_dofs`` (4,) radians (``CLOSE_EXTRA_RAD`` further,
    so a finger stopped by the object squeezes it) with each finger's target ramped at ``CLOSE_RATE_RAD_S`` and
    never more than ``SQUEEZE_RAD`` ahead of the finger: a finger the object blocks stops and squeezes with its
    force limit while the others close on (the BH8 closes finger by finger; driven at the motors' full speed a
    fingertip passed through a small cap in one physics step). Done when every finger is at its goal or has not
    moved for ``CLOSE_STALL_TICKS`` ticks."""
    assert run.robot is not None
    tick_s = STEPS_PER_WAYPOINT * TIME_STEP_S
    goal = target_dofs.copy()
    goal[1:] = np.minimum(goal[1:] + CLOSE_EXTRA_RAD, barrett.DOF_UPPER[1:])
    command = rb.hand_dofs(run.robot)
    command[0] = goal[0]
    history = [rb.hand_dofs(run.robot)]
    for _ in range(int(CLOSE_MAX_S / tick_s)):
        now = history[-1]
        command[1:] = np.minimum(np.minimum(command[1:] + CLOSE_RATE_RAD_S * tick_s, now[1:] + SQUEEZE_RAD), goal[1:])
        rb.drive_hand(run.robot, command)
        run.step(STEPS_PER_WAYPOINT)
        history.append(rb.hand_dofs(run.robot))
        if len(history) > CLOSE_STALL_TICKS:
            moved = np.abs(history[-1][1:] - history[-1 - CLOSE_STALL_TICKS][1:])
            if np.all((command[1:] >= goal[1:]) | (moved < CLOSE_STALL_RAD)):
                break
    run.step(int(CLOSE_SETTLE_S / TIME_STEP_S))


def _grasp_constraint(run: _Run, link: int) -> int:
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


def _descendants(run: _Run, joint: int) -> set[int]:
    """Scene link ``joint`` (the child of that joint) and every link below it."""
    pb = run.pb
    parent = {
        j: int(pb.getJointInfo(run.scene, j, physicsClientId=run.sim)[16])
        for j in range(pb.getNumJoints(run.scene, physicsClientId=run.sim))
    }
    out = {joint}
    changed = True
    while changed:
        changed = False
        for child, par in parent.items():
            if par in out and child not in out:
                out.add(child)
                changed = True
    return out


def _link_index(run: _Run, name: str) -> int:
    pb = run.pb
    base = pb.getBodyInfo(run.scene, physicsClientId=run.sim)[0].decode()
    if name == base:
        return -1
    for j in range(pb.getNumJoints(run.scene, physicsClientId=run.sim)):
        if pb.getJointInfo(run.scene, j, physicsClientId=run.sim)[12].decode() == name:
            return j
    msg = f"scene {run.setup.name}: no link named {name}"
    raise SimulationError(msg)


def primitive_twist(prim: Primitive, position: FloatArray, step: float) -> FloatArray:
    """(6,) palm twist (world, m and rad) advancing primitive ``prim`` by ``step`` (rad or m) from the palm
    ``position``: a turn about the primitive's axis, or a shift along its direction."""
    if prim.kind == "rotation":
        if prim.pos is None:
            msg = "rotation primitive without an axis point"
            raise SimulationError(msg)
        return screw_twist(position, prim.pos, prim.dir, step)
    return line_twist(prim.dir, step)


def posture_path(keys: Sequence[KeyPose], q_path: FloatArray, index: int) -> tuple[FloatArray, FloatArray]:
    """The base placement's verified arm angles along primitive ``index``: progress (k,) rad or m from 0, and
    arm angles (k, 7) radians (the first row: the key pose just before the primitive starts)."""
    rows = [i for i, k in enumerate(keys) if k.primitive == index]
    if not rows:
        return np.zeros(1), q_path[-1:].copy()
    first = rows[0] - 1
    progress = np.array([0.0, *(keys[i].progress for i in rows)])
    return progress, q_path[[first, *rows]]


def posture_at(path: tuple[FloatArray, FloatArray], progress: float) -> FloatArray:
    """(7,) arm angles interpolated along ``posture_path`` at ``progress`` (clamped to its ends)."""
    xs, qs = path
    return np.array([np.interp(progress, xs, qs[:, j]) for j in range(qs.shape[1])])


def _execute_primitive(
    run: _Run,
    index: int,
    prim: Primitive,
    match: JointMatch,
    joint: _Joint,
    *,
    path: tuple[FloatArray, FloatArray],
) -> PrimitiveResult:
    assert run.robot is not None
    start_steps = run.steps
    step = ARC_STEP_RAD if prim.kind == "rotation" else LINE_STEP_M
    planned = max(1, math.ceil(prim.extent / step))
    q_start, _ = run.joint_value(joint.index)
    checks0, hits0 = run.contact_checks, run.contact_hits
    history: list[float] = []
    stopped: StopReason = "end of path"

    def achieved() -> float:
        return match.sign * (run.joint_value(joint.index)[0] - q_start)

    for _ in range(int(MAX_PATH_FACTOR * planned) + STALL_WINDOW):
        p, _q = rb.palm_pose(run.robot)
        remaining = prim.extent - achieved()
        ahead = min(prim.extent, achieved() + step)
        run.move_by(primitive_twist(prim, p, min(step, max(remaining, 0.25 * step))), posture_at(path, ahead))
        run.step(STEPS_PER_WAYPOINT)
        run.check_contact()
        a = achieved()
        history.append(a)
        if a >= prim.extent:
            stopped = "extent reached"
            break
        if len(history) > STALL_WINDOW and history[-1] - history[-1 - STALL_WINDOW] < STALL_MIN_FRACTION * prim.extent:
            stopped = "stalled"
            break
    run.hold()
    for _ in range(int(SETTLE_MAX_S / (STEPS_PER_WAYPOINT * TIME_STEP_S))):
        run.step(STEPS_PER_WAYPOINT)
        run.check_contact()
        _, vel = run.joint_value(joint.index)
        if abs(vel) < SETTLED_SPEED:
            break
    run.frame(f"primitive-{index}")
    checks = run.contact_checks - checks0
    hits = run.contact_hits - hits0
    return PrimitiveResult(
        index=index,
        kind=prim.kind,
        joint=joint.axis.name,
        target=prim.extent,
        achieved=achieved(),
        contact_fraction=hits / checks if checks else 0.0,
        sim_time_s=(run.steps - start_steps) * TIME_STEP_S,
        stopped=stopped,
        end_speed=0.0,
        success=False,
    )


def execute(
    desc: Descriptor,
    setup: SceneSetup,
    *,
    grasp_mode: GraspMode = "constraint",
    frames_dir: Path | None = None,
) -> SimulationResult:
    """Run ``desc`` in a fresh pybullet DIRECT world built by ``setup`` and judge it (see the module docstring).

    ``SimulationError`` when the descriptor does not fit: no grasp, a primitive with no joint to drive or an
    axis far from every joint, or no base placement reaching the chain.
    """
    if desc.grasp is None:
        msg = f"descriptor {desc.name}: has no grasp (plan one first), nothing to hold the object with"
        raise SimulationError(msg)
    wall0 = time.perf_counter()
    cpu0 = time.process_time()
    run = _Run(setup, frames_dir)
    try:
        return replace(_execute(run, desc, grasp_mode, wall0), cpu_time_s=time.process_time() - cpu0)
    finally:
        run.close()


def _execute(run: _Run, desc: Descriptor, grasp_mode: GraspMode, wall0: float) -> SimulationResult:
    pb = run.pb
    assert desc.grasp is not None
    joints = scene_joints(run.sim, run.scene, run.setup.joints, run.setup.name)
    matches = match_chain(desc.chain, [j.axis for j in joints])
    by_name = {j.axis.name: j for j in joints}
    run.part_links = set().union(*(_descendants(run, by_name[m.joint].index) for m in matches))
    if run.setup.set_joint_friction:
        for j in scene_joints(run.sim, run.scene, None):
            authored = float(pb.getJointInfo(run.scene, j.index, physicsClientId=run.sim)[7])
            pb.setJointMotorControl2(
                run.scene,
                j.index,
                pb.VELOCITY_CONTROL,
                force=authored if authored > 0.0 else SCENE_JOINT_FRICTION_NM,
                physicsClientId=run.sim,
            )
    q0 = {j.index: run.joint_value(j.index)[0] for j in joints}
    keys = key_poses(desc, matches, by_name, q0)

    # Base placement in the planning client (scene + robot, kinematic only).
    run.planner = rb.load_robot(run.plan, [0.0, 0.0, -5.0], [0.0, 0.0, 0.0, 1.0])
    placement = place_base(run.planner, run.plan_scene, keys, run.setup.floor_z)
    pb.resetBasePositionAndOrientation(
        run.planner.body, placement.base_position.tolist(), placement.base_quat.tolist(), physicsClientId=run.plan
    )
    run.robot = rb.load_robot(run.sim, placement.base_position, placement.base_quat)
    centre = np.mean([k.position for k in keys], axis=0)
    run.camera_target = 0.6 * centre + 0.4 * placement.base_position
    to_base = placement.base_position - centre
    to_base[2] = 0.0
    side = matrix_from_axis_angle([0.0, 0.0, 1.0], math.radians(55.0)) @ (to_base / (np.linalg.norm(to_base) + 1e-9))
    run.camera_eye = run.camera_target + 2.0 * side + np.array([0.0, 0.0, 0.9])

    # Pre-grasp: arm at the first key pose, hand open at the grasp's spread.
    target_dofs = barrett.dofs_from_eigengrasps(*desc.grasp.eigengrasps)
    straight = rb.finger_straight_rad()
    open_finger = max(float(barrett.DOF_LOWER[1]), straight - OPEN_BEYOND_STRAIGHT_RAD)
    open_dofs = np.array([target_dofs[0], open_finger, open_finger, open_finger])
    loop0, loop_cpu0 = time.perf_counter(), time.process_time()
    run.q = placement.q_path[0].copy()
    rb.set_arm(run.robot, run.q)
    rb.set_hand(run.robot, open_dofs)
    run.step(int(0.05 / TIME_STEP_S))
    run.frame("pregrasp")

    # Approach along +z of the palm.
    pre = keys[0]
    approach = line_waypoints(pre.position, pre.quat, approach_axis(pre.quat), PREGRASP_BACK_M)
    for i in range(1, len(approach)):
        run.move_to(approach.positions[i], approach.quats[i])
        run.step(STEPS_PER_WAYPOINT)
    for _ in range(APPROACH_SETTLE_TICKS):
        p_now, q_now = rb.palm_pose(run.robot)
        err = pose_error(p_now, q_now, keys[1].position, keys[1].quat)
        if np.linalg.norm(err[:3]) < APPROACH_TOL_M and np.linalg.norm(err[3:]) < APPROACH_TOL_RAD:
            break
        run.move_to(keys[1].position, keys[1].quat)
        run.step(STEPS_PER_WAYPOINT)
    run.step(int(0.05 / TIME_STEP_S))

    # Close towards the eigengrasp amplitudes, each finger until it stops on the object.
    close_fingers(run, target_dofs)
    touched = run.hand_contacts()
    grasped = run.fingers_touching() >= 2
    notes: list[str] = []
    if grasp_mode == "constraint" and touched:
        if run.setup.grasp_link is not None:
            link = _link_index(run, run.setup.grasp_link)
        else:
            first = _descendants(run, by_name[matches[0].joint].index)
            on_part = [t for t in touched if t in first] or touched
            link = max(set(on_part), key=on_part.count)
        _grasp_constraint(run, link)
        held = rb.hand_dofs(run.robot)  # the constraint holds: the fingers only rest on the part
        held[1:] += SQUEEZE_RAD
        rb.drive_hand(run.robot, held, max_torque_nm=HOLD_TORQUE_NM)
    elif grasp_mode == "constraint":
        notes.append("no hand-object contact after closing: no grasp constraint made")
    run.frame("grasped")
    run.contact_checks = run.contact_hits = 0
    driven = list(dict.fromkeys(m.joint for m in matches))
    run.trace_joints = tuple(by_name[name].index for name in driven)

    results: list[PrimitiveResult] = []
    for i, (prim, match) in enumerate(zip(desc.chain, matches, strict=True)):
        path = posture_path(keys, placement.q_path, i)
        results.append(_execute_primitive(run, i, prim, match, by_name[match.joint], path=path))

    # Hold still, then judge.
    run.step(int(HOLD_S / TIME_STEP_S))
    end_contact = run.check_contact()
    contact_fraction = run.contact_hits / run.contact_checks if run.contact_checks else 0.0
    contact_kept = end_contact and contact_fraction >= CONTACT_KEPT_FRACTION
    judged: list[PrimitiveResult] = []
    for res, match in zip(results, matches, strict=True):
        joint = by_name[match.joint]
        _, vel = run.joint_value(joint.index)
        limit = STILL_ANGULAR_RAD_S if joint.axis.kind == "revolute" else STILL_LINEAR_M_S
        ok = res.achieved >= SUCCESS_FRACTION * res.target and abs(vel) < limit
        judged.append(
            PrimitiveResult(
                res.index,
                res.kind,
                res.joint,
                res.target,
                res.achieved,
                res.contact_fraction,
                res.sim_time_s,
                res.stopped,
                abs(vel),
                ok,
            )
        )
    run.frame("end")
    success = grasped and contact_kept and all(r.success for r in judged)
    if not grasped:
        notes.append("fewer than two fingers closed on the object")
    return SimulationResult(
        descriptor_id=desc.id,
        scene=run.setup.name,
        primitives=tuple(judged),
        grasped=grasped,
        contact_fraction=contact_fraction,
        contact_kept=contact_kept,
        success=success,
        sim_time_s=run.sim_time_s,
        wall_time_s=time.perf_counter() - wall0,
        base_position=(
            float(placement.base_position[0]),
            float(placement.base_position[1]),
            float(placement.base_position[2]),
        ),
        base_quat=(
            float(placement.base_quat[0]),
            float(placement.base_quat[1]),
            float(placement.base_quat[2]),
            float(placement.base_quat[3]),
        ),
        grasp_mode=grasp_mode,
        loop_wall_time_s=time.perf_counter() - loop0,
        loop_cpu_time_s=time.process_time() - loop_cpu0,
        trace=JointTrace(tuple(driven), tuple(run.trace_t), tuple(run.trace_q)),
        frames=tuple(run.frames),
        notes=tuple(notes),
    )
