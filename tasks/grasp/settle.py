"""Settling a closed grasp: what the hand holds once the squeezing fingers have pulled the part in.

The planner closes the fingers kinematically on a static model (GraspIt!'s autoGrasp). A hand that wraps a box or
a cylinder then touches it with its finger links only: every contact presses the part away from the palm, and the
grasp wrench space has no force closure, though the fingers, squeezing, pull the part into the palm and hold it
(most such wraps of boxes and cylinders hold under a shake with no static force closure at all). Settling
runs that in pybullet (DIRECT): the grasp set up as the shake test sets it up (``shake.grip``: the part a free
body of 0.3 kg, the palm held still, the fingers driven 0.3 rad past contact with at most 1.5 N m), without
gravity, for 0.3 s (a model with a mount is closed on whole, then the part alone is the free body). The settled
grasp is the palm pose relative to the part after that, expressed with the part back where it was (world frame,
metres, quaternion [x, y, z, w]), and the qualities of its contacts.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Vector3
from tasks.grasp import closing
from tasks.grasp.object_model import ObjectModel
from tasks.grasp.planner import LIMIT_TOL_M, GraspCandidate
from tasks.grasp.quality import DEFAULT_MU, GraspQuality, grasp_quality
from tasks.grasp.shake import TIME_STEP_S, ShakeParams, grip
from tasks.grasp.worker_pool import Beside

SETTLE_S = 0.3
SQUEEZE = ShakeParams()
"""The hold test's squeeze (``shake.grip``: 0.3 rad past contact, 1.5 N m, a part of 0.3 kg, the same friction)."""
WRAP_SETTLES = 3
"""Grasps without a static force closure settled per plan (about 0.1 s CPU each)."""
LATE_WRAP_SETTLES = 7
"""The next ones settled when no grasp of the first round holds (``tasks.grasp.api.plan_on_model``): a wrap whose
palm lies further along the demonstrated approach (on a tall cylinder, tens of mm) ranks behind the closest
three."""
MAX_SHIFT_M = 0.02
"""A settled wrap counts only when the part moved at most 20 mm into the hand: pulled further, the static pose
was far from a grasp and where the part ends up is the solver's chance (a microwave handle's crop pulled 30 mm
settled into a force closure that no independent model held)."""


@dataclass(frozen=True)
class Settled:
    """A settled grasp: palm ``position`` (3,) m and ``quat_xyzw`` (4,) relative to the part, expressed in the
    world with the part where the model has it; the quality of its contacts; whether the palm touches the part
    (``palm_contact``: a wrap); how far the part moved towards the palm (``shift_m``, m)."""

    position: Vector3
    quat_xyzw: FloatArray
    quality: GraspQuality
    palm_contact: bool
    shift_m: float


def settle(model: ObjectModel, position: Vector3, quat_xyzw: FloatArray, spread_rad: float, mu: float) -> Settled:
    """Close the open hand at spread ``spread_rad`` (rad) at the palm pose (world) on the part as a free body,
    squeeze and settle (see the module docstring); ``mu``: the friction coefficient of the quality."""
    client = pb.connect(pb.DIRECT)
    try:
        pb.setTimeStep(TIME_STEP_S, physicsClientId=client)
        pb.setPhysicsEngineParameter(numSolverIterations=SQUEEZE.solver_iterations, physicsClientId=client)
        posture = np.array([spread_rad, 0.0, 0.0, 0.0])
        hand, obj, _ = grip(client, model, position, quat_xyzw, posture, SQUEEZE)
        start_pos, start_quat = pb.getBasePositionAndOrientation(obj, physicsClientId=client)
        for _ in range(round(SETTLE_S / TIME_STEP_S)):
            pb.stepSimulation(physicsClientId=client)
        end_pos, end_quat = pb.getBasePositionAndOrientation(obj, physicsClientId=client)
        palm_pos, palm_quat = pb.getBasePositionAndOrientation(hand, physicsClientId=client)
        contacts = closing.contacts_of(client, hand, obj)
    finally:
        pb.disconnect(client)
    back = Rotation.from_quat(start_quat) * Rotation.from_quat(end_quat).inv()  # the part's motion undone

    def undo(points: np.ndarray) -> np.ndarray:
        return np.asarray(back.apply(points - np.asarray(end_pos)) + np.asarray(start_pos), dtype=np.float64)

    quality = grasp_quality(undo(contacts.positions), back.apply(contacts.normals_in), model.center, model.radius, mu)
    return Settled(
        undo(np.asarray(palm_pos, dtype=np.float64)),
        (back * Rotation.from_quat(palm_quat)).as_quat(),
        quality,
        bool(np.any(contacts.links == -1)),
        float(np.linalg.norm(np.asarray(end_pos) - np.asarray(start_pos))),
    )


def settled_wraps(  # noqa: PLR0917 -- candidates, model, seed pose, limits
    candidates: list[GraspCandidate],
    model: ObjectModel,
    seed_position: Vector3,
    seed_rot: FloatArray,
    max_lateral_m: float,
    max_angle_rad: float,
    *,
    count: int = WRAP_SETTLES,
    skip: int = 0,
    mu: float = DEFAULT_MU,
) -> list[GraspCandidate]:
    """Wraps among grasps without a static force closure: of the ``candidates`` on or along the demonstrated
    approach (``near`` or ``reach``) within ``max_angle_rad`` of the demonstrated palm, the ``count`` closest after
    the ``skip`` closest are settled; those that settle into a force closure with the palm on the part, the part
    pulled in at most ``MAX_SHIFT_M``, their settled palm within ``max_lateral_m`` of the demonstrated approach
    (world, m) and ``max_angle_rad`` of the demonstrated palm (rotation ``seed_rot`` (3, 3)), come back as near
    candidates at their settled palm pose with the settled qualities (friction coefficient ``mu``). The settling
    runs in the planner's worker processes (``worker_pool``)."""
    approach = seed_rot[:, 2]
    seed_inv = Rotation.from_matrix(seed_rot).inv()
    pool = sorted(
        (c for c in candidates if (c.near or c.reach) and not c.quality.force_closure and c.angle_rad <= max_angle_rad),
        key=lambda c: c.closeness,
    )
    chosen = pool[skip : skip + count]
    settling = [Beside(settle, model, c.position, c.quat_xyzw, float(c.closed[0]), mu) for c in chosen]
    out: list[GraspCandidate] = []
    for cand, running in zip(chosen, settling, strict=True):
        done = running.result()
        rel = done.position - np.asarray(seed_position, dtype=np.float64)
        lateral = float(np.linalg.norm(rel - float(rel @ approach) * approach))
        angle = float((seed_inv * Rotation.from_quat(done.quat_xyzw)).magnitude())
        if not (done.quality.force_closure and done.palm_contact) or done.shift_m > MAX_SHIFT_M:
            continue
        if lateral > max_lateral_m + LIMIT_TOL_M or angle > max_angle_rad:
            continue
        out.append(
            dataclasses.replace(
                cand,
                position=done.position,
                quat_xyzw=done.quat_xyzw,
                quality=done.quality,
                offset_m=lateral,
                angle_rad=angle,
                near=True,
            )
        )
    return out
