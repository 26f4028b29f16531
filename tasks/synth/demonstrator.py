"""The scripted demonstrator: what the hand and the object's joints do over time.

The hand rests still, reaches along a curved path (a cubic Bezier curve, minimum-jerk timing, orientation
slerped the same way) to the demonstrated palm pose, holds, then drives the scene's motions one after another
with minimum-jerk profiles and short holds between them, and holds at the end. From the grasp on the palm is
rigid with the grasp link. Times are seconds from the start of the recording; world frame, metres, radians,
quaternions ``[x, y, z, w]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from tasks.arrays import FloatArray, Points, Quats, Vector3
from tasks.errors import SceneError
from tasks.scenes.kinematics import joint_values_at_motion, min_jerk
from tasks.scenes.scene import Scene

PhaseKind = Literal["rest", "reach", "hold", "rotation", "translation"]

FINAL_APPROACH_M = 0.12
"""The last control point of the reach lies this far back along the approach: the hand comes in straight."""


@dataclass(frozen=True)
class Phase:
    """One span of the demonstration: ``kind``, [t_start, t_end) seconds, the motion index it drives (or None)."""

    kind: PhaseKind
    t_start: float
    t_end: float
    motion: int | None = None


@dataclass(frozen=True)
class Timing:
    """Durations (s) of the scripted phases: rest before the reach, the reach, holds, and seconds per unit of
    motion (s/rad for rotations, s/m for translations; a motion lasts at least ``min_motion_s``)."""

    rest_s: float = 0.6
    reach_s: float = 1.3
    grasp_hold_s: float = 0.7
    between_hold_s: float = 0.7
    end_hold_s: float = 0.7
    s_per_rad: float = 1.3
    s_per_m: float = 5.5
    min_motion_s: float = 1.0


NOMINAL_TIMING = Timing()


def draw_timing(rng: np.random.Generator) -> Timing:
    """A randomised demonstrator pace (a person is never quite as fast twice)."""
    u = rng.uniform
    return Timing(
        rest_s=u(0.4, 0.8),
        reach_s=u(1.0, 1.6),
        grasp_hold_s=u(0.5, 0.9),
        between_hold_s=u(0.5, 0.9),
        end_hold_s=u(0.5, 0.9),
        s_per_rad=u(1.0, 1.6),
        s_per_m=u(4.0, 7.0),
    )


@dataclass(frozen=True)
class Reach:
    """The reach: cubic Bezier control points (4, 3) from the rest position to the palm, and the rest and grasp
    palm orientations."""

    control: Points
    rest_quat: FloatArray
    palm_quat: FloatArray


def plan_reach(palm_pos: Vector3, palm_quat: FloatArray, floor_z: float, rng: np.random.Generator | None) -> Reach:
    """A curved reach ending at the palm pose (world): from 0.3-0.5 m back along the approach and to one side,
    bulging sideways; the rest orientation is 20-50 deg off the grasp's. ``rng`` None gives the nominal reach."""
    rot = Rotation.from_quat(palm_quat).as_matrix()
    x, y, approach = rot[:, 0], rot[:, 1], rot[:, 2]
    if rng is None:
        dist, side, bulge, turn = 0.4, np.array([0.3, 0.2]), 0.08, np.array([0.0, 0.35, 0.2])
    else:
        dist = rng.uniform(0.3, 0.5)
        side = rng.uniform(-0.6, 0.6, 2)
        bulge = rng.uniform(0.05, 0.12)
        axis = rng.normal(size=3)
        turn = axis / np.linalg.norm(axis) * np.radians(rng.uniform(20.0, 50.0))
    away = -approach + side[0] * x + side[1] * y
    away /= np.linalg.norm(away)
    rest = palm_pos + dist * away
    if rest[2] < floor_z + 0.1:  # keep the hand above the floor: mirror the offset's vertical part
        rest[2] = max(palm_pos[2] + abs(rest[2] - palm_pos[2]), floor_z + 0.1)
    p2 = palm_pos - FINAL_APPROACH_M * approach
    chord = p2 - rest
    normal = np.cross(chord, approach if abs(np.dot(chord, approach)) < 0.99 * np.linalg.norm(chord) else x)
    normal /= np.linalg.norm(normal)
    p1 = rest + 0.4 * chord + bulge * normal
    rest_quat = (Rotation.from_rotvec(turn) * Rotation.from_quat(palm_quat)).as_quat()
    control = np.array([rest, p1, p2, palm_pos], dtype=np.float64)
    return Reach(control, rest_quat, np.asarray(palm_quat, dtype=np.float64))


