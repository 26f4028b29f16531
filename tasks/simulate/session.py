"""One simulated execution's pybullet world: the physics client (scene + robot) and a planning client (scene +
a kinematic copy of the robot for IK), clocks, contact bookkeeping and one-tick palm motions.

``SceneSetup`` says how to build a scene; ``scene_joints`` lists its articulated joints with their world axes.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import pybullet as pb

from tasks.arrays import FloatArray
from tasks.errors import SimulationError
from tasks.simulate import clients
from tasks.simulate import robot as rb
from tasks.simulate.control import command_for_twist, pose_error
from tasks.simulate.matching import JointAxis
from tasks.simulate.render import save_frame

TIME_STEP_S = 1.0 / 120.0
"""Physics step, seconds: 1/120 s (half pybullet's default, the physics twice as fast; the 200 g caps of the
built-in bottles hold under it since the fingers close at a limited speed and rest once the palm constraint holds)."""
SOLVER_ITERATIONS = 50
"""Constraint solver iterations per step (pybullet's default; 20 let the cap slip under the palm constraint)."""
STEPS_PER_WAYPOINT = 3
"""Physics steps per control tick: 1° or 5 mm per 25 ms, i.e. 0.7 rad/s or 0.2 m/s along the path."""
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
class SceneJoint:
    """A scene joint: pybullet ``index``, world ``axis`` at load time, and its limits (rad or m)."""

    index: int
    axis: JointAxis
    lower: float
    upper: float


def scene_joints(client: int, body: int, names: Sequence[str] | None, scene_name: str = "scene") -> list[SceneJoint]:
    """The scene body's revolute/prismatic joints (world axes at the current state), optionally only ``names``."""

    found: list[SceneJoint] = []
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
        found.append(SceneJoint(j, axis, float(info[8]), float(info[9])))
    if names is not None:
        missing = [n for n in names if n not in {f.axis.name for f in found}]
        if missing:
            names_found = ", ".join(sorted(by_name))
            msg = f"scene {scene_name}: no revolute/prismatic joint named {', '.join(missing)} (joints: {names_found})"
            raise SimulationError(msg)
        found.sort(key=lambda f: list(names).index(f.axis.name))
    return found


class Session:
    """The mutable state of one execution (physics and planning clients, clocks, contact counts)."""

    def __init__(self, setup: SceneSetup, frames_dir: Path | None) -> None:
        self.pb = pb
        self.setup = setup
        self.frames_dir = frames_dir
        self.frames: list[str] = []
        self.sim = clients.acquire()
        self.plan = clients.acquire()
        for c in (self.sim, self.plan):
            pb.setGravity(0.0, 0.0, -9.81, physicsClientId=c)
            pb.setTimeStep(TIME_STEP_S, physicsClientId=c)
        pb.setPhysicsEngineParameter(numSolverIterations=SOLVER_ITERATIONS, physicsClientId=self.sim)
        self.scene = setup.load(self.sim)
        self.plan_scene = setup.load(self.plan)
        self.steps = 0
        self.physics_cpu_s = 0.0
        """CPU seconds spent in pybullet's physics steps."""
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
            clients.release(c)

    # --- physics ---------------------------------------------------------------------------------------
    def step(self, n: int) -> None:
        cpu0 = time.process_time()
        for _ in range(n):
            self.pb.stepSimulation(physicsClientId=self.sim)
        self.physics_cpu_s += time.process_time() - cpu0
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

    def mean_speeds(self, joints: Sequence[int], steps: int) -> dict[int, float]:
        """Step the physics ``steps`` times and return each scene joint's mean speed over them (its displacement
        over the time, rad/s or m/s): what the joint did, where pybullet's joint velocity under a grasp
        constraint is the solver's velocity before its position correction."""
        before = {j: self.joint_value(j)[0] for j in joints}
        self.step(steps)
        return {j: abs(self.joint_value(j)[0] - before[j]) / (steps * TIME_STEP_S) for j in joints}

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


def descendants(run: Session, joint: int) -> set[int]:
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


def link_index(run: Session, name: str) -> int:
    pb = run.pb
    base = pb.getBodyInfo(run.scene, physicsClientId=run.sim)[0].decode()
    if name == base:
        return -1
    for j in range(pb.getNumJoints(run.scene, physicsClientId=run.sim)):
        if pb.getJointInfo(run.scene, j, physicsClientId=run.sim)[12].decode() == name:
            return j
    msg = f"scene {run.setup.name}: no link named {name}"
    raise SimulationError(msg)
