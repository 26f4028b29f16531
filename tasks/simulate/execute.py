"""Execute a descriptor with the iiwa + Barrett hand in pybullet (paper Section V-A).

Order: place the base (IK sweep, ``placement.py``), start at the pre-grasp pose (``PREGRASP_BACK_M`` back along
the approach, the hand open: ``hand.py``), approach along the palm's +z, close the fingers towards the grasp's
eigengrasp DOFs, each until the object stops it, then run each primitive as a sequence of control ticks: the palm
is turned about the primitive's axis (the hand turning with the part) or shifted along its direction by one
step (1° or 5 mm) *from where it measurably is*, by resolved-rate control (``control.py``: differential IK from
the measured joint angles, the arm drifting in its null space towards the base placement's verified joint path)
into force-limited position targets; move on when the driven joint has reached the extent or progress stops.
Because each tick starts from the measured palm pose, a learned axis a few millimetres or degrees off does not
build up a growing fight between the hand and the part's hinge: the part moves along its true path and the
hand follows it (compliance). Finally hold still for ``HOLD_S`` and judge success (``result.py``).

Grasp modes: ``"friction"`` relies on the closed fingers' contact friction alone; ``"constraint"`` adds a fixed
constraint between palm and the grasped link once the fingers have closed on it (a common simulation stand-in
for a firm grasp, which pybullet's soft contacts do not hold under large wrist torques), only when the hand
touches that link. Contact is measured the same way in both modes.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from schemas.descriptor import Descriptor, Primitive
from tasks.arrays import FloatArray
from tasks.errors import SimulationError
from tasks.hand import barrett
from tasks.simulate import robot as rb
from tasks.simulate.control import line_twist, pose_error, screw_twist
from tasks.simulate.hand import attach, close_fingers, pregrasp_opening
from tasks.simulate.matching import JointMatch, match_chain
from tasks.simulate.placement import KeyPose, place_base
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
from tasks.simulate.session import (
    SCENE_JOINT_FRICTION_NM,
    STEPS_PER_WAYPOINT,
    TIME_STEP_S,
    GraspMode,
    SceneJoint,
    SceneSetup,
    Session,
    descendants,
    scene_joints,
)
from tasks.simulate.tracking import AxisTracker
from tasks.simulate.waypoints import (
    ARC_STEP_RAD,
    LINE_STEP_M,
    Waypoints,
    approach_axis,
    arc_waypoints,
    line_waypoints,
    matrix_from_axis_angle,
)

__all__ = ["GraspMode", "SceneSetup", "execute", "scene_joints"]

MAX_PATH_FACTOR = 1.6
"""A primitive gets at most 1.6x the control ticks of its planned waypoints (a part lagging a compliant hand)."""
SETTLED_SPEED = 0.02
"""After a primitive, the arm holds until the driven joint is slower than this (rad/s or m/s; its mean speed over
a control tick, from its displacement) ..."""
PREGRASP_BACK_M = 0.10
"""Pre-grasp palm pose: 10 cm back along the approach direction."""
APPROACH_SETTLE_TICKS = 20
"""At most this many extra control ticks to bring the palm onto the grasp pose ..."""
APPROACH_TOL_M = 0.001
APPROACH_TOL_RAD = math.radians(0.5)
"""... within 1 mm and 0.5°."""
HOLD_S = 0.5
"""Simulated seconds held still after the chain before judging stillness ..."""
END_SPEED_WINDOW_S = 0.1
"""... by each driven joint's displacement over the hold's last 0.1 s (its mean speed there, rad/s or m/s):
pybullet's joint velocity under the palm constraint is the solver's velocity before its position correction (a
lever read 0.73 to 2.6 rad/s while it turned 0.03° in 0.5 s, about 0.001 rad/s)."""
SETTLE_MAX_S = 0.5
"""... or at most this long."""
STALL_WINDOW = 30
"""Waypoints over which progress is judged (0.75 s) ..."""
STALL_MIN_FRACTION = 0.02
"""... a primitive has stalled when its joint moved less than 2% of the extent over the window."""
KEY_EVERY = 15
"""Every 15th waypoint (15° or 7.5 cm) is a key pose for base placement."""


def primitive_waypoints(primitive: Primitive, position: FloatArray, quat: FloatArray) -> Waypoints:
    """Palm waypoints for one primitive from the palm pose (``position``, ``quat``), world frame."""
    if primitive.kind == "rotation":
        if primitive.pos is None:
            msg = "rotation primitive without an axis point"
            raise SimulationError(msg)
        return arc_waypoints(position, quat, primitive.pos, primitive.dir, primitive.extent)
    return line_waypoints(position, quat, primitive.dir, primitive.extent)


def key_poses(
    desc: Descriptor, matches: Sequence[JointMatch], joints: dict[str, SceneJoint], q0: dict[int, float]
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
    if progress <= xs[0]:
        first: FloatArray = qs[0].copy()
        return first
    if progress >= xs[-1]:
        last: FloatArray = qs[-1].copy()
        return last
    i = int(np.searchsorted(xs, progress, side="right")) - 1  # xs[i] <= progress < xs[i + 1]
    t = (progress - xs[i]) / (xs[i + 1] - xs[i])
    out: FloatArray = qs[i] + t * (qs[i + 1] - qs[i])
    return out


def _execute_primitive(
    run: Session,
    index: int,
    prim: Primitive,
    match: JointMatch,
    joint: SceneJoint,
    *,
    path: tuple[FloatArray, FloatArray],
    correct_axis: bool = True,
    origin: float | None = None,
) -> PrimitiveResult:
    assert run.robot is not None
    start_steps = run.steps
    step = ARC_STEP_RAD if prim.kind == "rotation" else LINE_STEP_M
    planned = max(1, math.ceil(prim.extent / step))
    q_start = run.joint_value(joint.index)[0] if origin is None else origin
    checks0, hits0 = run.contact_checks, run.contact_hits
    history: list[float] = []
    stopped: StopReason = "end of path"

    def achieved() -> float:
        return match.sign * (run.joint_value(joint.index)[0] - q_start)

    tracker = AxisTracker(prim, *rb.palm_pose(run.robot))
    for _ in range(int(MAX_PATH_FACTOR * planned) + STALL_WINDOW):
        p, q = rb.palm_pose(run.robot)
        axis = tracker.corrected(p, q) if correct_axis else prim
        now = achieved()
        remaining = prim.extent - now
        ahead = min(prim.extent, now + step)
        run.move_by(primitive_twist(axis, p, min(step, max(remaining, 0.25 * step))), posture_at(path, ahead))
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
        speed = run.mean_speeds([joint.index], STEPS_PER_WAYPOINT)[joint.index]  # displacement, not pybullet's
        run.check_contact()  # velocity, which under the palm constraint jitters while the joint stands still
        if speed < SETTLED_SPEED:
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
    run = Session(setup, frames_dir)
    try:
        return replace(_execute(run, desc, grasp_mode, wall0), cpu_time_s=time.process_time() - cpu0)
    finally:
        run.close()


def _execute(run: Session, desc: Descriptor, grasp_mode: GraspMode, wall0: float) -> SimulationResult:
    pb = run.pb
    assert desc.grasp is not None
    joints = scene_joints(run.sim, run.scene, run.setup.joints, run.setup.name)
    matches = match_chain(desc.chain, [j.axis for j in joints])
    by_name = {j.axis.name: j for j in joints}
    run.part_links = set().union(*(descendants(run, by_name[m.joint].index) for m in matches))
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
    run.planner = rb.load_robot(run.plan, [0.0, 0.0, -5.0], [0.0, 0.0, 0.0, 1.0], visuals=False)
    placement = place_base(run.planner, run.plan_scene, keys, run.setup.floor_z)
    pb.resetBasePositionAndOrientation(
        run.planner.body, placement.base_position.tolist(), placement.base_quat.tolist(), physicsClientId=run.plan
    )
    run.robot = rb.load_robot(run.sim, placement.base_position, placement.base_quat, visuals=run.frames_dir is not None)
    centre = np.mean([k.position for k in keys], axis=0)
    run.camera_target = 0.6 * centre + 0.4 * placement.base_position
    to_base = placement.base_position - centre
    to_base[2] = 0.0
    side = matrix_from_axis_angle([0.0, 0.0, 1.0], math.radians(55.0)) @ (to_base / (np.linalg.norm(to_base) + 1e-9))
    run.camera_eye = run.camera_target + 2.0 * side + np.array([0.0, 0.0, 0.9])

    # Pre-grasp: arm at the first key pose, hand open at the grasp's spread.
    target_dofs = barrett.dofs_from_eigengrasps(*desc.grasp.eigengrasps)
    open_dofs = pregrasp_opening(run.planner, run.plan_scene, placement.q_path[1], float(target_dofs[0]))
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
    grasped = run.fingers_touching() >= 2
    notes: list[str] = []
    if grasp_mode == "constraint":
        first_part = descendants(run, by_name[matches[0].joint].index)
        note = attach(run, run.setup.grasp_link, first_part)
        if note:
            notes.append(note)
    run.frame("grasped")
    run.contact_checks = run.contact_hits = 0
    driven = list(dict.fromkeys(m.joint for m in matches))
    run.trace_joints = tuple(by_name[name].index for name in driven)

    results: list[PrimitiveResult] = []
    seen: set[str] = set()
    for i, (prim, match) in enumerate(zip(desc.chain, matches, strict=True)):
        # a joint's first primitive counts its motion from the scene's start (a grasp may already have moved it)
        origin = None if match.joint in seen else q0[by_name[match.joint].index]
        seen.add(match.joint)
        path = posture_path(keys, placement.q_path, i)
        results.append(
            _execute_primitive(
                run,
                i,
                prim,
                match,
                by_name[match.joint],
                path=path,
                correct_axis=grasp_mode == "constraint",
                origin=origin,
            )
        )

    # Hold still, then judge.
    window = round(END_SPEED_WINDOW_S / TIME_STEP_S)
    run.step(int(HOLD_S / TIME_STEP_S) - window)
    end_speeds = run.mean_speeds([by_name[m.joint].index for m in matches], window)
    end_contact = run.check_contact()
    contact_fraction = run.contact_hits / run.contact_checks if run.contact_checks else 0.0
    contact_kept = end_contact and contact_fraction >= CONTACT_KEPT_FRACTION
    judged: list[PrimitiveResult] = []
    for res, match in zip(results, matches, strict=True):
        joint = by_name[match.joint]
        speed = end_speeds[joint.index]
        limit = STILL_ANGULAR_RAD_S if joint.axis.kind == "revolute" else STILL_LINEAR_M_S
        ok = res.achieved >= SUCCESS_FRACTION * res.target and speed < limit
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
                speed,
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
        physics_cpu_time_s=run.physics_cpu_s,
        trace=JointTrace(tuple(driven), tuple(run.trace_t), tuple(run.trace_q)),
        frames=tuple(run.frames),
        notes=tuple(notes),
    )