def bezier(control: Points, s: FloatArray) -> Points:
    """Points (n, 3) of the cubic Bezier curve with ``control`` (4, 3) at parameters ``s`` (n,) in [0, 1]."""
    s = np.asarray(s, dtype=np.float64)[:, None]
    c = control
    out: Points = (1 - s) ** 3 * c[0] + 3 * (1 - s) ** 2 * s * c[1] + 3 * (1 - s) * s**2 * c[2] + s**3 * c[3]
    return out


def reach_pose(reach: Reach, s: FloatArray) -> tuple[Points, Quats]:
    """Palm positions (n, 3) and quaternions (n, 4) at reach progress ``s`` (n,) in [0, 1] (already min-jerk)."""
    slerp = Slerp([0.0, 1.0], Rotation.from_quat(np.stack([reach.rest_quat, reach.palm_quat])))
    quats: Quats = slerp(np.clip(s, 0.0, 1.0)).as_quat()
    return bezier(reach.control, np.clip(s, 0.0, 1.0)), quats


@dataclass(frozen=True)
class Demonstration:
    """A scripted demonstration of ``scene``: its phases in time order, the reach and the total duration (s)."""

    scene: Scene
    phases: tuple[Phase, ...]
    reach: Reach
    duration_s: float

    @property
    def grasp_s(self) -> float:
        """Time (s) the hand arrives at the grasp (the end of the reach)."""
        return next(p.t_end for p in self.phases if p.kind == "reach")


def motion_kind(scene: Scene, k: int, joint_types: dict[str, str]) -> PhaseKind:
    """``rotation`` or ``translation`` for motion ``k`` (``joint_types``: joint name -> URDF type)."""
    joint = scene.motions[k].joint
    kind = joint_types.get(joint)
    if kind in ("revolute", "continuous"):
        return "rotation"
    if kind == "prismatic":
        return "translation"
    msg = f"scene {scene.name!r}: motion joint {joint!r} is {kind or 'missing'}, not revolute or prismatic"
    raise SceneError(msg)


def plan_demonstration(
    scene: Scene,
    joint_types: dict[str, str],
    palm_pos: Vector3,
    palm_quat: FloatArray,
    rng: np.random.Generator | None,
) -> Demonstration:
    """Script the demonstration of ``scene`` (palm pose world at the grasp); ``rng`` None gives nominal pacing."""
    if not scene.motions:
        msg = f"scene {scene.name!r} has no motions to demonstrate"
        raise SceneError(msg)
    timing = NOMINAL_TIMING if rng is None else draw_timing(rng)
    reach = plan_reach(palm_pos, palm_quat, scene.floor_z, rng)
    phases = [Phase("rest", 0.0, timing.rest_s)]
    t = timing.rest_s
    phases.append(Phase("reach", t, t + timing.reach_s))
    t += timing.reach_s
    phases.append(Phase("hold", t, t + timing.grasp_hold_s))
    t += timing.grasp_hold_s
    for k, motion in enumerate(scene.motions):
        kind = motion_kind(scene, k, joint_types)
        per_unit = timing.s_per_rad if kind == "rotation" else timing.s_per_m
        length = max(timing.min_motion_s, per_unit * abs(motion.end - motion.start))
        phases.append(Phase(kind, t, t + length, k))
        t += length
        hold = timing.end_hold_s if k == len(scene.motions) - 1 else timing.between_hold_s
        phases.append(Phase("hold", t, t + hold))
        t += hold
    return Demonstration(scene, tuple(phases), reach, t)


def joint_values_at(dem: Demonstration, t_s: float) -> dict[str, float]:
    """Every scripted joint's value (rad or m) at time ``t_s`` (s)."""
    done = -1
    for phase in dem.phases:
        if phase.motion is None:
            continue
        if t_s < phase.t_start:
            break
        progress = float(min_jerk(np.array([(t_s - phase.t_start) / (phase.t_end - phase.t_start)]))[0])
        if progress < 1.0:
            return joint_values_at_motion(dem.scene, phase.motion, progress)
        done = phase.motion
    if done < 0:
        return joint_values_at_motion(dem.scene, 0, 0.0)
    return joint_values_at_motion(dem.scene, done, 1.0)


def reach_progress(dem: Demonstration, t_s: FloatArray) -> FloatArray:
    """Min-jerk reach progress (0 at rest, 1 at the grasp) at times ``t_s`` (n,) seconds."""
    reach = next(p for p in dem.phases if p.kind == "reach")
    return min_jerk((np.asarray(t_s, dtype=np.float64) - reach.t_start) / (reach.t_end - reach.t_start))
